// The generic decoder against the real thing: every catalog type is filled with distinct values,
// serialized by the fastddsgen code (little-endian through XxxPubSubType::serialize, as Fast DDS
// writes it; big-endian through Fast CDR directly), decoded from the catalog's flattened IDL, and
// compared field by field. The Sampler records each value with its path as the filler sets it,
// so a member the filler forgets shows up as an extra decoded field.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastdds/rtps/common/SerializedPayload.h>
#include <fastrtps/utils/fixed_size_string.hpp>

#include "AgentAnnouncePubSubTypes.h"
#include "CompensatorOutputPubSubTypes.h"
#include "CurrentFeedbackPubSubTypes.h"
#include "DriveControlPubSubTypes.h"
#include "DriveStatePubSubTypes.h"
#include "EstimatedStatePubSubTypes.h"
#include "EvaluationRequestPubSubTypes.h"
#include "EvaluationResultPubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "LaunchRequestPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "NetworkWeightsPubSubTypes.h"
#include "NodeExitPubSubTypes.h"
#include "ParameterEventPubSubTypes.h"
#include "ParameterRequestPubSubTypes.h"
#include "NodeOutputPubSubTypes.h"
#include "NodeStatusPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "TrainerProgressPubSubTypes.h"
#include "TrainingSetupPubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "VelocitySetpointPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "WorkerStatusPubSubTypes.h"
#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"

