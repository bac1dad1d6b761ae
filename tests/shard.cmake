# Photon shards and `baker merge` (issue 14 item 3): test_shard bakes the
# sphere scene whole and in 1, 2, 5 shards through the commands themselves and
# compares the grids bit for bit (reference; adaptive without the filter) or
# within 1e-5 (adaptive with the filter, which the merge runs on the host);
# refusals of shards that do not belong together; the photon ranges; shards
# baked on the host and on OpenCL merged bit for bit.
add_executable(test_shard ${BAKER_TEST_DIR}/test_shard.c)
target_link_libraries(test_shard PRIVATE bakercore)
set(SHARD_OUT ${CMAKE_BINARY_DIR}/shard_tests)
file(MAKE_DIRECTORY ${SHARD_OUT})
foreach(t reference adaptive refuse range anisotropic mixed)
  add_test(NAME shard_${t} COMMAND test_shard ${CMAKE_SOURCE_DIR}/scenes ${SHARD_OUT} ${t})
endforeach()
set_tests_properties(shard_reference shard_adaptive shard_refuse shard_anisotropic shard_mixed PROPERTIES
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/kernel-cache" TIMEOUT 300)
