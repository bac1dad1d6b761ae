# Fuzz targets (issue 17 item 7, tests/fuzz/, docs/reliability.md). When
# clang's libFuzzer links a test program, the targets are built with clang,
# ASan and UBSan as a project of their own (tests/fuzz/CMakeLists.txt) into
# build/fuzz, and each gets a short run from its seed corpus (fuzz_short_*,
# skipped with a message otherwise). Saved crash inputs (tests/data/fuzz/)
# are replayed by fuzz_replay_* through the same code built normally, so
# they run everywhere. scripts/fuzz runs one target for longer.
option(BAKER_FUZZ "build the fuzz targets when clang's libFuzzer works" ON)
set(BAKER_FUZZ_TARGETS fuzz_scene fuzz_mesh_obj fuzz_mesh_ply_ascii fuzz_mesh_ply_binary
    fuzz_mesh_stl_ascii fuzz_mesh_stl_binary fuzz_mesh_off fuzz_vdb)
set(BAKER_FUZZ_SECONDS 12 CACHE STRING "seconds of each fuzz_short_* test")
set(BAKER_FUZZ_BIN ${CMAKE_BINARY_DIR}/fuzz)

function(baker_fuzz_usable out)
  find_program(BAKER_FUZZ_CC NAMES clang-14 clang)
  find_program(BAKER_FUZZ_CXX NAMES clang++-14 clang++)
  set(${out} OFF PARENT_SCOPE)
  if(NOT BAKER_FUZZ_CC OR NOT BAKER_FUZZ_CXX)
    return()
  endif()
  set(dir ${CMAKE_BINARY_DIR}/fuzz-check)
  file(WRITE ${dir}/t.c
       "#include <stddef.h>\nint LLVMFuzzerTestOneInput(const unsigned char *d, size_t n) { return 0; }\n")
  execute_process(COMMAND ${BAKER_FUZZ_CC} -fsanitize=fuzzer,address,undefined ${dir}/t.c -o ${dir}/t
                  RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
  if(rc EQUAL 0)
    set(${out} ON PARENT_SCOPE)
  endif()
endfunction()

if(BAKER_FUZZ)
  baker_fuzz_usable(BAKER_FUZZ_OK)
  if(BAKER_FUZZ_OK)
    include(ExternalProject)
    ExternalProject_Add(fuzz_targets
      SOURCE_DIR ${BAKER_TEST_DIR}/fuzz BINARY_DIR ${BAKER_FUZZ_BIN}
      CMAKE_ARGS -DCMAKE_C_COMPILER=${BAKER_FUZZ_CC} -DCMAKE_CXX_COMPILER=${BAKER_FUZZ_CXX}
                 -DCMAKE_BUILD_TYPE=None
      BUILD_ALWAYS 1 INSTALL_COMMAND "")
  else()
    message(STATUS "clang's libFuzzer does not work here: fuzz_short_* tests will be skipped")
  endif()
endif()

foreach(t ${BAKER_FUZZ_TARGETS})
  add_test(NAME fuzz_short_${t}
           COMMAND bash ${BAKER_TEST_DIR}/fuzz/ctest_fuzz.sh short ${BAKER_FUZZ_BIN} ${t}
                   ${BAKER_TEST_DIR} ${CMAKE_BINARY_DIR}/fuzz-runs ${BAKER_FUZZ_SECONDS})
  set_tests_properties(fuzz_short_${t} PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 120)
endforeach()

# Replays: the target's own source with replay_main.c instead of libFuzzer.
function(baker_fuzz_replay t src)
  add_executable(replay_${t} ${BAKER_TEST_DIR}/fuzz/${src} ${BAKER_TEST_DIR}/fuzz/fuzz_util.c
                 ${BAKER_TEST_DIR}/fuzz/replay_main.c)
  target_compile_definitions(replay_${t} PRIVATE ${ARGN})
  target_link_libraries(replay_${t} PRIVATE bakercore)
  add_test(NAME fuzz_replay_${t}
           COMMAND bash ${BAKER_TEST_DIR}/fuzz/ctest_fuzz.sh replay $<TARGET_FILE:replay_${t}> ${t}
                   ${BAKER_TEST_DIR})
  set_tests_properties(fuzz_replay_${t} PROPERTIES TIMEOUT 120)
endfunction()
baker_fuzz_replay(fuzz_scene fuzz_scene.c)
foreach(kind obj:obj ply_ascii:ply ply_binary:ply stl_ascii:stl stl_binary:stl off:off)
  string(REPLACE ":" ";" kv ${kind})
  list(GET kv 0 tname)
  list(GET kv 1 ext)
  baker_fuzz_replay(fuzz_mesh_${tname} fuzz_mesh.c FUZZ_MESH_EXT=".${ext}")
endforeach()
baker_fuzz_replay(fuzz_vdb fuzz_vdb.c)