namespace {

namespace msg = pmlsm_msgs::msg;
using eprosima::fastrtps::fixed_string;
using pmlsm::introspect::Decoded;
using pmlsm::introspect::Field;
using pmlsm::introspect::MessageSchema;
using Bytes = std::vector<std::uint8_t>;

/// Hands out distinct values (negative, fractional, high bits set) and records what it gave.
class Sampler {
 public:
  double real(const std::string& path) {
    const int k = next();
    return record(path, (k % 2 == 0 ? 1.0 : -1.0) * (k * 1.0625 + 1.0 / (k + 2)));
  }
  std::uint64_t u64(const std::string& path) {
    return record(path, 0xF000000000000000ULL + 0x0101010101ULL * static_cast<std::uint64_t>(next()));
  }
  std::int64_t i64(const std::string& path) { return record(path, -1'000'000'000'000'000LL - 3 * next()); }
  std::int32_t i32(const std::string& path) {
    return static_cast<std::int32_t>(record(path, std::int64_t{-100000 - 3 * next()}));
  }
  std::uint32_t u32(const std::string& path) {
    return static_cast<std::uint32_t>(record(path, std::uint64_t{0x80000000U + 7U * next()}));
  }
  std::uint16_t u16(const std::string& path) {
    return static_cast<std::uint16_t>(record(path, std::uint64_t{40000U + 3U * next()}));
  }
  std::uint8_t u8(const std::string& path) {
    return static_cast<std::uint8_t>(record(path, std::uint64_t{100U + next() % 100U}));
  }
  bool flag(const std::string& path) { return record(path, next() % 2 == 1); }
  template <std::size_t N>
  fixed_string<N> text(const std::string& path) {
    // Quotes, a newline and a name-specific tail: what YAML quoting and bounds must survive.
    std::string value = "v" + std::to_string(next()) + " it's \"" + path + "\"\nend";
    value.resize(std::min(value.size(), N));
    return fixed_string<N>(record(path, value));
  }
  std::vector<double> reals(const std::string& path, std::size_t count) {
    std::vector<double> values;
    for (std::size_t i = 0; i < count; ++i) values.push_back(real(indexed(path, i)));
    return values;
  }
  template <std::size_t N>
  std::vector<fixed_string<N>> texts(const std::string& path, std::size_t count) {
    std::vector<fixed_string<N>> values;
    for (std::size_t i = 0; i < count; ++i) values.push_back(text<N>(indexed(path, i)));
    return values;
  }
  static std::string indexed(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }
  const std::vector<Field>& expected() const { return expected_; }

 private:
  int next() { return ++count_; }
  template <class T>
  T record(const std::string& path, T value) {
    Field field;
    field.path = path;
    field.value = value;
    expected_.push_back(field);
    return value;
  }
  int count_ = 0;
  std::vector<Field> expected_;
};

msg::Stamp stamp(Sampler& s) {
  msg::Stamp v;
  v.tick(s.u64("stamp.tick"));
  v.sim_time_ns(s.i64("stamp.sim_time_ns"));
  v.source_time_ns(s.i64("stamp.source_time_ns"));
  v.run_id(s.u64("stamp.run_id"));
  return v;
}

msg::MotorFeedback motor_feedback(Sampler& s) {
  msg::MotorFeedback v;
  v.stamp(stamp(s));
  v.position_m(s.real("position_m"));
  v.velocity_mps(s.real("velocity_mps"));
  v.i_d_a(s.real("i_d_a"));
  v.i_q_a(s.real("i_q_a"));
  v.thrust_force_n(s.real("thrust_force_n"));
  v.applied_force_n(s.real("applied_force_n"));
  v.applied_command_tick(s.u64("applied_command_tick"));
  v.status(s.u32("status"));
  v.power_state(s.u8("power_state"));
  v.error_code(s.u16("error_code"));
  v.load_sensor(s.u8("load_sensor"));
  v.load_position_m(s.real("load_position_m"));
  v.load_acceleration_mps2(s.real("load_acceleration_mps2"));
  return v;
}

msg::DriveState drive_state(Sampler& s) {
  msg::DriveState v;
  v.stamp(stamp(s));
  v.drive_name(s.text<64>("drive_name"));
  v.power_state(s.u8("power_state"));
  v.statusword(s.u16("statusword"));
  v.error_code(s.u16("error_code"));
  v.fault_reason(s.text<128>("fault_reason"));
  v.request_id(s.u64("request_id"));
  v.request_accepted(s.flag("request_accepted"));
  v.request_message(s.text<128>("request_message"));
  v.refused_requests(s.u64("refused_requests"));
  v.faults(s.u64("faults"));
  v.safe_ticks(s.u64("safe_ticks"));
  v.watchdog_armed(s.flag("watchdog_armed"));
  return v;
}

msg::DriveControl drive_control(Sampler& s) {
  msg::DriveControl v;
  v.stamp(stamp(s));
  v.drive_name(s.text<64>("drive_name"));
  v.command(s.u8("command"));
  v.request_id(s.u64("request_id"));
  v.requester(s.text<64>("requester"));
  return v;
}

msg::PlantTruth plant_truth(Sampler& s) {
  msg::PlantTruth v;
  v.stamp(stamp(s));
  v.motor_position_m(s.real("motor_position_m"));
  v.motor_velocity_mps(s.real("motor_velocity_mps"));
  v.motor_acceleration_mps2(s.real("motor_acceleration_mps2"));
  v.load_position_m(s.real("load_position_m"));
  v.load_velocity_mps(s.real("load_velocity_mps"));
  v.load_acceleration_mps2(s.real("load_acceleration_mps2"));
  v.spring_force_n(s.real("spring_force_n"));
  v.thrust_force_n(s.real("thrust_force_n"));
  v.ripple_force_n(s.real("ripple_force_n"));
  v.friction_force_n(s.real("friction_force_n"));
  v.command_force_n(s.real("command_force_n"));
  v.psi_d_wb(s.real("psi_d_wb"));
  v.psi_q_wb(s.real("psi_q_wb"));
  v.psi_damper_d_wb(s.real("psi_damper_d_wb"));
  v.psi_damper_q_wb(s.real("psi_damper_q_wb"));
  v.i_d_a(s.real("i_d_a"));
  v.i_q_a(s.real("i_q_a"));
  v.i_damper_d_a(s.real("i_damper_d_a"));
  v.i_damper_q_a(s.real("i_damper_q_a"));
  v.u_d_v(s.real("u_d_v"));
  v.u_q_v(s.real("u_q_v"));
  return v;
}

msg::ForceCommand force_command(Sampler& s) {
  msg::ForceCommand v;
  v.stamp(stamp(s));
  v.feedback_tick(s.u64("feedback_tick"));
  v.force_n(s.real("force_n"));
  v.pi_force_n(s.real("pi_force_n"));
  v.compensation_force_n(s.real("compensation_force_n"));
  v.velocity_error_mps(s.real("velocity_error_mps"));
  v.saturated(s.flag("saturated"));
  v.v_ref_mps(s.real("v_ref_mps"));
  v.x_ref_m(s.real("x_ref_m"));
  return v;
}

msg::CurrentFeedback current_feedback(Sampler& s) {
  msg::CurrentFeedback v;
  v.stamp(stamp(s));
  v.substep(s.u32("substep"));
  v.i_d_a(s.real("i_d_a"));
  v.i_q_a(s.real("i_q_a"));
  v.velocity_mps(s.real("velocity_mps"));
  v.position_m(s.real("position_m"));
  return v;
}

msg::VoltageCommand voltage_command(Sampler& s) {
  msg::VoltageCommand v;
  v.stamp(stamp(s));
  v.substep(s.u32("substep"));
  v.u_d_v(s.real("u_d_v"));
  v.u_q_v(s.real("u_q_v"));
  v.i_d_ref_a(s.real("i_d_ref_a"));
  v.i_q_ref_a(s.real("i_q_ref_a"));
  v.saturated(s.flag("saturated"));
  return v;
}

msg::VelocityReference velocity_reference(Sampler& s) {
  msg::VelocityReference v;
  v.stamp(stamp(s));
  v.velocity_command_mps(s.real("velocity_command_mps"));
  v.v_ref_mps(s.real("v_ref_mps"));
  v.a_ref_mps2(s.real("a_ref_mps2"));
  v.parameters_version(s.u64("parameters_version"));
  return v;
}

msg::VelocitySetpoint velocity_setpoint(Sampler& s) {
  msg::VelocitySetpoint v;
  v.stamp(stamp(s));
  v.velocity_mps(s.real("velocity_mps"));
  v.accel_limit_mps2(s.real("accel_limit_mps2"));
  v.session(s.u64("session"));
  v.sequence_number(s.u64("sequence_number"));
  v.source(s.text<64>("source"));
  return v;
}

msg::EstimatedState estimated_state(Sampler& s) {
  msg::EstimatedState v;
  v.stamp(stamp(s));
  v.feedback_tick(s.u64("feedback_tick"));
  v.v_motor_mps(s.real("v_motor_mps"));
  v.v_load_mps(s.real("v_load_mps"));
  v.spring_force_n(s.real("spring_force_n"));
  v.a_load_mps2(s.real("a_load_mps2"));
  v.input_force_n(s.real("input_force_n"));
  v.innovation_mps(s.real("innovation_mps"));
  const auto diagonal = s.reals("covariance_diag", 3);
  v.covariance_diag({diagonal[0], diagonal[1], diagonal[2]});
  v.load_sensor_use(s.u8("load_sensor_use"));
  v.load_sensor_fault(s.u8("load_sensor_fault"));
  v.accelerometer_bias_mps2(s.real("accelerometer_bias_mps2"));
  return v;
}

msg::CompensatorOutput compensator_output(Sampler& s) {
  msg::CompensatorOutput v;
  v.stamp(stamp(s));
  v.estimate_tick(s.u64("estimate_tick"));
  v.weights_version(s.u64("weights_version"));
  v.force_n(s.real("force_n"));
  v.u_n(s.real("u_n"));
  v.training_error_mps(s.real("training_error_mps"));
  v.k_c_mps(s.real("k_c_mps"));
  v.flags(s.u32("flags"));
  return v;
}

msg::NetworkWeights network_weights(Sampler& s) {
  msg::NetworkWeights v;
  v.stamp(stamp(s));
  v.version(s.u64("version"));
  std::vector<std::uint16_t> layer_sizes;
  for (std::size_t i = 0; i < 5; ++i) layer_sizes.push_back(s.u16(Sampler::indexed("layer_sizes", i)));
  v.layer_sizes(layer_sizes);
  v.weights(s.reals("weights", 37));
  v.input_scale(s.real("input_scale"));
  v.gain_n(s.real("gain_n"));
  v.cost(s.real("cost"));
  v.source(s.text<64>("source"));
  return v;
}

msg::TrainerProgress trainer_progress(Sampler& s) {
  msg::TrainerProgress v;
  v.stamp(stamp(s));
  v.generation(s.u64("generation"));
  v.max_generations(s.u64("max_generations"));
  v.evaluations(s.u64("evaluations"));
  v.best_weights_version(s.u64("best_weights_version"));
  v.best_cost(s.real("best_cost"));
  v.mean_cost(s.real("mean_cost"));
  v.elapsed_s(s.real("elapsed_s"));
  v.eta_s(s.real("eta_s"));
  v.population_size(s.u32("population_size"));
  v.optimiser(s.text<32>("optimiser"));
  return v;
}

msg::NodeStatus node_status(Sampler& s) {
  msg::NodeStatus v;
  v.stamp(stamp(s));
  v.node_name(s.text<64>("node_name"));
  v.host_name(s.text<64>("host_name"));
  v.pid(s.u32("pid"));
  v.state(s.u8("state"));
  v.ticks(s.u64("ticks"));
  v.late(s.u64("late"));
  v.rejected(s.u64("rejected"));
  v.deadline_misses(s.u64("deadline_misses"));
  v.max_loop_time_us(s.real("max_loop_time_us"));
  v.mean_loop_time_us(s.real("mean_loop_time_us"));
  v.message(s.text<128>("message"));
  return v;
}

msg::TrainingSetup training_setup(Sampler& s) {
  msg::TrainingSetup v;
  v.stamp(stamp(s));
  v.run_id(s.u64("run_id"));
  v.system_yaml(s.text<65536>("system_yaml"));
  v.system_origin(s.text<256>("system_origin"));
  v.system_overrides(s.texts<256>("system_overrides", 3));
  std::vector<msg::TrainingScenarioText> scenarios(2);
  for (std::size_t i = 0; i < scenarios.size(); ++i) {
    const std::string path = Sampler::indexed("scenarios", i);
    scenarios[i].yaml(s.text<8192>(path + ".yaml"));
    scenarios[i].origin(s.text<256>(path + ".origin"));
    scenarios[i].weight(s.real(path + ".weight"));
  }
  v.scenarios(scenarios);
  v.cost_velocity(s.text<16>("cost_velocity"));
  std::vector<msg::TrainingPlantText> plants(2);
  for (std::size_t i = 0; i < plants.size(); ++i) {
    const std::string path = Sampler::indexed("plants", i);
    plants[i].name(s.text<64>(path + ".name"));
    plants[i].moves(s.texts<256>(path + ".moves", 2));
    plants[i].weight(s.real(path + ".weight"));
    plants[i].models(s.texts<256>(path + ".models", 2));
  }
  v.plants(plants);
  v.plant_objective(s.text<32>("plant_objective"));
  msg::TrainingVerdict verdict;
  verdict.judge_runs(s.flag("verdict.judge_runs"));
  verdict.tail_s(s.real("verdict.tail_s"));
  verdict.tail_windows(s.u64("verdict.tail_windows"));
  verdict.limit_cycle_amplitude_m(s.real("verdict.limit_cycle_amplitude_m"));
  verdict.min_decay_rate_per_s(s.real("verdict.min_decay_rate_per_s"));
  verdict.max_saturated_tail_share(s.real("verdict.max_saturated_tail_share"));
  verdict.max_free_vibration_settling_s(s.real("verdict.max_free_vibration_settling_s"));
  verdict.rest_command_band_mps(s.real("verdict.rest_command_band_mps"));
  verdict.min_rest_s(s.real("verdict.min_rest_s"));
  verdict.max_rest_stretch_peak_m(s.real("verdict.max_rest_stretch_peak_m"));
  verdict.max_rest_compensation_rms_n(s.real("verdict.max_rest_compensation_rms_n"));
  verdict.max_forced_ratio_to_pi(s.real("verdict.max_forced_ratio_to_pi"));
  v.verdict(verdict);
  return v;
}

msg::EvaluationRequest evaluation_request(Sampler& s) {
  msg::EvaluationRequest v;
  v.stamp(stamp(s));
  v.run_id(s.u64("run_id"));
  v.job_id(s.u64("job_id"));
  v.worker_id(s.text<64>("worker_id"));
  v.candidate(s.reals("candidate", 11));
  return v;
}

msg::EvaluationResult evaluation_result(Sampler& s) {
  msg::EvaluationResult v;
  v.stamp(stamp(s));
  v.run_id(s.u64("run_id"));
  v.job_id(s.u64("job_id"));
  v.worker_id(s.text<64>("worker_id"));
  v.cost(s.real("cost"));
  v.eval_time_s(s.real("eval_time_s"));
  v.status(s.u32("status"));
  return v;
}

msg::WorkerStatus worker_status(Sampler& s) {
  msg::WorkerStatus v;
  v.stamp(stamp(s));
  v.worker_id(s.text<64>("worker_id"));
  v.run_id(s.u64("run_id"));
  v.slots(s.u32("slots"));
  v.queued(s.u32("queued"));
  v.evaluated(s.u64("evaluated"));
  v.setup_error(s.text<128>("setup_error"));
  return v;
}

msg::AgentAnnounce agent_announce(Sampler& s) {
  msg::AgentAnnounce v;
  v.stamp(stamp(s));
  v.host_name(s.text<64>("host_name"));
  v.agent_id(s.text<64>("agent_id"));
  v.pid(s.u32("pid"));
  v.secure(s.flag("secure"));
  v.launch_id(s.u64("launch_id"));
  v.lease_ms(s.u32("lease_ms"));
  v.message(s.text<128>("message"));
  return v;
}

msg::LaunchRequest launch_request(Sampler& s) {
  msg::LaunchRequest v;
  v.stamp(stamp(s));
  v.launch_id(s.u64("launch_id"));
  v.host_name(s.text<64>("host_name"));
  v.command(s.u8("command"));
  v.requester(s.text<64>("requester"));
  v.lease_ms(s.u32("lease_ms"));
  v.start_grace_ms(s.u32("start_grace_ms"));
  v.stop_timeout_ms(s.u32("stop_timeout_ms"));
  v.slice_yaml(s.text<16384>("slice_yaml"));
  return v;
}

msg::NodeOutput node_output(Sampler& s) {
  msg::NodeOutput v;
  v.stamp(stamp(s));
  v.launch_id(s.u64("launch_id"));
  v.host_name(s.text<64>("host_name"));
  v.node_name(s.text<64>("node_name"));
  v.stream(s.u8("stream"));
  v.line_number(s.u64("line_number"));
  v.line(s.text<1024>("line"));
  return v;
}

msg::NodeExit node_exit(Sampler& s) {
  msg::NodeExit v;
  v.stamp(stamp(s));
  v.launch_id(s.u64("launch_id"));
  v.host_name(s.text<64>("host_name"));
  v.event(s.u8("event"));
  v.exit_code(s.i32("exit_code"));
  v.message(s.text<256>("message"));
  return v;
}

msg::ParameterRequest parameter_request(Sampler& s) {
  msg::ParameterRequest v;
  v.stamp(stamp(s));
  v.node(s.text<64>("node"));
  v.operation(s.u8("operation"));
  v.key(s.text<128>("key"));
  v.value(s.text<64>("value"));
  v.request_id(s.u64("request_id"));
  v.requester(s.text<64>("requester"));
  v.entries(s.texts<192>("entries", 2));
  return v;
}

msg::ParameterEvent parameter_event(Sampler& s) {
  msg::ParameterEvent v;
  v.stamp(stamp(s));
  v.node(s.text<64>("node"));
  v.request_id(s.u64("request_id"));
  v.operation(s.u8("operation"));
  v.accepted(s.flag("accepted"));
  v.key(s.text<128>("key"));
  v.value(s.text<64>("value"));
  v.old_value(s.text<64>("old_value"));
  v.version(s.u64("version"));
  v.effective_tick(s.u64("effective_tick"));
  v.reason(s.text<256>("reason"));
  v.entries(s.texts<192>("entries", 3));
  return v;
}

enum class ByteOrder { Little, Big };

/// Little-endian as Fast DDS publishes it; big-endian through Fast CDR with the same code.
template <class PubSubType, auto fill>
Bytes make_sample(Sampler& sampler, ByteOrder order) {
  auto sample = fill(sampler);
  PubSubType type;
  if (order == ByteOrder::Little) {
    eprosima::fastrtps::rtps::SerializedPayload_t payload(type.m_typeSize);
    EXPECT_TRUE(type.serialize(&sample, &payload));
    return Bytes(payload.data, payload.data + payload.length);
  }
  std::vector<char> buffer(type.m_typeSize);
  eprosima::fastcdr::FastBuffer fast_buffer(buffer.data(), buffer.size());
  eprosima::fastcdr::Cdr cdr(fast_buffer, eprosima::fastcdr::Cdr::BIG_ENDIANNESS, eprosima::fastcdr::Cdr::DDS_CDR);
  cdr.serialize_encapsulation();
  sample.serialize(cdr);
  const auto* first = reinterpret_cast<const std::uint8_t*>(buffer.data());
  return Bytes(first, first + cdr.getSerializedDataLength());
}

struct CatalogCase {
  const char* type_name;
  Bytes (*make)(Sampler&, ByteOrder);
};

const CatalogCase kCases[] = {
    {"pmlsm_msgs::msg::MotorFeedback", make_sample<msg::MotorFeedbackPubSubType, motor_feedback>},
    {"pmlsm_msgs::msg::PlantTruth", make_sample<msg::PlantTruthPubSubType, plant_truth>},
    {"pmlsm_msgs::msg::ForceCommand", make_sample<msg::ForceCommandPubSubType, force_command>},
    {"pmlsm_msgs::msg::CurrentFeedback", make_sample<msg::CurrentFeedbackPubSubType, current_feedback>},
    {"pmlsm_msgs::msg::VoltageCommand", make_sample<msg::VoltageCommandPubSubType, voltage_command>},
    {"pmlsm_msgs::msg::VelocityReference", make_sample<msg::VelocityReferencePubSubType, velocity_reference>},
    {"pmlsm_msgs::msg::VelocitySetpoint", make_sample<msg::VelocitySetpointPubSubType, velocity_setpoint>},
    {"pmlsm_msgs::msg::EstimatedState", make_sample<msg::EstimatedStatePubSubType, estimated_state>},
    {"pmlsm_msgs::msg::DriveControl", make_sample<msg::DriveControlPubSubType, drive_control>},
    {"pmlsm_msgs::msg::DriveState", make_sample<msg::DriveStatePubSubType, drive_state>},
    {"pmlsm_msgs::msg::CompensatorOutput", make_sample<msg::CompensatorOutputPubSubType, compensator_output>},
    {"pmlsm_msgs::msg::NetworkWeights", make_sample<msg::NetworkWeightsPubSubType, network_weights>},
    {"pmlsm_msgs::msg::TrainerProgress", make_sample<msg::TrainerProgressPubSubType, trainer_progress>},
    {"pmlsm_msgs::msg::NodeStatus", make_sample<msg::NodeStatusPubSubType, node_status>},
    {"pmlsm_msgs::msg::TrainingSetup", make_sample<msg::TrainingSetupPubSubType, training_setup>},
    {"pmlsm_msgs::msg::EvaluationRequest", make_sample<msg::EvaluationRequestPubSubType, evaluation_request>},
    {"pmlsm_msgs::msg::EvaluationResult", make_sample<msg::EvaluationResultPubSubType, evaluation_result>},
    {"pmlsm_msgs::msg::WorkerStatus", make_sample<msg::WorkerStatusPubSubType, worker_status>},
    {"pmlsm_msgs::msg::AgentAnnounce", make_sample<msg::AgentAnnouncePubSubType, agent_announce>},
    {"pmlsm_msgs::msg::LaunchRequest", make_sample<msg::LaunchRequestPubSubType, launch_request>},
    {"pmlsm_msgs::msg::NodeOutput", make_sample<msg::NodeOutputPubSubType, node_output>},
    {"pmlsm_msgs::msg::NodeExit", make_sample<msg::NodeExitPubSubType, node_exit>},
    {"pmlsm_msgs::msg::ParameterRequest", make_sample<msg::ParameterRequestPubSubType, parameter_request>},
    {"pmlsm_msgs::msg::ParameterEvent", make_sample<msg::ParameterEventPubSubType, parameter_event>},
};

const CatalogCase* find_case(const std::string& type_name) {
  for (const auto& c : kCases) {
    if (type_name == c.type_name) return &c;
  }
  return nullptr;
}

MessageSchema schema_of(const std::string& type_name) {
  const auto* entry = pmlsm::dds::find_type(type_name);
  if (entry == nullptr) throw std::logic_error("not in the catalog: " + type_name);
  return MessageSchema::parse(entry->schema_idl, entry->type_name);
}

void expect_fields(const Decoded& decoded, const std::vector<Field>& expected) {
  ASSERT_EQ(decoded.fields.size(), expected.size()) << decoded.error;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const Field& got = decoded.fields[i];
    EXPECT_EQ(got.path, expected[i].path);
    EXPECT_EQ(got.value.index(), expected[i].value.index()) << got.path;
    EXPECT_TRUE(got.value == expected[i].value)
        << got.path << ": got " << got.to_string() << ", want " << expected[i].to_string();
  }
}

TEST(CatalogDecode, EveryCatalogTypeHasACase) {
  ASSERT_EQ(pmlsm::dds::catalog().size(), std::size(kCases));
  for (const auto& entry : pmlsm::dds::catalog()) {
    EXPECT_NE(find_case(entry.type_name), nullptr) << entry.type_name;
  }
}

class CatalogTypeTest : public ::testing::TestWithParam<CatalogCase> {};

TEST_P(CatalogTypeTest, DecodesLittleEndianAsFastDdsWritesIt) {
  Sampler sampler;
  const Bytes bytes = GetParam().make(sampler, ByteOrder::Little);
  ASSERT_GE(bytes.size(), 4U);
  EXPECT_EQ(bytes[1], 1U);  // CDR_LE
  const Decoded decoded = schema_of(GetParam().type_name).decode(bytes.data(), bytes.size());
  EXPECT_TRUE(decoded.ok()) << decoded.error;
  expect_fields(decoded, sampler.expected());
}

TEST_P(CatalogTypeTest, DecodesBigEndian) {
  Sampler sampler;
  const Bytes bytes = GetParam().make(sampler, ByteOrder::Big);
  ASSERT_GE(bytes.size(), 4U);
  EXPECT_EQ(bytes[1], 0U);  // CDR_BE
  const Decoded decoded = schema_of(GetParam().type_name).decode(bytes.data(), bytes.size());
  EXPECT_TRUE(decoded.ok()) << decoded.error;
  expect_fields(decoded, sampler.expected());
}

TEST_P(CatalogTypeTest, FieldPathsMatchTheDecodedFields) {
  // Without sequence indices ("weights[3]" -> "weights[]"), the decoded paths are field_paths()
  // in order, each sequence element repeating its element's paths.
  Sampler sampler;
  const Bytes bytes = GetParam().make(sampler, ByteOrder::Little);
  const MessageSchema schema = schema_of(GetParam().type_name);
  const auto paths = schema.field_paths();
  std::vector<std::string> generic;
  for (const auto& field : schema.decode(bytes.data(), bytes.size()).fields) {
    std::string path = field.path;
    // Only covariance_diag is a fixed array in the catalog: its indices stay.
    if (path.rfind("covariance_diag", 0) != 0) {
      for (std::size_t open = path.find('['); open != std::string::npos; open = path.find('[', open + 2)) {
        path.erase(open + 1, path.find(']', open) - open - 1);
      }
    }
    if (generic.empty() || generic.back() != path) generic.push_back(path);
  }
  std::vector<std::string> distinct;
  for (const auto& path : generic) {
    if (std::find(distinct.begin(), distinct.end(), path) == distinct.end()) distinct.push_back(path);
  }
  EXPECT_EQ(distinct, paths);
}

TEST_P(CatalogTypeTest, SurvivesCorruptedSamples) {
  // Random byte flips and cuts of a valid sample: any outcome but a crash or an exception.
  Sampler sampler;
  const Bytes original = GetParam().make(sampler, ByteOrder::Little);
  const MessageSchema schema = schema_of(GetParam().type_name);
  std::mt19937 random(12345);
  for (int round = 0; round < 300; ++round) {
    Bytes bytes = original;
    const int flips = 1 + static_cast<int>(random() % 4);
    for (int i = 0; i < flips; ++i) {
      bytes[4 + random() % (bytes.size() - 4)] = static_cast<std::uint8_t>(random());
    }
    bytes.resize(4 + random() % (bytes.size() - 3));
    const Decoded decoded = schema.decode(bytes.data(), bytes.size());
    EXPECT_LE(decoded.fields.size(), bytes.size());
  }
}

INSTANTIATE_TEST_SUITE_P(Catalog, CatalogTypeTest, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<CatalogCase>& info) {
                           const std::string name = info.param.type_name;
                           return name.substr(name.rfind(':') + 1);
                         });

/// Every prefix of a valid sample: no crash, an error naming the byte and the field, and the
/// fields decoded before the cut equal to the full decode's.
void check_every_truncation(const std::string& type_name, const Bytes& bytes) {
  const MessageSchema schema = schema_of(type_name);
  const Decoded full = schema.decode(bytes.data(), bytes.size());
  ASSERT_TRUE(full.ok()) << full.error;
  std::size_t previous_count = 0;
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    const Bytes cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(length));
    const Decoded decoded = schema.decode(cut.data(), cut.size());
    ASSERT_FALSE(decoded.ok()) << "length " << length;
    ASSERT_LT(decoded.fields.size(), full.fields.size()) << "length " << length;
    EXPECT_GE(decoded.fields.size(), previous_count) << "length " << length;
    previous_count = decoded.fields.size();
    for (std::size_t i = 0; i < decoded.fields.size(); ++i) {
      EXPECT_EQ(decoded.fields[i].path, full.fields[i].path);
      EXPECT_TRUE(decoded.fields[i].value == full.fields[i].value) << decoded.fields[i].path;
    }
    if (length < 4) {
      EXPECT_NE(decoded.error.find("encapsulation header"), std::string::npos) << decoded.error;
    } else {
      EXPECT_NE(decoded.error.find("at byte "), std::string::npos) << decoded.error;
      // The field named is the one being read at the cut (a sequence names itself).
      const std::string& next_path = full.fields[decoded.fields.size()].path;
      const std::string named = next_path.substr(0, next_path.find('['));
      EXPECT_NE(decoded.error.find("field '" + named), std::string::npos)
          << "length " << length << ": " << decoded.error;
    }
  }
}

