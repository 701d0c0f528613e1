# Runs tests/node/read_mcap.mjs on a recording of mcap_write_cdr_sample and compares decoded values
# with what the sample program put in (see its motor_feedback(), node_status(), ...). The values
# are binary fractions and integers, so JavaScript prints them exactly as written here.
#
#   cmake -DNODE=node -DCHECKER=read_mcap.mjs -DFILE=sample.mcap -P check_node_decode.cmake

foreach(variable NODE CHECKER FILE)
  if(NOT DEFINED ${variable})
    message(FATAL_ERROR "check_node_decode: -D${variable}=... is required")
  endif()
endforeach()

execute_process(
  COMMAND ${NODE} ${CHECKER} ${FILE}
          --expect-topic /pmlsm/motor_feedback --expect-topic /pmlsm/force_command
          --expect-topic /pmlsm/node_status --expect-topic /pmlsm/network_weights
          --expect-topic /pmlsm/training/setup
          --expect-topic /pmlsm/drive_state --expect-topic /pmlsm/drive_control
          --min-messages 200
          --print-first /pmlsm/motor_feedback --print-first /pmlsm/force_command
          --print-first /pmlsm/node_status --print-first /pmlsm/network_weights
          --print-first /pmlsm/training/setup
          --print-first /pmlsm/drive_state --print-first /pmlsm/drive_control
  RESULT_VARIABLE result
  OUTPUT_VARIABLE output
  ERROR_VARIABLE errors)
message(STATUS "read_mcap.mjs: ${output}${errors}")
if(NOT result EQUAL 0)
  message(FATAL_ERROR "read_mcap.mjs failed (exit ${result})")
endif()

# 50 ticks: the two control topics every tick, the other 22 every 10th tick.
string(JSON message_count GET "${output}" messages)
string(JSON topic_count LENGTH "${output}" topics)
string(JSON motor_feedback_count GET "${output}" topics /pmlsm/motor_feedback)
set(failures "")
macro(expect actual expected what)
  if(NOT "${actual}" STREQUAL "${expected}")
    string(APPEND failures "\n  ${what}: got '${actual}', expected '${expected}'")
  endif()
endmacro()
expect("${message_count}" 210 "message count")
expect("${topic_count}" 24 "topics with messages")
expect("${motor_feedback_count}" 50 "/pmlsm/motor_feedback messages")

# Each check: topic, JSON path below the decoded message, expected text.
set(checks
  "/pmlsm/motor_feedback|stamp tick|0"
  "/pmlsm/motor_feedback|stamp sim_time_ns|0"
  "/pmlsm/motor_feedback|stamp source_time_ns|1700000000000000000"
  "/pmlsm/motor_feedback|stamp run_id|18364758544493064720"
  "/pmlsm/motor_feedback|position_m|0.125"
  "/pmlsm/motor_feedback|velocity_mps|-1.5"
  "/pmlsm/motor_feedback|i_q_a|2.5"
  "/pmlsm/motor_feedback|applied_force_n|29.5"
  "/pmlsm/motor_feedback|status|192"
  "/pmlsm/motor_feedback|power_state|6"
  "/pmlsm/motor_feedback|error_code|34321"
  "/pmlsm/motor_feedback|load_sensor|2"
  "/pmlsm/motor_feedback|load_acceleration_mps2|-3.25"
  "/pmlsm/force_command|force_n|12.5"
  "/pmlsm/force_command|pi_force_n|10.25"
  "/pmlsm/force_command|velocity_error_mps|-0.5"
  "/pmlsm/force_command|saturated|OFF"
  "/pmlsm/force_command|stamp run_id|18364758544493064720"
  "/pmlsm/node_status|node_name|plant_sim"
  "/pmlsm/node_status|host_name|host-a"
  "/pmlsm/node_status|pid|4242"
  "/pmlsm/node_status|state|2"
  "/pmlsm/node_status|max_loop_time_us|12.75"
  "/pmlsm/node_status|message|running"
  "/pmlsm/network_weights|version|7"
  "/pmlsm/network_weights|layer_sizes 1|6"
  "/pmlsm/network_weights|layer_sizes 4|1"
  "/pmlsm/network_weights|weights 1|-0.25"
  "/pmlsm/network_weights|gain_n|40"
  "/pmlsm/network_weights|source|test"
  "/pmlsm/training/setup|run_id|99"
  "/pmlsm/training/setup|system_overrides 0|controller.kp=1"
  "/pmlsm/training/setup|scenarios 1 origin|step.yaml"
  "/pmlsm/training/setup|scenarios 1 weight|2"
  "/pmlsm/training/setup|cost_velocity|truth"
  "/pmlsm/drive_state|stamp tick|0"
  "/pmlsm/drive_state|stamp run_id|18364758544493064720"
  "/pmlsm/drive_state|drive_name|plant_sim"
  "/pmlsm/drive_state|power_state|7"
  "/pmlsm/drive_state|statusword|536"
  "/pmlsm/drive_state|error_code|34321"
  "/pmlsm/drive_state|fault_reason|following error 0.5 mm"
  "/pmlsm/drive_state|request_id|41"
  "/pmlsm/drive_state|request_accepted|ON"
  "/pmlsm/drive_state|request_message|enable operation: done"
  "/pmlsm/drive_state|refused_requests|3"
  "/pmlsm/drive_state|faults|2"
  "/pmlsm/drive_state|safe_ticks|1500"
  "/pmlsm/drive_state|watchdog_armed|OFF"
  "/pmlsm/drive_control|stamp tick|0"
  "/pmlsm/drive_control|stamp run_id|18364758544493064720"
  "/pmlsm/drive_control|drive_name|*"
  "/pmlsm/drive_control|command|6"
  "/pmlsm/drive_control|request_id|42"
  "/pmlsm/drive_control|requester|operator@host-b"
)
foreach(check IN LISTS checks)
  string(REPLACE "|" ";" parts "${check}")
  list(GET parts 0 topic)
  list(GET parts 1 path)
  list(GET parts 2 expected)
  string(REPLACE " " ";" path "${path}")
  string(JSON actual ERROR_VARIABLE json_error GET "${output}" first ${topic} ${path})
  if(json_error)
    string(APPEND failures "\n  ${topic} ${path}: ${json_error}")
  else()
    expect("${actual}" "${expected}" "${topic} ${path}")
  endif()
endforeach()
string(JSON layer_count LENGTH "${output}" first /pmlsm/network_weights layer_sizes)
expect("${layer_count}" 5 "/pmlsm/network_weights layer_sizes length")

if(failures)
  message(FATAL_ERROR "decoded values differ from what was written:${failures}")
endif()
message(STATUS "check_node_decode: ${message_count} messages on ${topic_count} topics decoded; values match")
