# moreau_add_test(NAME name SOURCES a.cc b.cc LIBS lib...)
# One GoogleTest executable, registered test by test with CTest. The working directory is the source
# tree, so tests can read scenes/ by relative path.
function(moreau_add_test)
  cmake_parse_arguments(T "" "NAME" "SOURCES;LIBS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES})
  target_link_libraries(${T_NAME} PRIVATE ${T_LIBS} GTest::gtest_main GTest::gmock)
  target_compile_definitions(${T_NAME} PRIVATE MOREAU_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  # tests/support/ (fixtures shared by the parts' tests) is included as "support/...".
  target_include_directories(${T_NAME} PRIVATE ${PROJECT_SOURCE_DIR}/tests)
  gtest_discover_tests(${T_NAME} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} DISCOVERY_TIMEOUT 60)
endfunction()

# moreau_add_bench(NAME name SOURCES a.cc LIBS lib...)
function(moreau_add_bench)
  cmake_parse_arguments(B "" "NAME" "SOURCES;LIBS" ${ARGN})
  add_executable(${B_NAME} ${B_SOURCES})
  target_link_libraries(${B_NAME} PRIVATE ${B_LIBS} benchmark::benchmark)
  target_compile_definitions(${B_NAME} PRIVATE MOREAU_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
endfunction()

# moreau_require_system_python_module(MODULE module PACKAGE debian-package)
# Sets MOREAU_SYSTEM_PYTHON3 to Debian's python3 (looked for in /usr/bin first, so that another python3
# earlier on PATH does not hide the packages), and stops with the package to install if it cannot import
# `module`: the test scripts that need it must run, never skip.
function(moreau_require_system_python_module)
  cmake_parse_arguments(P "" "MODULE;PACKAGE" "" ${ARGN})
  find_program(MOREAU_SYSTEM_PYTHON3 python3 PATHS /usr/bin NO_DEFAULT_PATH)
  find_program(MOREAU_SYSTEM_PYTHON3 python3 REQUIRED)
  execute_process(COMMAND ${MOREAU_SYSTEM_PYTHON3} -c "import ${P_MODULE}" RESULT_VARIABLE missing OUTPUT_QUIET ERROR_QUIET)
  if(missing)
    message(FATAL_ERROR "${MOREAU_SYSTEM_PYTHON3} cannot import ${P_MODULE}: install ${P_PACKAGE} (scripts/install-deps.sh)")
  endif()
endfunction()
