# scripts/gpu-check (issue 14 item 5): "no non-PoCL device" on a machine
# without a GPU, and the whole path with PoCL standing in for the GPU.
add_test(NAME gpu_check
         COMMAND bash ${BAKER_TEST_DIR}/gpu_check.sh ${CMAKE_SOURCE_DIR} $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/gpu_check $<TARGET_FILE:bench_tool>)
set_tests_properties(gpu_check PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 120
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/kernel-cache")

# The batch runner's ways to the sums (mapped on a CPU device, copied as on
# a GPU with PoCL standing in, the host's C march): bit for bit alike.
add_test(NAME buffer_paths
         COMMAND bash ${BAKER_TEST_DIR}/buffer_paths.sh ${CMAKE_SOURCE_DIR} $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/buffer_paths $<TARGET_FILE:bench_tool>)
set_tests_properties(buffer_paths PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 180
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/kernel-cache")
