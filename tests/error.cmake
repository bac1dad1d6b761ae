# The bake's error estimate (issue 11): test_error on the sphere scene at
# 32^3 — the estimate against a truth bake, reproducible bits and batches,
# the command's metadata, grid, --stats JSON and refused values; the same
# for the adaptive pipeline, with its target and budget; the order
# statistic behind the lit threshold; and target mode's integrator choice.
add_executable(test_error ${BAKER_TEST_DIR}/test_error.c)
target_link_libraries(test_error PRIVATE bakercore)
set(ERROR_OUT ${CMAKE_BINARY_DIR}/error_tests)
file(MAKE_DIRECTORY ${ERROR_OUT})
foreach(t honest bits cli adaptive rank step_bound)
  add_test(NAME error_${t} COMMAND test_error ${CMAKE_SOURCE_DIR}/scenes ${ERROR_OUT} ${t})
  set_tests_properties(error_${t} PROPERTIES
                       ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/kernel-cache" TIMEOUT 300)
endforeach()
