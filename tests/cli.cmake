# End-to-end checks of `baker bake` on bad input (issue 2): each case must exit
# 2, name the file and the problem, and leave no output file.
foreach(case malformed_json missing_key wrong_type negative_resolution huge_grid
        missing_mesh nan_mesh empty_mesh unwritable_output truncated_ior_vdb fifo_mesh
        device_vdb)
  add_test(NAME cli_bad_${case}
           COMMAND bash ${BAKER_TEST_DIR}/cli_bad_input.sh $<TARGET_FILE:baker>
                   ${CMAKE_BINARY_DIR}/cli_bad ${CMAKE_SOURCE_DIR}/scenes/meshes ${case})
endforeach()

# Frame ranges, restart and Slurm array tasks (DESIGN §6-7).
add_test(NAME cli_bake_frames
         COMMAND bash ${BAKER_TEST_DIR}/bake_frames.sh $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/cli_frames ${CMAKE_SOURCE_DIR}/scenes)

# getopt_long: `--opt=value` as well as `--opt value`, and --version on each
# subcommand (exit 0).
add_test(NAME cli_bake_equals_form
         COMMAND $<TARGET_FILE:baker> bake ${CMAKE_SOURCE_DIR}/scenes/cube.json --photons=1000
                 --resolution=16 --output=${CMAKE_BINARY_DIR}/cli_equals.vdb --force -q)
set_tests_properties(cli_bake_equals_form PROPERTIES FIXTURES_SETUP cli_equals)
add_test(NAME cli_view_equals_form
         COMMAND $<TARGET_FILE:baker> view ${CMAKE_BINARY_DIR}/cli_equals.vdb --resolution=8x6
                 --output=${CMAKE_BINARY_DIR}/cli_equals.exr -q)
set_tests_properties(cli_view_equals_form PROPERTIES FIXTURES_REQUIRED cli_equals)
add_test(NAME cli_bake_version COMMAND $<TARGET_FILE:baker> bake --version)
add_test(NAME cli_view_version COMMAND $<TARGET_FILE:baker> view --version)

# The memory budget (baker/budget.h): refusal before any work, --max-memory,
# an estimate not below the real peak, and a batch of frames that drops its
# kept fields rather than be refused; a grey bake that fits only with its σ
# coded, coded; and the view's (baker/view_budget.h);
# a grid whose buffers the OpenCL device cannot hold, refused before work.
foreach(case refuse max_memory honest frames_fallback code_grey view_refuse view_honest
        device_bake device_bake_vdb device_view)
  add_test(NAME cli_budget_${case}
           COMMAND bash ${BAKER_TEST_DIR}/budget.sh $<TARGET_FILE:baker>
                   ${CMAKE_BINARY_DIR}/cli_budget ${CMAKE_SOURCE_DIR}/scenes ${case})
endforeach()
set_tests_properties(cli_budget_honest cli_budget_view_honest cli_budget_code_grey PROPERTIES
                     SKIP_RETURN_CODE 77 RUN_SERIAL TRUE)
set_tests_properties(cli_budget_device_bake_vdb cli_budget_device_view PROPERTIES
                     SKIP_RETURN_CODE 77)

# Peak memory per voxel (docs/memory.md): the slope of the peak RSS between
# 128^3 and 192^3 for a grey and an RGB medium, against the measured level.
add_test(NAME cli_memory_per_voxel
         COMMAND bash ${BAKER_TEST_DIR}/memory_per_voxel.sh $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/cli_memory ${CMAKE_SOURCE_DIR}/scenes)
set_tests_properties(cli_memory_per_voxel PROPERTIES SKIP_RETURN_CODE 77 RUN_SERIAL TRUE)

# An object in a vacuum: the bake covers the box around it (baker/vox_crop.h),
# equal to the whole grid's bake there, and its memory does not grow with
# grid.bounds.
add_test(NAME cli_crop_vacuum
         COMMAND bash ${BAKER_TEST_DIR}/crop_vacuum.sh $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/cli_crop ${CMAKE_SOURCE_DIR}/scenes)
set_tests_properties(cli_crop_vacuum PROPERTIES RUN_SERIAL TRUE)

# The light scattered towards the scene's camera (radiance_camera): written
# with g != 0 and a camera, used by the view from that camera only, merged
# from shards bit for bit.
add_test(NAME cli_camera_phase
         COMMAND bash ${BAKER_TEST_DIR}/camera_phase.sh $<TARGET_FILE:baker>
                 $<TARGET_FILE:bench_tool> ${CMAKE_BINARY_DIR}/cli_camera_phase)
set_tests_properties(cli_camera_phase PROPERTIES
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/kernel-cache")

# Keyframed lights and frame reuse (docs/animation.md): a light-only batch
# voxelizes once and writes grids bit-identical to single-frame bakes.
add_test(NAME cli_bake_reuse
         COMMAND bash ${BAKER_TEST_DIR}/bake_reuse.sh $<TARGET_FILE:baker>
                 ${CMAKE_BINARY_DIR}/cli_reuse ${CMAKE_SOURCE_DIR}/scenes)
set_tests_properties(cli_bake_reuse PROPERTIES SKIP_RETURN_CODE 77)

# A keyframed camera through one bake: `baker view --frames` reads the file
# once and renders each frame as a single view with that frame's camera.
add_test(NAME cli_view_camera_frames
         COMMAND bash ${BAKER_TEST_DIR}/view_camera_frames.sh $<TARGET_FILE:baker>
                 $<TARGET_FILE:bench_tool> ${CMAKE_BINARY_DIR}/cli_view_camera ${CMAKE_SOURCE_DIR}/scenes)
