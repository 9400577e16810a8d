# totalgrad_core_library(NAME SOURCES... DEPS ...)
# One static library per core/ concept, aliased totalgrad::core_<name>.
# Sources are the folder's *.cc files (core/<name>/*.cc).
function(totalgrad_core_library name)
  cmake_parse_arguments(ARG "" "" "DEPS" ${ARGN})
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/${name}/*.cc)
  if(sources)
    add_library(totalgrad_core_${name} STATIC ${sources})
    # The numerical kernels compile one file at a time, as they always have:
    # their cost is code generation, not headers, and a trial's bits then
    # never depend on which files a unity batch put together.
    set_target_properties(totalgrad_core_${name} PROPERTIES UNITY_BUILD OFF)
    target_include_directories(totalgrad_core_${name} PUBLIC ${PROJECT_SOURCE_DIR})
    target_link_libraries(totalgrad_core_${name} PUBLIC ${ARG_DEPS})
    # Eigen and abseil parsed once for all of core/ (core/common/
    # precompiled_headers.h): every core library has core_common's flags and
    # definitions, so they reuse its precompiled header.
    if(TOTALGRAD_PRECOMPILED_HEADERS)
      if(name STREQUAL "common")
        target_precompile_headers(totalgrad_core_common PRIVATE
                                  ${PROJECT_SOURCE_DIR}/core/common/precompiled_headers.h)
      else()
        target_precompile_headers(totalgrad_core_${name} REUSE_FROM totalgrad_core_common)
      endif()
    endif()
  else()
    add_library(totalgrad_core_${name} INTERFACE)
    target_include_directories(totalgrad_core_${name} INTERFACE ${PROJECT_SOURCE_DIR})
    target_link_libraries(totalgrad_core_${name} INTERFACE ${ARG_DEPS})
  endif()
  add_library(totalgrad::core_${name} ALIAS totalgrad_core_${name})
endfunction()

# totalgrad_reuse_core_precompiled_headers(TARGET...)
# A library or program above core/ that links core_common (so it compiles
# with core's definitions, EIGEN_USE_BLAS among them) parses Eigen and
# abseil from core's precompiled header too. GCC checks that a file's
# settings match the header's and otherwise parses the headers itself
# (-Winvalid-pch says so): programs (-fpie) and targets compiled with
# -pthread (gRPC's, Threads') cannot use it, so they are not listed.
function(totalgrad_reuse_core_precompiled_headers)
  if(TOTALGRAD_PRECOMPILED_HEADERS)
    foreach(target IN LISTS ARGN)
      target_precompile_headers(${target} REUSE_FROM totalgrad_core_common)
    endforeach()
  endif()
endfunction()

# totalgrad_test_folder(tests/<folder> LIBS ... LABELS ...)
# One GoogleTest executable per test folder (tests/core/pilco ->
# core_pilco_tests) holding every *_test.cc in it, registered with CTest test
# by test. The folder's files compile as unity batches: a test file's cost is
# mostly the headers it parses and the Eigen and GoogleTest templates it
# instantiates, which a batch does once (core/pilco: 80 CPU s as one batch,
# 132 as five files). Each file keeps its helpers in a namespace named after
# the file (not an anonymous one), so files can share a batch.
function(totalgrad_test_folder folder)
  cmake_parse_arguments(ARG "" "" "LIBS;LABELS" ${ARGN})
  file(GLOB sources CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/${folder}/*_test.cc)
  string(REPLACE "/" "_" prefix "${folder}")
  set(target "${prefix}_tests")
  add_executable(${target} ${sources})
  set_target_properties(${target} PROPERTIES UNITY_BUILD ON)
  target_link_libraries(${target} PRIVATE ${ARG_LIBS} totalgrad_testutil totalgrad_test_main GTest::gmock)
  # Where committed test data lives (tests/*/testdata).
  target_compile_definitions(${target} PRIVATE TOTALGRAD_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  gtest_discover_tests(${target} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS "${ARG_LABELS}")
endfunction()
