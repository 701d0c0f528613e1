# `pmlsm config write`: a copy of the system file with the values set (each source naming why),
# loaded back with every check; a bad key or value exits 2 naming it and writes nothing.
# Run as: cmake -DPROGRAM=<pmlsm> -DWORK_DIR=<scratch> -P this_file
cmake_minimum_required(VERSION 3.22)

foreach(var PROGRAM WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "config_write_check: -D${var}=... is required")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(nudged "${WORK_DIR}/nudged.yaml")

execute_process(COMMAND "${PROGRAM}" config write --set plant.mechanics.load_mass_kg=4.000004
                        --reason "the load's mass nudged by 1 ppm" -o "${nudged}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 60)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "config write: exit '${rc}'\nstdout:\n${out}\nstderr:\n${err}")
endif()
file(READ "${nudged}" text)
string(FIND "${text}" "load_mass_kg: {value: 4.000004, source: \"chosen: the load's mass nudged by 1 ppm\"}" at)
if(at EQUAL -1)
  message(FATAL_ERROR "config write: the value and its reason are not in ${nudged}:\n${text}")
endif()
# The copy is a system file every program loads; the model's own load mass is untouched.
string(FIND "${text}" "load_mass_kg: {value: 4.0, source: \"paper Table 2: m_L (the nominal plant" model_at)
if(model_at EQUAL -1)
  message(FATAL_ERROR "config write: kalman.model.load_mass_kg changed too:\n${text}")
endif()
execute_process(COMMAND "${PROGRAM}" config check -c "${nudged}"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 60)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "config check of the copy: exit '${rc}'\nstdout:\n${out}\nstderr:\n${err}")
endif()

set(refused "${WORK_DIR}/refused.yaml")
foreach(bad "plant.mechanics.load_mas=4" "plant.mechanics.load_mass_kg=-1")
  execute_process(COMMAND "${PROGRAM}" config write --set "${bad}" -o "${refused}"
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 60)
  string(REGEX MATCH "^[^=]+" key "${bad}")
  string(FIND "${err}" "${key}" named)
  if(NOT rc EQUAL 2 OR named EQUAL -1)
    message(FATAL_ERROR "config write --set ${bad}: expected exit 2 naming ${key}, got '${rc}'\nstderr:\n${err}")
  endif()
  if(EXISTS "${refused}")
    message(FATAL_ERROR "config write --set ${bad}: wrote ${refused} anyway")
  endif()
endforeach()
message(STATUS "config write: the copy carries the value and its reason, loads back, and bad input writes nothing")
