# Every test carries its kind as a ctest label, so a run can take its share
# (`ctest -L unit`, `./scripts/test.sh --quick`):
#   unit         a library in-process, or a program's command line; no DDS domain: seconds
#   integration  programs as real processes on DDS or the CAN bus (nodes, launcher, agents, tools)
#   interop      a third party reads us or talks to us (python-can, @mcap/core, Cyclone DDS)
#   fuzz         the fuzz targets over their corpora and regression inputs

# The tests of a GoogleTest executable, discovered, labelled KIND; TIMEOUT seconds each (ctest's
# default when absent), PREFIX before their names.
function(pmlsm_add_gtests target kind)
  cmake_parse_arguments(PARSE_ARGV 2 arg "" "TIMEOUT;PREFIX" "")
  set(prefix)
  if(arg_PREFIX)
    set(prefix TEST_PREFIX ${arg_PREFIX})
  endif()
  set(properties LABELS ${kind})
  if(arg_TIMEOUT)
    list(APPEND properties TIMEOUT ${arg_TIMEOUT})
  endif()
  gtest_discover_tests(${target} ${prefix} DISCOVERY_TIMEOUT 60 PROPERTIES ${properties})
endfunction()

# Labels tests made with add_test (their other properties untouched).
function(pmlsm_label_tests kind)
  set_property(TEST ${ARGN} APPEND PROPERTY LABELS ${kind})
endfunction()
