# What other tools read (issue 13): NanoVDB output and validation, and the
# Blender add-on rendered with Cycles against `baker view`.
find_program(NANOVDB_VALIDATE_PROGRAM nanovdb_validate)
find_program(NANOVDB_CONVERT_PROGRAM nanovdb_convert)
if(NANOVDB_VALIDATE_PROGRAM AND NANOVDB_CONVERT_PROGRAM)
  add_test(NAME interop_nanovdb
           COMMAND bash ${BAKER_TEST_DIR}/nanovdb_check.sh $<TARGET_FILE:baker>
                   $<TARGET_FILE:bench_tool> ${CMAKE_BINARY_DIR}/interop_nanovdb
                   ${CMAKE_SOURCE_DIR}/scenes)
else()
  message(STATUS "nanovdb_validate/nanovdb_convert not found (libnanovdb-tools): "
                 "test interop_nanovdb skipped")
endif()
