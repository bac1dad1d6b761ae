# Reliability faults (issue 17, docs/reliability.md): a full disk during a
# write (an LD_PRELOAD shim), litter of killed processes, no HOME, physics
# guards and checksums.
add_library(bk_enospc_shim MODULE ${BAKER_TEST_DIR}/enospc_shim.c)
target_link_libraries(bk_enospc_shim PRIVATE ${CMAKE_DL_LIBS})
foreach(case enospc_vdb fsync_vdb enospc_exr enospc_png stale_temp no_home huge_intensity
        coarse_step verify view_checksum)
  add_test(NAME reliability_${case}
           COMMAND bash ${BAKER_TEST_DIR}/reliability.sh $<TARGET_FILE:baker>
                   ${CMAKE_BINARY_DIR}/reliability ${CMAKE_SOURCE_DIR}/scenes
                   $<TARGET_FILE:bk_enospc_shim> ${case})
endforeach()

# Untrusted VDB input (issue 17 item 2): seeded byte flips of a blosc, zip
# and uncompressed bake through view and bake under a memory cap; every run
# exit 0 or 2. scripts/vdb_flip_sweep is the full sweep.
add_test(NAME reliability_vdb_flips
         COMMAND ${Python3_EXECUTABLE} ${BAKER_TEST_DIR}/vdb_flip.py $<TARGET_FILE:baker>
                 ${CMAKE_SOURCE_DIR}/scenes ${CMAKE_BINARY_DIR}/reliability/vdb_flips
                 --flips 25 --bakes 2 --timeout 60)