TEST(CatalogDecode, EveryTruncationOfMotorFeedback) {
  Sampler sampler;
  const Bytes bytes = make_sample<msg::MotorFeedbackPubSubType, motor_feedback>(sampler, ByteOrder::Little);
  // header + 11 eight-byte members (4 in the stamp) + uint32 + uint8 + 1 padding + uint16 + uint8
  // + 7 padding + 2 eight-byte members
  ASSERT_EQ(bytes.size(), 124U);
  check_every_truncation("pmlsm_msgs::msg::MotorFeedback", bytes);
  // Fixed layout: member i (< 11) ends at byte 4 + 8 (i + 1), status at 96, power_state at 97,
  // error_code (aligned to 2) at 100, load_sensor at 101, the load's position (aligned to 8 in
  // the payload) at 116 and its acceleration at 124.
  std::vector<std::size_t> ends;
  for (std::size_t i = 0; i < 11; ++i) ends.push_back(4 + 8 * (i + 1));
  ends.insert(ends.end(), {96, 97, 100, 101, 116, 124});
  const MessageSchema schema = schema_of("pmlsm_msgs::msg::MotorFeedback");
  ASSERT_EQ(schema.decode(bytes.data(), bytes.size()).fields.size(), ends.size());
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    std::size_t complete = 0;
    for (const std::size_t end : ends) complete += (end <= length) ? 1 : 0;
    EXPECT_EQ(schema.decode(bytes.data(), length).fields.size(), complete) << length;
  }
}

