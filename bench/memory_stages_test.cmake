# bench_pipeline records each stage's memory (issue 45): two small boxes
# run once, then the result file must give, for every run, every stage of
# the pipeline and the writing of the outputs, each with a positive peak at
# least what it left resident; and the memory
# section written from them must hold the tables and the fitted model.
# Asserts what is recorded, not how fast or how much.
#   cmake -DBENCH=<bench_pipeline> -DWORK_DIR=<dir> -P memory_stages_test.cmake
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
execute_process(COMMAND "${BENCH}" --boxes 32,48 --repeats 1 --threads 2 --no-mesh-3 --no-snappy
                        --json "${WORK_DIR}/result.json" --plot "${WORK_DIR}/plot.png"
                        --memory-doc "${WORK_DIR}/memory.md"
                WORKING_DIRECTORY "${WORK_DIR}" RESULT_VARIABLE status OUTPUT_VARIABLE output ERROR_VARIABLE output)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "bench_pipeline failed (${status}):\n${output}")
endif()
if(NOT output MATCHES "\\| stage \\| peak MiB \\| peak B/tet \\| held after MiB \\| held B/tet \\|")
  message(FATAL_ERROR "bench_pipeline printed no memory per stage table:\n${output}")
endif()

file(READ "${WORK_DIR}/result.json" result)
string(JSON sizes LENGTH "${result}" sizes)
if(NOT sizes EQUAL 2)
  message(FATAL_ERROR "expected 2 sizes in the result, got ${sizes}")
endif()
set(expected import isosurface smoothing sizing remeshing volume write)
math(EXPR last_size "${sizes} - 1")
foreach(i RANGE ${last_size})
  string(JSON run GET "${result}" sizes ${i} runs 0)
  string(JSON run_peak GET "${run}" peak_bytes)
  string(JSON count LENGTH "${run}" memory_stages)
  set(names)
  math(EXPR last_stage "${count} - 1")
  foreach(k RANGE ${last_stage})
    string(JSON name GET "${run}" memory_stages ${k} stage)
    string(JSON peak GET "${run}" memory_stages ${k} peak_bytes)
    string(JSON held GET "${run}" memory_stages ${k} held_after_bytes)
    list(APPEND names ${name})
    # if() compares numbers as doubles, so "4.4e+07" as written by the JSON library is fine.
    if(NOT peak GREATER 0 OR peak LESS held)
      message(FATAL_ERROR "size ${i}, stage ${name}: peak ${peak}, held after ${held}, run peak ${run_peak}")
    endif()
  endforeach()
  if(NOT names STREQUAL expected)
    message(FATAL_ERROR "size ${i}: stages recorded '${names}', expected '${expected}'")
  endif()
endforeach()

file(READ "${WORK_DIR}/memory.md" memory)
foreach(part "## Memory per stage" "Memory per stage, 32x" "Memory per stage, 48x" "bytes = " "| 24 GiB |" "| 128 GiB |")
  string(FIND "${memory}" "${part}" at)
  if(at LESS 0)
    message(FATAL_ERROR "the memory section lacks '${part}':\n${memory}")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK_DIR}")
