# The installed package as a user meets it: `cmake --install` of this build
# into a scratch prefix, then tests/package/ configured against it with
# find_package(scalemesh), built and run (it meshes a sphere through the
# library and checks the result). Any failing step fails the test.
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... -P package_test.cmake

foreach(var BUILD_DIR SOURCE_DIR WORK_DIR)
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
foreach(file bin/scalemesh include/scalemesh/scalemesh.h include/scalemesh/mesh.h include/scalemesh/errors.h
             lib/libscalemesh.a lib/cmake/scalemesh/scalemeshConfig.cmake
             lib/cmake/scalemesh/scalemeshConfigVersion.cmake lib/cmake/scalemesh/scalemeshTargets.cmake
             lib/python3/dist-packages/scalemesh.pyi)
  if(NOT EXISTS "${prefix}/${file}")
    message(FATAL_ERROR "the install has no ${file}")
  endif()
endforeach()
step("installed scalemesh --help" "${prefix}/bin/scalemesh" --help)

step("configure the consumer" "${CMAKE_COMMAND}" -S "${SOURCE_DIR}/tests/package" -B "${WORK_DIR}/consumer"
     -G Ninja -DCMAKE_BUILD_TYPE=Release "-DCMAKE_PREFIX_PATH=${prefix}")
step("build the consumer" "${CMAKE_COMMAND}" --build "${WORK_DIR}/consumer")
step("run the consumer" "${WORK_DIR}/consumer/consumer")
file(REMOVE_RECURSE "${WORK_DIR}")
