# The Debian packages on this machine: `cpack -G DEB` of this build makes
# three, scalemesh (command line and libscalemesh.so.0), libscalemesh-dev
# (headers, CMake package, the .so link) and python3-scalemesh (the module),
# whose names, files and Depends are checked (dpkg-deb); then `dpkg -i` of
# the three (root only: the test fails, saying so, when not root), the
# installed /usr/bin/scalemesh answers --help and writes a phantom, the
# library is in the multiarch directory and python3 imports the module;
# finally `dpkg -r` leaves the machine as it was. A failing step removes
# what the test installed and made as well (cleanup).
#   cmake -DBUILD_DIR=... -DWORK_DIR=... -DLIBDIR=lib/<arch> [-DPACK_ONLY=ON] -P deb_test.cmake
# PACK_ONLY: make and check the packages only, install nothing (no root).

cmake_minimum_required(VERSION 3.22)
foreach(var BUILD_DIR WORK_DIR LIBDIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "deb_test.cmake needs -D${var}=...")
  endif()
endforeach()

execute_process(COMMAND id -u OUTPUT_VARIABLE uid OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT uid STREQUAL "0" AND NOT PACK_ONLY)
  message(FATAL_ERROR "deb_install needs root to run dpkg -i (uid here: ${uid}); run ctest as root, as CI does")
endif()

# What the test installs (set(installed ON) before dpkg -i, which may fail
# with some of them unpacked) and makes (WORK_DIR) goes again, on failure
# as on success.
set(installed OFF)
function(cleanup)
  if(installed)
    execute_process(COMMAND dpkg -r python3-scalemesh libscalemesh-dev scalemesh)
  endif()
  file(REMOVE_RECURSE "${WORK_DIR}")
endfunction()

# fail(text): the test fails, saying `text`, after cleanup.
function(fail text)
  cleanup()
  message(FATAL_ERROR "${text}")
endfunction()

function(step name)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    fail("${name} failed (${code}):\n${out}\n${err}")
  endif()
  message(STATUS "${name}: ok\n${out}")
  set(step_output "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
step("cpack -G DEB" "${CMAKE_CPACK_COMMAND}" -G DEB -B "${WORK_DIR}" --config "${BUILD_DIR}/CPackConfig.cmake")
file(GLOB debs RELATIVE "${WORK_DIR}" "${WORK_DIR}/*.deb")
list(SORT debs)
list(LENGTH debs count)
if(NOT count EQUAL 3)
  fail("cpack made ${count} .deb files in ${WORK_DIR}, not three: ${debs}")
endif()

# check(package depends_regex file_regex...): the package's .deb, its name,
# a Depends matching the regex, and the files (paths under /usr) it holds.
set(packages "")
function(check package depends)
  file(GLOB deb "${WORK_DIR}/${package}_*.deb")
  if(NOT deb)
    fail("cpack made no ${package}_*.deb: ${debs}")
  endif()
  step("dpkg-deb --field ${package}" dpkg-deb --field "${deb}" Package Depends)
  set(depends_field "")
  if(step_output MATCHES "Depends: ([^\n]*)")
    set(depends_field "${CMAKE_MATCH_1}")
  endif()
  if(NOT step_output MATCHES "Package: ${package}\n" OR NOT depends_field MATCHES "${depends}")
    fail("${package}: the control fields lack the name or a Depends matching '${depends}':\n${step_output}")
  endif()
  execute_process(COMMAND dpkg-deb --contents "${deb}" OUTPUT_VARIABLE contents RESULT_VARIABLE code)
  if(NOT code EQUAL 0)
    fail("dpkg-deb --contents ${deb} failed (${code})")
  endif()
  foreach(file IN LISTS ARGN)
    if(NOT contents MATCHES " \\./usr/${file}( |\n)")
      fail("${package} holds no /usr/${file}:\n${contents}")
    endif()
  endforeach()
  set(packages ${packages} "${deb}" PARENT_SCOPE)
endfunction()
# The library's Depends come from dpkg-shlibdeps; the -dev package's config
# finds no other package, so it depends on the library only.
check(scalemesh "libopenvdb" bin/scalemesh "${LIBDIR}/libscalemesh\\.so\\.0")
check(libscalemesh-dev "^scalemesh \\(= [0-9.]+\\)$" "include/scalemesh/scalemesh\\.h"
      "${LIBDIR}/libscalemesh\\.so" "${LIBDIR}/cmake/scalemesh/scalemeshConfig\\.cmake")
check(python3-scalemesh "^python3, python3-numpy, " "lib/python3/dist-packages/scalemesh\\.cpython-[^ ]*\\.so"
      "lib/python3/dist-packages/scalemesh\\.pyi")
if(PACK_ONLY)
  cleanup()
  return()
endif()

set(installed ON)
step("dpkg -i" dpkg -i ${packages})
step("scalemesh --help" /usr/bin/scalemesh --help)
if(NOT step_output MATCHES "Usage" OR NOT step_output MATCHES "run")
  fail("the installed scalemesh --help printed no usage:\n${step_output}")
endif()
step("scalemesh phantom" /usr/bin/scalemesh phantom sphere --voxel-size 2 -o "${WORK_DIR}/sphere.vdb")
if(NOT EXISTS "${WORK_DIR}/sphere.vdb")
  fail("the installed scalemesh wrote no phantom")
endif()
step("ldconfig -p" /sbin/ldconfig -p)
# With the merged /usr of Debian 12 the cache names /lib/... for /usr/lib/...
if(NOT step_output MATCHES "libscalemesh\\.so\\.0 [^\n]*=> (/usr)?/${LIBDIR}/libscalemesh\\.so\\.0")
  fail("the loader does not know /usr/${LIBDIR}/libscalemesh.so.0")
endif()
# No ';' in the code: a CMake argument list would split it there.
step("python3 -c 'import scalemesh'" /usr/bin/python3 -c "print(__import__('scalemesh').__file__)")
if(NOT step_output MATCHES "^/usr/lib/python3/dist-packages/scalemesh")
  fail("python3 imported scalemesh from elsewhere: ${step_output}")
endif()
step("dpkg -r" dpkg -r python3-scalemesh libscalemesh-dev scalemesh)
set(installed OFF)
cleanup()
