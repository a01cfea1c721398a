# Imported targets for the two Debian packages scalemesh links that ship no
# CMake package: scalemesh::openvdb (OpenVDB 10) and scalemesh::gmsh (the
# Gmsh SDK), for the build (Dependencies.cmake); not installed: the users of
# libscalemesh.so link neither.

if(NOT TARGET scalemesh::openvdb)
  find_package(Threads REQUIRED)
  find_package(TBB REQUIRED)
  find_package(Imath CONFIG REQUIRED)
  find_path(OPENVDB_INCLUDE_DIR openvdb/openvdb.h REQUIRED)
  find_library(OPENVDB_LIBRARY openvdb REQUIRED)
  add_library(scalemesh::openvdb INTERFACE IMPORTED)
  target_include_directories(scalemesh::openvdb SYSTEM INTERFACE "${OPENVDB_INCLUDE_DIR}")
  target_link_libraries(scalemesh::openvdb INTERFACE "${OPENVDB_LIBRARY}" Imath::Imath TBB::tbb Threads::Threads)
endif()

# The Gmsh SDK has neither a CMake config nor pkg-config.
if(NOT TARGET scalemesh::gmsh)
  find_path(GMSH_INCLUDE_DIR gmsh.h REQUIRED)
  find_library(GMSH_LIBRARY gmsh REQUIRED)
  add_library(scalemesh::gmsh INTERFACE IMPORTED)
  target_include_directories(scalemesh::gmsh SYSTEM INTERFACE "${GMSH_INCLUDE_DIR}")
  target_link_libraries(scalemesh::gmsh INTERFACE "${GMSH_LIBRARY}")
endif()
