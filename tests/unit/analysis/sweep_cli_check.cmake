# `pmlsm sweep`'s command-line contract: a sweep whose runs all pass exits 0 with its CSV and
# heat map; one with a run that fails its verdict exits 6 and says so; a bad sweep file exits 2
# naming the file, the key, the value and its line, and writes nothing; an output folder that
# cannot be made exits 2 before any run.
# Run as: cmake -DPROGRAM=<pmlsm> -DSOURCE_DIR=<repo> -DWORK_DIR=<scratch> -P this_file
cmake_minimum_required(VERSION 3.22)
foreach(var PROGRAM SOURCE_DIR WORK_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "sweep_cli_check: -D${var}=... is required")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")

# A sweep file over the load mass only, its centre and corners as given.
function(write_sweep path min max grid)
  file(WRITE "${path}" "plants:
  grid_points: {value: ${grid}, source: \"chosen: test\"}
  centre: {value: true, source: \"chosen: test\"}
  random: {value: 0, source: \"chosen: test\"}
  seed: {value: 1, source: \"chosen: test\"}
  parameters:
    - {key: plant.mechanics.load_mass_kg, min: ${min}, max: ${max}, source: \"chosen: test\"}
    - {key: plant.mechanics.spring_n_per_m, min: 13000.0, max: 14400.0, source: \"chosen: test\"}
compensators: [accel]
rnn_weights: ${SOURCE_DIR}/configs/rnn_weights.yaml
scenarios: [${SOURCE_DIR}/configs/scenarios/pulse.yaml]
verdict:
  tail_s: {value: 0.4, source: \"chosen: test\"}
  tail_windows: {value: 2, source: \"chosen: test\"}
  limit_cycle_amplitude_m: {value: 5.0e-4, source: \"chosen: test\"}
  min_decay_rate_per_s: {value: 0.3, source: \"chosen: test\"}
  max_saturated_tail_share: {value: 0.05, source: \"chosen: test\"}
  max_free_vibration_settling_s: {value: 1.0, source: \"chosen: test\"}
  rest_command_band_mps: {value: 1.0e-6, source: \"chosen: test\"}
  min_rest_s: {value: 1.0, source: \"chosen: test\"}
  max_rest_stretch_peak_m: {value: 1.0e-3, source: \"chosen: test\"}
  max_rest_compensation_rms_n: {value: 1000.0, source: \"chosen: test\"}
  max_forced_ratio_to_pi: {value: 1.5, source: \"chosen: test\"}
")
endfunction()

function(run_sweep file out expected_rc)
  execute_process(COMMAND "${PROGRAM}" sweep "${file}" -c "${SOURCE_DIR}/configs/system.yaml" -o "${out}" -j 2
                  RESULT_VARIABLE rc OUTPUT_VARIABLE stdout ERROR_VARIABLE stderr TIMEOUT 300)
  if(NOT rc STREQUAL "${expected_rc}")
    message(FATAL_ERROR "${file}: expected exit ${expected_rc}, got '${rc}'\nstdout:\n${stdout}\nstderr:\n${stderr}")
  endif()
  set(stdout "${stdout}" PARENT_SCOPE)
  set(stderr "${stderr}" PARENT_SCOPE)
endfunction()

# Near the nominal plant (3.8-4.2 kg): acceleration feedback beats PI alone everywhere: exit 0.
write_sweep("${WORK_DIR}/near.yaml" 3.8 4.2 2)
run_sweep("${WORK_DIR}/near.yaml" "${WORK_DIR}/near" 0)
if(NOT stdout MATCHES "every run passed")
  message(FATAL_ERROR "near: no 'every run passed' in\n${stdout}")
endif()
file(STRINGS "${WORK_DIR}/near/sweep.csv" rows)
list(LENGTH rows count)
# Header + (4 corners + centre) x (PI alone, accel) x 1 scenario.
if(NOT count EQUAL 11)
  message(FATAL_ERROR "near: sweep.csv has ${count} lines, expected 11")
endif()
if(NOT EXISTS "${WORK_DIR}/near/pulse_heatmap.png")
  message(FATAL_ERROR "near: no heat map pulse_heatmap.png")
endif()

# The light load with a stiff spring (2 kg at 27,400 N/m) is outside what the nominal estimator
# knows: acceleration feedback loses to PI alone there: exit 6, and the table names the plant.
write_sweep("${WORK_DIR}/stiff.yaml" 2.0 2.2 0)
file(READ "${WORK_DIR}/stiff.yaml" text)
string(REPLACE "min: 13000.0, max: 14400.0" "min: 27000.0, max: 27400.0" text "${text}")
file(WRITE "${WORK_DIR}/stiff.yaml" "${text}")
run_sweep("${WORK_DIR}/stiff.yaml" "${WORK_DIR}/stiff" 6)
if(NOT stdout MATCHES "1 runs failed their verdict")
  message(FATAL_ERROR "stiff: expected '1 runs failed their verdict' in\n${stdout}")
endif()

# Inverted bounds: exit 2 naming file, key, values and line; nothing written.
write_sweep("${WORK_DIR}/inverted.yaml" 8.0 2.0 2)
run_sweep("${WORK_DIR}/inverted.yaml" "${WORK_DIR}/inverted" 2)
foreach(needle "inverted.yaml" "plants.parameters[0]" "min (8) must be below max (2)" "(line 7)")
  string(FIND "${stderr}" "${needle}" pos)
  if(pos EQUAL -1)
    message(FATAL_ERROR "inverted: stderr does not name '${needle}':\n${stderr}")
  endif()
endforeach()
if(EXISTS "${WORK_DIR}/inverted")
  message(FATAL_ERROR "inverted: a rejected sweep file still wrote ${WORK_DIR}/inverted")
endif()

# An output folder that cannot be made (under a file): exit 2 before any run.
run_sweep("${WORK_DIR}/near.yaml" "${WORK_DIR}/near.yaml/out" 2)
string(FIND "${stderr}" "cannot be made" pos)
if(pos EQUAL -1)
  message(FATAL_ERROR "unwritable: stderr does not say the folder cannot be made:\n${stderr}")
endif()
string(FIND "${stderr}" " runs (" pos)
if(NOT pos EQUAL -1)
  message(FATAL_ERROR "unwritable: the sweep ran before the folder was checked:\n${stderr}")
endif()
