# Benchmark harness (issue 6): the image-difference tool scripts/bench uses,
# and tests that keep the harness from rotting. Timings are never asserted.
add_executable(bench_tool ${CMAKE_SOURCE_DIR}/scripts/bench_tool.c)
target_link_libraries(bench_tool PRIVATE bakercore)

# The metric code on closed forms: trilinear resampling of a linear field,
# relative L2, Pareto front, power-law fit, cone/box chord energy integral.
add_test(NAME bench_metrics
         COMMAND /usr/bin/python3 ${BAKER_TEST_DIR}/bench_check.py metrics
                 ${CMAKE_SOURCE_DIR}/scripts)

# A tiny sweep end to end (3 runs at 32^3, a reference, one analytic energy
# row), then checks that the JSON carries every field the plots and tables
# need and that the PNG plot was written.
set(BENCH_TINY_DIR ${CMAKE_BINARY_DIR}/bench_tiny)
add_test(NAME bench_harness
         COMMAND /usr/bin/python3 ${BAKER_TEST_DIR}/bench_check.py harness
                 ${CMAKE_SOURCE_DIR}/scripts $<TARGET_FILE:baker> $<TARGET_FILE:bench_tool>
                 ${BENCH_TINY_DIR})
set_tests_properties(bench_harness PROPERTIES TIMEOUT 300)
