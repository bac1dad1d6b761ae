# The relocatable bundle (scripts/bundle): runs with the build tree out of
# reach and loads nothing from outside it but the base system (issue 14).
add_test(NAME bundle
         COMMAND bash ${BAKER_TEST_DIR}/bundle_check.sh ${CMAKE_SOURCE_DIR} ${CMAKE_BINARY_DIR}
                 ${CMAKE_BINARY_DIR}/bundle_check)
set_tests_properties(bundle PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 120 DEPENDS baker)
