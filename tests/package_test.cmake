# The installed package as a user meets it: `cmake --install` of this build
# into a scratch prefix, then tests/package/ configured against it with
# find_package(scalemesh), built (C++17) and run (it meshes a sphere through
# the library and checks the result), and the installed Python module
# (tests/package/installed_python.py). Any failing step fails the test. The
# library is the shared libscalemesh.so.0 with its stages inside: no static
# library is installed, and the consumer's direct NEEDED entries (readelf -d)
# name libscalemesh.so.0 and none of the third-party libraries it links.
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... -DLIBDIR=lib/<arch> -P package_test.cmake

cmake_minimum_required(VERSION 3.22)
foreach(var BUILD_DIR SOURCE_DIR WORK_DIR LIBDIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "package_test.cmake needs -D${var}=...")
  endif()
endforeach()

file(REMOVE_RECURSE "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")

function(step name)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${name} failed (${code}):\n${out}\n${err}")
  endif()
  message(STATUS "${name}: ok\n${out}")
endfunction()

step("install" "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${prefix}")
foreach(file bin/scalemesh include/scalemesh/scalemesh.h include/scalemesh/mesh.h include/scalemesh/gmsh_model.h
             include/scalemesh/errors.h ${LIBDIR}/libscalemesh.so ${LIBDIR}/libscalemesh.so.0
             ${LIBDIR}/cmake/scalemesh/scalemeshConfig.cmake ${LIBDIR}/cmake/scalemesh/scalemeshConfigVersion.cmake
             ${LIBDIR}/cmake/scalemesh/scalemeshTargets.cmake lib/python3/dist-packages/scalemesh.pyi)
  if(NOT EXISTS "${prefix}/${file}")
    message(FATAL_ERROR "the install has no ${file}")
  endif()
endforeach()
file(GLOB_RECURSE archives "${prefix}/*.a")
if(archives)
  message(FATAL_ERROR "the install has static libraries: ${archives}")
endif()

# The direct NEEDED entries and the SONAME of an ELF file, as a list.
function(dynamic_section file out_needed out_soname)
  execute_process(COMMAND readelf -d "${file}" RESULT_VARIABLE code OUTPUT_VARIABLE text ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "readelf -d ${file} failed (${code}): ${err}")
  endif()
  string(REGEX MATCHALL "\\(NEEDED\\)[^[]*\\[[^]]*\\]" lines "${text}")
  set(needed "")
  foreach(line IN LISTS lines)
    string(REGEX REPLACE ".*\\[(.*)\\]" "\\1" name "${line}")
    list(APPEND needed "${name}")
  endforeach()
  set(soname "")
  if(text MATCHES "\\(SONAME\\)[^[]*\\[([^]]*)\\]")
    set(soname "${CMAKE_MATCH_1}")
  endif()
  set(${out_needed} "${needed}" PARENT_SCOPE)
  set(${out_soname} "${soname}" PARENT_SCOPE)
endfunction()

dynamic_section("${prefix}/${LIBDIR}/libscalemesh.so" lib_needed lib_soname)
if(NOT lib_soname STREQUAL "libscalemesh.so.0")
  message(FATAL_ERROR "the installed libscalemesh.so has the SONAME '${lib_soname}', not libscalemesh.so.0")
endif()
message(STATUS "libscalemesh.so: SONAME ${lib_soname}, NEEDED ${lib_needed}")
step("installed scalemesh --help" "${prefix}/bin/scalemesh" --help)

step("configure the consumer" "${CMAKE_COMMAND}" -S "${SOURCE_DIR}/tests/package" -B "${WORK_DIR}/consumer"
     -G Ninja -DCMAKE_BUILD_TYPE=Release "-DCMAKE_PREFIX_PATH=${prefix}")
step("build the consumer" "${CMAKE_COMMAND}" --build "${WORK_DIR}/consumer")
# A consumer links one library: the third-party ones stay behind
# libscalemesh.so.0.
dynamic_section("${WORK_DIR}/consumer/consumer" consumer_needed consumer_soname)
message(STATUS "consumer: NEEDED ${consumer_needed}")
if(NOT "libscalemesh.so.0" IN_LIST consumer_needed)
  message(FATAL_ERROR "the consumer does not need libscalemesh.so.0: NEEDED ${consumer_needed}")
endif()
foreach(name IN LISTS consumer_needed)
  if(name MATCHES "^lib(ITK|itk|hdf5|gmsh|openvdb|Imath|tbb|embree|gmp|mpfr|png|expat|tinyobjloader|tomlplusplus)")
    message(FATAL_ERROR "the consumer links ${name} directly: NEEDED ${consumer_needed}")
  endif()
endforeach()
step("run the consumer" "${WORK_DIR}/consumer/consumer")
# The installed Python module: the shared aorta STL through mesh_image, its
# case through checkMesh, to_meshio, a NumPy ball of voxels.
step("the installed Python module" "${CMAKE_COMMAND}" -E env
     "PYTHONPATH=${prefix}/lib/python3/dist-packages" "WM_PROJECT_DIR=/usr/share/openfoam"
     /usr/bin/python3 "${SOURCE_DIR}/tests/package/installed_python.py" "${prefix}"
     "${SOURCE_DIR}/../shared/data/vmtk_aorta_capped.stl")
file(REMOVE_RECURSE "${WORK_DIR}")
