# The farm recipes run for real under their schedulers (scripts/farm/,
# issue 14 item 4); skipped with a message when the scheduler is missing.
add_test(NAME farm_slurm
         COMMAND bash ${BAKER_TEST_DIR}/farm_slurm.sh $<TARGET_FILE:baker> ${CMAKE_SOURCE_DIR}
                 ${CMAKE_BINARY_DIR}/farm_slurm)
add_test(NAME farm_parallel
         COMMAND bash ${BAKER_TEST_DIR}/farm_parallel.sh $<TARGET_FILE:baker> ${CMAKE_SOURCE_DIR}
                 ${CMAKE_BINARY_DIR}/farm_parallel)
set_tests_properties(farm_slurm farm_parallel PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 180
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/kernel-cache")
