# The closed_loop program's command-line contract: a bad config or override
# exits non-zero naming the key path (and value), a good one writes the trace.
# Run as: cmake -DPROGRAM=<closed_loop> -DSOURCE_DIR=<repo> -DWORK_DIR=<scratch> -P this_file
cmake_minimum_required(VERSION 3.22)

foreach(var PROGRAM SOURCE_DIR WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "closed_loop_cli_check: -D${var}=... is required")
  endif()
endforeach()

set(good_config "${SOURCE_DIR}/configs/system.yaml")
set(bad_config "${WORK_DIR}/system_bad_load_mass.yaml")
set(scenario "${SOURCE_DIR}/configs/scenarios/pulse.yaml")
set(out_dir "${WORK_DIR}/out")
set(trace "${out_dir}/pulse.csv")

# Start clean, so a trace left by an earlier run cannot satisfy the last check.
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")

# Runs PROGRAM with ARGS; requires a clean non-zero exit (not a crash) whose
# stderr contains every MENTIONS string, and that no trace was written.
function(expect_rejected what)
  cmake_parse_arguments(PARSE_ARGV 1 arg "" "" "MENTIONS;ARGS")
  execute_process(COMMAND "${PROGRAM}" ${arg_ARGS}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 120)
  if(NOT rc MATCHES "^[0-9]+$" OR rc EQUAL 0)
    message(FATAL_ERROR "${what}: expected a non-zero exit code, got '${rc}'\nstdout:\n${out}\nstderr:\n${err}")
  endif()
  foreach(needle IN LISTS arg_MENTIONS)
    string(FIND "${err}" "${needle}" pos)
    if(pos EQUAL -1)
      message(FATAL_ERROR "${what}: stderr does not name '${needle}'\nstderr:\n${err}")
    endif()
  endforeach()
  if(EXISTS "${trace}")
    message(FATAL_ERROR "${what}: a rejected config still wrote ${trace}")
  endif()
endfunction()

# 1. A negative load mass in the file.
file(READ "${good_config}" text)
string(REGEX REPLACE "load_mass_kg: {value: [^,}]+" "load_mass_kg: {value: -4" bad_text "${text}")
if(bad_text STREQUAL text)
  message(FATAL_ERROR "could not find load_mass_kg's value in ${good_config} to corrupt")
endif()
file(WRITE "${bad_config}" "${bad_text}")
expect_rejected("negative load mass in the file"
  MENTIONS "${bad_config}" "plant.mechanics.load_mass_kg" "-4"
  ARGS -c "${bad_config}" -s "${scenario}" -o "${out_dir}")

# 2. An override of a key the file does not have.
expect_rejected("override of an unknown key"
  MENTIONS "plant.mechanics.nonexistent_key"
  ARGS -c "${good_config}" -s "${scenario}" -o "${out_dir}"
       --set plant.mechanics.nonexistent_key=1)

# 3. The shipped config runs and writes the trace.
execute_process(COMMAND "${PROGRAM}" -c "${good_config}" -s "${scenario}" -o "${out_dir}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 600)
if(NOT rc STREQUAL "0")
  message(FATAL_ERROR "good config: expected exit code 0, got '${rc}'\nstdout:\n${out}\nstderr:\n${err}")
endif()
if(NOT EXISTS "${trace}")
  message(FATAL_ERROR "good config: ${trace} was not written\nstdout:\n${out}")
endif()
file(SIZE "${trace}" trace_size)
if(trace_size EQUAL 0)
  message(FATAL_ERROR "good config: ${trace} is empty")
endif()
message(STATUS "closed_loop CLI contract holds")
