# Frame lists (base/frames): fileseq/Deadline/OpenJD syntax, order, refusals.
add_executable(test_frames ${BAKER_TEST_DIR}/test_frames.c)
target_link_libraries(test_frames PRIVATE bakercore)
add_test(NAME frames_list_syntax COMMAND test_frames)

# The farm side of `baker bake` (issue 13 items 5-6, issue 17 item 3): one
# case per behaviour, each in its own directory.
foreach(case list_order keep_going stale_settings stale_scene missing_scene set_override
        set_errors stdin_scene output_refused task_vars progress_json log_threads)
  add_test(NAME cli_farm_${case}
           COMMAND bash ${BAKER_TEST_DIR}/bake_farm.sh $<TARGET_FILE:baker>
                   ${CMAKE_BINARY_DIR}/cli_farm ${CMAKE_SOURCE_DIR}/scenes ${case})
endforeach()
