# moreau_add_test(NAME name SOURCES a.cc b.cc LIBS lib...)
# One GoogleTest executable, registered test by test with CTest. The working directory is the source
# tree, so tests can read scenes/ by relative path.
function(moreau_add_test)
  cmake_parse_arguments(T "" "NAME" "SOURCES;LIBS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES})
  target_link_libraries(${T_NAME} PRIVATE ${T_LIBS} GTest::gtest_main GTest::gmock)
  target_compile_definitions(${T_NAME} PRIVATE MOREAU_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  gtest_discover_tests(${T_NAME} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} DISCOVERY_TIMEOUT 60)
endfunction()

# moreau_add_bench(NAME name SOURCES a.cc LIBS lib...)
function(moreau_add_bench)
  cmake_parse_arguments(B "" "NAME" "SOURCES;LIBS" ${ARGN})
  add_executable(${B_NAME} ${B_SOURCES})
  target_link_libraries(${B_NAME} PRIVATE ${B_LIBS} benchmark::benchmark)
  target_compile_definitions(${B_NAME} PRIVATE MOREAU_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
endfunction()
