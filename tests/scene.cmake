# Scene loading and the JSON parser (owner: scene). Each case writes its own
# files, named after the case, into build/test_scene_files.
add_executable(test_scene ${BAKER_TEST_DIR}/test_scene.c)
target_link_libraries(test_scene PRIVATE bakercore)
foreach(case full defaults missing_comma trailing_comma unterminated_string garbage_after
        duplicate_key deep_nesting json_strings missing_resolution resolution_type
        resolution_negative bounds spot_angle unknown_key huge_number keyframes)
  add_test(NAME scene_${case}
           COMMAND test_scene ${case} ${CMAKE_BINARY_DIR}/test_scene_files)
endforeach()
