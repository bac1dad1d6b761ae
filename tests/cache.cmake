# The kernel cache's cap and `baker cache` (issue 14, item 6).
add_executable(test_clcache ${BAKER_TEST_DIR}/test_clcache.c)
target_link_libraries(test_clcache PRIVATE bakercore)
add_test(NAME clcache_prune COMMAND test_clcache ${CMAKE_CURRENT_BINARY_DIR}/clcache_unit)

add_test(NAME cli_cache
         COMMAND bash ${BAKER_TEST_DIR}/cache_cmd.sh $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/cli_cache ${CMAKE_SOURCE_DIR}/scenes)
