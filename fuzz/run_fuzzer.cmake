# cmake -D FUZZER=... -D SEEDS=dir -D REGRESSIONS=dir -D WORK=dir -D SECONDS=n -P run_fuzzer.cmake
# One bounded libFuzzer run for ctest. New inputs go to WORK/corpus, the first
# corpus directory, so the seeds and the committed regressions stay as they
# are; a crash input is kept in WORK/artifacts.
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}/corpus" "${WORK}/artifacts")
set(corpora "${WORK}/corpus" "${SEEDS}")
if(EXISTS "${REGRESSIONS}")
  list(APPEND corpora "${REGRESSIONS}")
endif()
# SECONDS 0: read the seeds and regressions once each, without fuzzing.
if(SECONDS EQUAL 0)
  set(bound -runs=0)
else()
  set(bound -max_total_time=${SECONDS})
endif()
execute_process(COMMAND "${FUZZER}" ${bound} -rss_limit_mb=2048 -timeout=10
                        "-artifact_prefix=${WORK}/artifacts/" -print_final_stats=1 ${corpora}
                RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "${FUZZER} failed (${result}); the input is in ${WORK}/artifacts. "
                      "Replay it with: ${FUZZER} <that file>")
endif()
