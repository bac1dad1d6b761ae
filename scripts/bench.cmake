# Benchmarks (issue 6): the programs the scripts/bench* drivers run, built
# with everything else and never run by ctest, and two tests that keep the
# harness from rotting. Timings are never asserted.
set(BAKER_SCRIPTS_DIR ${CMAKE_SOURCE_DIR}/scripts)
add_executable(bench_tool ${BAKER_SCRIPTS_DIR}/bench_tool.c)              # scripts/bench: image errors
add_executable(bench_voxelize ${BAKER_SCRIPTS_DIR}/bench_voxelize.c)      # scripts/bench_voxelize
add_executable(bench_march_run ${BAKER_SCRIPTS_DIR}/bench_march_run.c)    # scripts/bench_march
add_executable(bench_adaptive_run ${BAKER_SCRIPTS_DIR}/bench_adaptive_run.c) # scripts/bench_adaptive
add_executable(bench_error_run ${BAKER_SCRIPTS_DIR}/bench_error_run.c)    # scripts/bench_error
foreach(t bench_tool bench_voxelize bench_march_run bench_adaptive_run bench_error_run)
  target_link_libraries(${t} PRIVATE bakercore)
endforeach()
# the plain OpenMP march, the yardstick of scripts/bench_march (issue 15)
find_package(OpenMP COMPONENTS C)
if(OpenMP_C_FOUND)
  target_link_libraries(bench_march_run PRIVATE OpenMP::OpenMP_C)
endif()

# The metric code on closed forms: trilinear resampling of a linear field,
# relative L2, Pareto front, power-law fit, cone/box chord energy integral.
add_test(NAME bench_metrics
         COMMAND /usr/bin/python3 ${BAKER_SCRIPTS_DIR}/bench_check.py metrics
                 ${BAKER_SCRIPTS_DIR})

# A tiny sweep end to end (3 runs at 32^3, a reference, one analytic energy
# row), then checks that the JSON carries every field the plots and tables
# need and that the PNG plot was written.
set(BENCH_TINY_DIR ${CMAKE_BINARY_DIR}/bench_tiny)
add_test(NAME bench_harness
         COMMAND /usr/bin/python3 ${BAKER_SCRIPTS_DIR}/bench_check.py harness
                 ${BAKER_SCRIPTS_DIR} $<TARGET_FILE:baker> $<TARGET_FILE:bench_tool>
                 ${BENCH_TINY_DIR})
set_tests_properties(bench_harness PROPERTIES TIMEOUT 300)

# The POV-Ray yardstick's scene translation (scripts/pov/scene2pov.py): the
# committed sphere.pov is current, bad keys are refused, and a lit fog has
# the same mean luminance in POV-Ray as in baker (skipped without povray).
add_test(NAME pov_scene
         COMMAND /usr/bin/python3 ${BAKER_SCRIPTS_DIR}/bench_check.py pov
                 ${BAKER_SCRIPTS_DIR} $<TARGET_FILE:baker> ${CMAKE_BINARY_DIR}/pov_scene)
set_tests_properties(pov_scene PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 120)
