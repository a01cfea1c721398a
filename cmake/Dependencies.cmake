# Imported targets for the Debian 12 packages scalemesh builds against.
# Each stage links the one third-party library it is about (STYLE.md).

find_package(Threads REQUIRED)
find_package(TBB REQUIRED)
find_package(Imath CONFIG REQUIRED)

# OpenVDB 10 ships no CMake config; an imported target from its header and library.
find_path(OPENVDB_INCLUDE_DIR openvdb/openvdb.h REQUIRED)
find_library(OPENVDB_LIBRARY openvdb REQUIRED)
add_library(scalemesh::openvdb INTERFACE IMPORTED)
target_include_directories(scalemesh::openvdb SYSTEM INTERFACE "${OPENVDB_INCLUDE_DIR}")
target_link_libraries(scalemesh::openvdb INTERFACE "${OPENVDB_LIBRARY}" Imath::Imath TBB::tbb Threads::Threads)

find_package(embree 3 REQUIRED)

# The Gmsh SDK has neither a CMake config nor pkg-config.
find_path(GMSH_INCLUDE_DIR gmsh.h REQUIRED)
find_library(GMSH_LIBRARY gmsh REQUIRED)
add_library(scalemesh::gmsh INTERFACE IMPORTED)
target_include_directories(scalemesh::gmsh SYSTEM INTERFACE "${GMSH_INCLUDE_DIR}")
target_link_libraries(scalemesh::gmsh INTERFACE "${GMSH_LIBRARY}")

find_package(Boost 1.74 REQUIRED)
find_package(tomlplusplus REQUIRED)
find_package(CLI11 REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