TEST(CatalogDecode, EveryTruncationOfDriveState) {
  Sampler sampler;
  check_every_truncation("pmlsm_msgs::msg::DriveState",
                         make_sample<msg::DriveStatePubSubType, drive_state>(sampler, ByteOrder::Little));
}

TEST(CatalogDecode, EveryTruncationOfDriveControl) {
  Sampler sampler;
  check_every_truncation("pmlsm_msgs::msg::DriveControl",
                         make_sample<msg::DriveControlPubSubType, drive_control>(sampler, ByteOrder::Little));
}

TEST(CatalogDecode, EveryTruncationOfNetworkWeights) {
  Sampler sampler;
  check_every_truncation("pmlsm_msgs::msg::NetworkWeights",
                         make_sample<msg::NetworkWeightsPubSubType, network_weights>(sampler, ByteOrder::Little));
}

TEST(CatalogDecode, RejectsOtherEncapsulations) {
  Sampler sampler;
  const Bytes valid = make_sample<msg::MotorFeedbackPubSubType, motor_feedback>(sampler, ByteOrder::Little);
  const MessageSchema schema = schema_of("pmlsm_msgs::msg::MotorFeedback");
  const std::pair<std::uint8_t, std::string> kinds[] = {{0x02, "0x0002 (PL_CDR_BE)"},
                                                        {0x03, "0x0003 (PL_CDR_LE)"},
                                                        {0x06, "0x0006 (CDR2_BE)"},
                                                        {0x07, "0x0007 (CDR2_LE)"},
                                                        {0x08, "0x0008"},
                                                        {0x09, "0x0009"},
                                                        {0x0a, "0x000a"},
                                                        {0x0b, "0x000b (PL_CDR2_LE)"},
                                                        {0x42, "0x0042"}};
  for (const auto& [kind, text] : kinds) {
    Bytes bytes = valid;
    bytes[1] = kind;
    const Decoded decoded = schema.decode(bytes.data(), bytes.size());
    EXPECT_TRUE(decoded.fields.empty());
    EXPECT_NE(decoded.error.find("unsupported encapsulation " + text), std::string::npos) << decoded.error;
  }
  Bytes bytes = valid;
  bytes[0] = 0x01;
  EXPECT_NE(schema.decode(bytes.data(), bytes.size()).error.find("unsupported encapsulation 0x0101"),
            std::string::npos);
  EXPECT_FALSE(schema.decode(nullptr, 10).ok());
}

