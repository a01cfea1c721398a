# `cmake --install build --prefix P`: the command line (bin/scalemesh), the
# library (include/scalemesh/ and the shared libscalemesh.so.0 in LIBDIR,
# lib/x86_64-linux-gnu on Debian), the Python module and its type stub
# (lib/python3/dist-packages) and a CMake package, LIBDIR/cmake/scalemesh, for
#   find_package(scalemesh REQUIRED)
#   target_link_libraries(app PRIVATE scalemesh::scalemesh)
# libscalemesh.so holds the stage libraries and links the third-party shared
# libraries itself, privately: the package finds nothing for the user, who
# links one library (and needs C++17 for the headers).
#
# `cpack -G DEB` in the build directory packs the same files as three .debs,
# one per install component:
#   scalemesh          (runtime) bin/scalemesh, libscalemesh.so.0, the docs,
#                      the Gmsh GUI client
#   libscalemesh-dev   (dev)     the headers, the CMake package, the
#                                libscalemesh.so link
#   python3-scalemesh  (python)  the Python module and its .pyi
# The command line and the Python module hold the stage libraries themselves
# (static), so neither needs libscalemesh.so.

include(CMakePackageConfigHelpers)

set(SCALEMESH_CMAKE_DIR "${CMAKE_INSTALL_LIBDIR}/cmake/scalemesh")

install(TARGETS scalemesh RUNTIME DESTINATION "${CMAKE_INSTALL_BINDIR}" COMPONENT runtime)
install(TARGETS scalemesh_library EXPORT scalemeshTargets
        LIBRARY DESTINATION "${CMAKE_INSTALL_LIBDIR}" COMPONENT runtime NAMELINK_COMPONENT dev)
install(FILES include/scalemesh/scalemesh.h include/scalemesh/mesh.h include/scalemesh/gmsh_model.h
        "${PROJECT_BINARY_DIR}/generated/include/scalemesh/errors.h"
        DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/scalemesh" COMPONENT dev)
# The Python module (src/python/) where Debian's python3 finds it: with the
# prefix /usr (the .deb) /usr/lib/python3/dist-packages; with another prefix
# P, P/lib/python3/dist-packages (add it to PYTHONPATH).
set(SCALEMESH_PYTHON_INSTALL_DIR "lib/python3/dist-packages" CACHE STRING
    "Where the Python module is installed, relative to the install prefix")
install(TARGETS scalemesh_python LIBRARY DESTINATION "${SCALEMESH_PYTHON_INSTALL_DIR}" COMPONENT python)
# Its type stub, beside it (PEP 484: a .pyi next to the extension module).
install(FILES src/python/scalemesh.pyi DESTINATION "${SCALEMESH_PYTHON_INSTALL_DIR}" COMPONENT python)
install(EXPORT scalemeshTargets NAMESPACE scalemesh:: DESTINATION "${SCALEMESH_CMAKE_DIR}" COMPONENT dev)

configure_package_config_file(cmake/scalemeshConfig.cmake.in "${PROJECT_BINARY_DIR}/scalemeshConfig.cmake"
                              INSTALL_DESTINATION "${SCALEMESH_CMAKE_DIR}")
# 0.x: a minor version may change the API (and the ABI: then
# SCALEMESH_SOVERSION, src/api/CMakeLists.txt, is raised).
write_basic_package_version_file("${PROJECT_BINARY_DIR}/scalemeshConfigVersion.cmake"
                                 COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/scalemeshConfig.cmake" "${PROJECT_BINARY_DIR}/scalemeshConfigVersion.cmake"
        DESTINATION "${SCALEMESH_CMAKE_DIR}" COMPONENT dev)
# The README beside the docs/ it links to, so that its links and pictures
# resolve in the installed copy.
install(FILES README.md DESTINATION "${CMAKE_INSTALL_DOCDIR}" COMPONENT runtime)
file(GLOB SCALEMESH_DOCS "${PROJECT_SOURCE_DIR}/docs/*.md" "${PROJECT_SOURCE_DIR}/docs/*.png")
install(FILES ${SCALEMESH_DOCS} DESTINATION "${CMAKE_INSTALL_DOCDIR}/docs" COMPONENT runtime)
install(DIRECTORY docs/images DESTINATION "${CMAKE_INSTALL_DOCDIR}/docs" COMPONENT runtime)
# The Gmsh GUI client (`gmsh share/scalemesh/scalemesh_gui.py`); it finds
# bin/scalemesh of the same prefix.
install(PROGRAMS tools/scalemesh_gui.py DESTINATION "${CMAKE_INSTALL_DATADIR}/scalemesh" COMPONENT runtime)

# The Debian packages: <name>_<version>_<arch>.deb, one per component, the
# Depends of each computed from its binaries' shared libraries by
# dpkg-shlibdeps (Debian package dpkg-dev), plus those named here.
set(CPACK_PACKAGE_NAME scalemesh)
set(CPACK_PACKAGE_VENDOR "scalemesh")
set(CPACK_PACKAGE_CONTACT "scalemesh maintainers <scalemesh@localhost>")
# No CPACK_PACKAGE_DESCRIPTION_SUMMARY: each package's synopsis is the first
# line of its component's description (CPackDeb would put that one summary
# above all three). CPackDeb indents the lines after it.
set(CPACK_PACKAGE_VERSION "${PROJECT_VERSION}")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_GENERATOR DEB)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL runtime dev python)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)

set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME scalemesh)
set(CPACK_COMPONENT_RUNTIME_DESCRIPTION
    "scale-invariant layered tetrahedral meshes from segmented images, for CFD
The scalemesh command line (surface, volume mesh and OpenFOAM case from a
segmented image or a surface) and the shared library libscalemesh.so.0.")
# A shlibs file for libscalemesh.so.0 (and ldconfig in postinst, postrm),
# with CPack's default policy "=": a binary built against this release asks
# for exactly this release, strict while scalemesh is 0.x.
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON)
# The Allrun script each OpenFOAM case gets runs Debian's OpenFOAM; the GUI
# client runs in gmsh.
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SUGGESTS "openfoam, gmsh")

set(CPACK_DEBIAN_DEV_PACKAGE_NAME libscalemesh-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_COMPONENT_DEV_DESCRIPTION
    "scalemesh library: development files
The C++ headers, the CMake package (find_package(scalemesh)) and the link
to libscalemesh.so.0. The package finds no other library: libscalemesh.so
links its dependencies itself.")
# The CMake package's config calls no find_dependency: the library only.
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS "scalemesh (= ${CPACK_PACKAGE_VERSION})")
# mesh_gmsh_model works in the host's Gmsh session, which the host links
# itself (include/scalemesh/gmsh_model.h).
set(CPACK_DEBIAN_DEV_PACKAGE_SUGGESTS "libgmsh-dev")

set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-scalemesh)
set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
set(CPACK_COMPONENT_PYTHON_DESCRIPTION
    "scalemesh for Python 3
The Python module scalemesh (mesh_surface, mesh_image, mesh_gmsh_model) for
Debian's python3, with its type stub.")
# The module returns NumPy arrays and speaks to gmsh.py's model; its
# MeshResult.to_meshio imports meshio.
set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS "python3, python3-numpy")
set(CPACK_DEBIAN_PYTHON_PACKAGE_RECOMMENDS "python3-gmsh")
set(CPACK_DEBIAN_PYTHON_PACKAGE_SUGGESTS "python3-meshio")
include(CPack)
