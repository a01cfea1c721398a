# Imported targets for the Debian 12 packages scalemesh builds against.
# Each stage links the one third-party library it is about (STYLE.md).

find_package(Threads REQUIRED)
find_package(TBB REQUIRED)
find_package(Imath CONFIG REQUIRED)

find_package(embree 3 REQUIRED)

# OpenVDB and the Gmsh SDK ship no CMake config: scalemesh::openvdb and
# scalemesh::gmsh (used inside the build only).
include(scalemeshImportedTargets)

find_package(Boost 1.74 REQUIRED)
find_package(tomlplusplus REQUIRED)
find_package(CLI11 REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
