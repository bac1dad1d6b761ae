# Reliability faults (issue 17, docs/reliability.md): a full disk during a
# write (an LD_PRELOAD shim), litter of killed processes, no HOME, physics
# guards and checksums.
add_library(bk_enospc_shim MODULE ${BAKER_TEST_DIR}/enospc_shim.c)
target_link_libraries(bk_enospc_shim PRIVATE ${CMAKE_DL_LIBS})
if(BAKER_SANITIZE)
  # An LD_PRELOAD library loads before the executable's ASan runtime; built
  # with ASan it would need that runtime first. It stays uninstrumented (and
  # scripts/sanitize.sh sets verify_asan_link_order=0).
  target_compile_options(bk_enospc_shim PRIVATE -fno-sanitize=all)
  target_link_options(bk_enospc_shim PRIVATE -fno-sanitize=all)
endif()
foreach(case enospc_vdb fsync_vdb enospc_exr enospc_png stale_temp no_home huge_intensity
        coarse_step fine_step verify verify_absurd view_checksum view_handover mesh_headers mesh_isolated)
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
