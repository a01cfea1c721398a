# The Debian package on this machine: `cpack -G DEB` of this build, `dpkg -i`
# of the .deb (root only: the test fails, saying so, when not root), then the
# installed /usr/bin/scalemesh answers --help and writes a phantom; finally
# `dpkg -r scalemesh` leaves the machine as it was.
#   cmake -DBUILD_DIR=... -DWORK_DIR=... -P deb_test.cmake

foreach(var BUILD_DIR WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "deb_test.cmake needs -D${var}=...")
  endif()
endforeach()

execute_process(COMMAND id -u OUTPUT_VARIABLE uid OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT uid STREQUAL "0")
  message(FATAL_ERROR "deb_install needs root to run dpkg -i (uid here: ${uid}); run ctest as root, as CI does")
endif()

function(step name)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${name} failed (${code}):\n${out}\n${err}")
  endif()
  message(STATUS "${name}: ok\n${out}")
  set(step_output "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
step("cpack -G DEB" "${CMAKE_CPACK_COMMAND}" -G DEB -B "${WORK_DIR}" --config "${BUILD_DIR}/CPackConfig.cmake")
file(GLOB debs "${WORK_DIR}/scalemesh_*.deb")
list(LENGTH debs count)
if(NOT count EQUAL 1)
  message(FATAL_ERROR "cpack made ${count} .deb files in ${WORK_DIR}, not one")
endif()
step("dpkg-deb --field" dpkg-deb --field "${debs}" Package Depends)
if(NOT step_output MATCHES "Package: scalemesh" OR NOT step_output MATCHES "libopenvdb")
  message(FATAL_ERROR "the package's control fields lack the name or the dependencies:\n${step_output}")
endif()

step("dpkg -i" dpkg -i "${debs}")
step("scalemesh --help" /usr/bin/scalemesh --help)
if(NOT step_output MATCHES "Usage" OR NOT step_output MATCHES "run")
  message(FATAL_ERROR "the installed scalemesh --help printed no usage:\n${step_output}")
endif()
step("scalemesh phantom" /usr/bin/scalemesh phantom sphere --voxel-size 2 -o "${WORK_DIR}/sphere.vdb")
if(NOT EXISTS "${WORK_DIR}/sphere.vdb")
  message(FATAL_ERROR "the installed scalemesh wrote no phantom")
endif()
step("dpkg -r" dpkg -r scalemesh)
file(REMOVE_RECURSE "${WORK_DIR}")
