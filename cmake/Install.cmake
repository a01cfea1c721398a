# `cmake --install build --prefix P`: the command line (bin/scalemesh), the
# library (include/scalemesh/, lib/libscalemesh.a over the stage libraries in
# lib/scalemesh/), the Python module and its type stub
# (lib/python3/dist-packages) and a CMake
# package, lib/cmake/scalemesh, for
#   find_package(scalemesh REQUIRED)
#   target_link_libraries(app PRIVATE scalemesh::scalemesh)
# The stage libraries are static, so the package finds, for the consumer, the
# third-party libraries they link (scalemeshConfig.cmake.in).
# `cpack -G DEB` in the build directory packs the same files as a .deb.

include(CMakePackageConfigHelpers)

set(SCALEMESH_CMAKE_DIR "${CMAKE_INSTALL_LIBDIR}/cmake/scalemesh")
set(scalemesh_stage_libraries core phantom isosurface smoothing sizing remeshing volume openings surface_io gmsh_io exporters
    importers pipeline)

install(TARGETS scalemesh RUNTIME DESTINATION "${CMAKE_INSTALL_BINDIR}")
install(TARGETS scalemesh_library EXPORT scalemeshTargets ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}")
# The stage libraries under lib/scalemesh/: their names (libcore.a,
# libvolume.a) are too generic for a shared lib/.
install(TARGETS ${scalemesh_stage_libraries} EXPORT scalemeshTargets
        ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}/scalemesh")
install(FILES include/scalemesh/scalemesh.h include/scalemesh/mesh.h include/scalemesh/gmsh_model.h
        "${PROJECT_BINARY_DIR}/generated/include/scalemesh/errors.h"
        DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/scalemesh")
# The Python module (src/python/) where Debian's python3 finds it: with the
# prefix /usr (the .deb) /usr/lib/python3/dist-packages; with another prefix
# P, P/lib/python3/dist-packages (add it to PYTHONPATH).
set(SCALEMESH_PYTHON_INSTALL_DIR "lib/python3/dist-packages" CACHE STRING
    "Where the Python module is installed, relative to the install prefix")
install(TARGETS scalemesh_python LIBRARY DESTINATION "${SCALEMESH_PYTHON_INSTALL_DIR}")
# Its type stub, beside it (PEP 484: a .pyi next to the extension module).
install(FILES src/python/scalemesh.pyi DESTINATION "${SCALEMESH_PYTHON_INSTALL_DIR}")
install(EXPORT scalemeshTargets NAMESPACE scalemesh:: DESTINATION "${SCALEMESH_CMAKE_DIR}")

configure_package_config_file(cmake/scalemeshConfig.cmake.in "${PROJECT_BINARY_DIR}/scalemeshConfig.cmake"
                              INSTALL_DESTINATION "${SCALEMESH_CMAKE_DIR}")
# 0.x: a minor version may change the API.
write_basic_package_version_file("${PROJECT_BINARY_DIR}/scalemeshConfigVersion.cmake"
                                 COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/scalemeshConfig.cmake" "${PROJECT_BINARY_DIR}/scalemeshConfigVersion.cmake"
              cmake/scalemeshImportedTargets.cmake
        DESTINATION "${SCALEMESH_CMAKE_DIR}")
install(FILES README.md docs/case-file.md docs/user-guide.md DESTINATION "${CMAKE_INSTALL_DOCDIR}")
# The Gmsh GUI client (`gmsh share/scalemesh/scalemesh_gui.py`); it finds
# bin/scalemesh of the same prefix.
install(PROGRAMS tools/scalemesh_gui.py DESTINATION "${CMAKE_INSTALL_DATADIR}/scalemesh")

# The Debian package: scalemesh_<version>_<arch>.deb, its Depends computed
# from the binary's shared libraries by dpkg-shlibdeps (Debian package
# dpkg-dev).
set(CPACK_PACKAGE_NAME scalemesh)
set(CPACK_PACKAGE_VENDOR "scalemesh")
set(CPACK_PACKAGE_CONTACT "scalemesh maintainers <scalemesh@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "scale-invariant layered tetrahedral meshes from segmented images, for CFD")
set(CPACK_PACKAGE_VERSION "${PROJECT_VERSION}")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_GENERATOR DEB)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# The Allrun script each OpenFOAM case gets runs Debian's OpenFOAM; the
# Python module's MeshResult.to_meshio imports meshio.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "openfoam, python3-meshio")
# The Python module imports numpy and speaks to gmsh.py's model.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "python3-numpy, python3-gmsh")
include(CPack)
