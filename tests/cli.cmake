# End-to-end checks of `baker bake` on bad input (issue 2): each case must exit
# 2, name the file and the problem, and leave no output file.
foreach(case malformed_json missing_key wrong_type negative_resolution huge_grid
        missing_mesh nan_mesh empty_mesh unwritable_output truncated_ior_vdb)
  add_test(NAME cli_bad_${case}
           COMMAND bash ${BAKER_TEST_DIR}/cli_bad_input.sh $<TARGET_FILE:baker>
                   ${CMAKE_BINARY_DIR}/cli_bad ${CMAKE_SOURCE_DIR}/scenes/meshes ${case})
endforeach()

# Frame ranges, restart and Slurm array tasks (DESIGN §6-7).
add_test(NAME cli_bake_frames
         COMMAND bash ${BAKER_TEST_DIR}/bake_frames.sh $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/cli_frames ${CMAKE_SOURCE_DIR}/scenes)
