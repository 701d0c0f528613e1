# Bad configs through the programs' command lines: closed_loop and plant_sim must exit with
# exactly 2 (bad config) and name the key and value on stderr, for the issue's cases: a
# spring of 1e308, a subnormal load mass, a fractional pole-pair count, a duplicate key,
# an anchor bomb, an empty and a binary file.
# Run as: cmake -DPROGRAMS="<closed_loop>;<plant_sim>" -DSOURCE_DIR=<repo> -DWORK_DIR=<scratch> -P this_file
cmake_minimum_required(VERSION 3.22)

foreach(var PROGRAMS SOURCE_DIR WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "config_cli_check: -D${var}=... is required")
  endif()
endforeach()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(scenario "${SOURCE_DIR}/configs/scenarios/pulse.yaml")
file(READ "${SOURCE_DIR}/configs/system.yaml" good)

# Writes NAME.yaml with the value of KEY (the last part of its path) replaced.
function(write_with_value name key value)
  string(REGEX REPLACE "${key}: {value: [^,}]+" "${key}: {value: ${value}" text "${good}")
  if(text STREQUAL good)
    message(FATAL_ERROR "could not find ${key}'s value in configs/system.yaml")
  endif()
  file(WRITE "${WORK_DIR}/${name}.yaml" "${text}")
endfunction()

write_with_value(spring spring_n_per_m 1e308)
write_with_value(subnormal load_mass_kg 1e-320)
write_with_value(pole_pairs pole_pairs 1.5)
string(REGEX MATCH "\n    motor_mass_kg: [^\n]*" line "${good}")
string(REPLACE "${line}" "${line}${line}" text "${good}")
file(WRITE "${WORK_DIR}/duplicate.yaml" "${text}")
file(WRITE "${WORK_DIR}/bomb.yaml" "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\nc: [*b, *b, *b, *b, *b, *b, *b, *b, *b]\n")
file(WRITE "${WORK_DIR}/empty.yaml" "")
string(RANDOM LENGTH 2048 RANDOM_SEED 15 ALPHABET "!#$%&()*+-./0123456789;<=>?@ABCDEFGHIJKLMNOPQRSTUVWXYZ^_`abcdefghijklmnopqrstuvwxyz|~" noise)
file(WRITE "${WORK_DIR}/binary.yaml" "${noise}")

set(cases
  "spring|plant.mechanics.spring_n_per_m|1e+308"
  "subnormal|plant.mechanics.load_mass_kg|subnormal"
  "pole_pairs|plant.electrical.pole_pairs|1.5"
  "duplicate|plant.mechanics.motor_mass_kg: duplicate key|line"
  "bomb|anchors and aliases|line"
  "empty|top level must be a mapping|empty.yaml"
  "binary|binary.yaml|binary.yaml")
foreach(program IN LISTS PROGRAMS)
  get_filename_component(program_name "${program}" NAME)
  set(extra "")
  if(program_name STREQUAL "closed_loop")
    set(extra -o "${WORK_DIR}/out")
  endif()
  foreach(case IN LISTS cases)
    string(REPLACE "|" ";" parts "${case}")
    list(GET parts 0 name)
    list(GET parts 1 key)
    list(GET parts 2 value)
    execute_process(COMMAND "${program}" -c "${WORK_DIR}/${name}.yaml" -s "${scenario}" ${extra}
                    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 60)
    if(NOT rc STREQUAL "2")
      message(FATAL_ERROR "${program_name} ${name}: expected exit code 2, got '${rc}'\nstdout:\n${out}\nstderr:\n${err}")
    endif()
    foreach(needle "${key}" "${value}")
      string(FIND "${err}" "${needle}" pos)
      if(pos EQUAL -1)
        message(FATAL_ERROR "${program_name} ${name}: stderr does not name '${needle}'\nstderr:\n${err}")
      endif()
    endforeach()
  endforeach()
endforeach()
message(STATUS "bad configs exit 2 naming key and value")