TEST(CatalogDecode, SequenceCountBeyondItsBoundOrTheData) {
  Sampler sampler;
  Bytes bytes = make_sample<msg::NetworkWeightsPubSubType, network_weights>(sampler, ByteOrder::Little);
  const MessageSchema schema = schema_of("pmlsm_msgs::msg::NetworkWeights");
  // layer_sizes' count follows stamp (32 bytes) and version (8): byte 4 + 40 = 44.
  ASSERT_EQ(bytes[44], 5U);
  bytes[44] = 9;
  Decoded decoded = schema.decode(bytes.data(), bytes.size());
  EXPECT_EQ(decoded.error, "at byte 44, field 'layer_sizes': sequence count 9 exceeds its bound 8");
  EXPECT_EQ(decoded.fields.size(), 5U);  // stamp (4) and version
  // weights' count: after 5 uint16 (rel 44..54) and padding to 4: rel 56, byte 60.
  bytes[44] = 5;
  ASSERT_EQ(bytes[60], 37U);
  bytes[60] = 0xff;
  bytes[61] = 0x03;  // 1023: within the bound, far beyond the data
  decoded = schema.decode(bytes.data(), bytes.size());
  EXPECT_NE(decoded.error.find("at byte 60, field 'weights': sequence count 1023 needs at least "
                               "8184 bytes"),
            std::string::npos)
      << decoded.error;
  EXPECT_EQ(decoded.fields.size(), 10U);  // up to the last layer size
}

TEST(CatalogDecode, YamlOfASample) {
  msg::NetworkWeights sample;
  msg::Stamp stamp;
  stamp.tick(12);
  stamp.sim_time_ns(12'000'000);
  stamp.source_time_ns(-5);
  stamp.run_id(0xFEDCBA9876543210ULL);
  sample.stamp(stamp);
  sample.version(3);
  sample.layer_sizes({3, 1});
  sample.weights({1.5, -0.25});
  sample.input_scale(0.1);
  sample.gain_n(2.0);
  sample.cost(1e20);
  sample.source("file 'a.yaml'");
  msg::NetworkWeightsPubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.m_typeSize);
  ASSERT_TRUE(type.serialize(&sample, &payload));
  const Decoded decoded = schema_of("pmlsm_msgs::msg::NetworkWeights").decode(payload.data, payload.length);
  ASSERT_TRUE(decoded.ok()) << decoded.error;
  EXPECT_EQ(MessageSchema::to_yaml(decoded),
            "stamp:\n"
            "  tick: 12\n"
            "  sim_time_ns: 12000000\n"
            "  source_time_ns: -5\n"
            "  run_id: 18364758544493064720\n"
            "version: 3\n"
            "layer_sizes:\n"
            "- 3\n"
            "- 1\n"
            "weights:\n"
            "- 1.5\n"
            "- -0.25\n"
            "input_scale: 0.1\n"
            "gain_n: 2.0\n"
            "cost: 1.0e+20\n"
            "source: 'file ''a.yaml'''\n");
  EXPECT_EQ(decoded.find("weights[1]")->as_double(), -0.25);
  EXPECT_EQ(decoded.find("stamp.tick")->as_double(), 12.0);
  EXPECT_FALSE(decoded.find("source")->as_double().has_value());
  EXPECT_EQ(decoded.find("weights[2]"), nullptr);
}

TEST(CatalogDecode, RosStyleTypeNames) {
  const auto* entry = pmlsm::dds::find_type("pmlsm_msgs::msg::MotorFeedback");
  ASSERT_NE(entry, nullptr);
  for (const char* name : {"pmlsm_msgs/msg/MotorFeedback", "/pmlsm_msgs/msg/MotorFeedback",
                           "::pmlsm_msgs::msg::MotorFeedback", "pmlsm_msgs::msg::MotorFeedback"}) {
    EXPECT_EQ(MessageSchema::parse(entry->schema_idl, name).type_name(), "pmlsm_msgs::msg::MotorFeedback") << name;
  }
}

TEST(CatalogDecode, UnknownTypeListsTheStructs) {
  const auto* entry = pmlsm::dds::find_type("pmlsm_msgs::msg::MotorFeedback");
  ASSERT_NE(entry, nullptr);
  try {
    MessageSchema::parse(entry->schema_idl, "pmlsm_msgs/msg/MotorFeedbak");
    FAIL() << "no SchemaError";
  } catch (const pmlsm::introspect::SchemaError& error) {
    EXPECT_EQ(std::string(error.what()),
              "unknown type 'pmlsm_msgs/msg/MotorFeedbak': the IDL defines the structs "
              "pmlsm_msgs::msg::Stamp, pmlsm_msgs::msg::MotorFeedback");
  }
}

}  // namespace
