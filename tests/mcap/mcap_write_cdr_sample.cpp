// Writes the recordings the Node.js check (tests/node/read_mcap.mjs) opens with @mcap/core and
// decodes with the Foxglove OMG IDL reader: one channel per catalog topic, as the recorder makes
// them (schema = the flattened IDL, encoding "omgidl", messages in CDR from the fastddsgen types),
// with values check_node_decode.cmake compares after decoding.
//
//   mcap_write_cdr_sample COMPRESSION OUTPUT TRUNCATED_OUTPUT [omgidl|ros2]
//
// The last argument picks the profile, as `pmlsm record --profile` does: omgidl (the default)
// or ros2 (ros2msg schemas, the header's profile "ros2"); the messages are the same bytes.
// TRUNCATED_OUTPUT is OUTPUT cut in the middle of its fifth chunk, as a killed recorder leaves it.

#include <fastdds/rtps/common/SerializedPayload.h>

#include <cstdint>
#include <cstdio>
#include <exception>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "CompensatorOutputPubSubTypes.h"
#include "CurrentFeedbackPubSubTypes.h"
#include "DriveControlPubSubTypes.h"
#include "DriveStatePubSubTypes.h"
#include "EstimatedStatePubSubTypes.h"
#include "EvaluationRequestPubSubTypes.h"
#include "EvaluationResultPubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "NetworkWeightsPubSubTypes.h"
#include "NodeStatusPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "TrainerProgressPubSubTypes.h"
#include "TrainingSetupPubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "VelocitySetpointPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "WorkerStatusPubSubTypes.h"
#include "AgentAnnouncePubSubTypes.h"
#include "LaunchRequestPubSubTypes.h"
#include "NodeExitPubSubTypes.h"
#include "ParameterEventPubSubTypes.h"
#include "ParameterRequestPubSubTypes.h"
#include "NodeOutputPubSubTypes.h"
#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/mcap/mcap.hpp"

namespace {

namespace msg = pmlsm_msgs::msg;
using eprosima::fastrtps::rtps::SerializedPayload_t;

constexpr std::uint32_t kTicks = 50;
constexpr std::uint32_t kTicksPerChunk = 10;
constexpr std::int64_t kTickNs = 1'000'000;
// Above 2^53: the Node.js check must keep all 64 bits (it prints it as a decimal string).
constexpr std::uint64_t kRunId = 0xFEDCBA9876543210ULL;

// The CDR bytes Fast DDS puts on the wire, encapsulation header included.
template <class PubSubType, class T>
std::vector<std::uint8_t> to_cdr(T& sample) {
  PubSubType type;
  SerializedPayload_t payload(type.getSerializedSizeProvider(&sample)());
  if (!type.serialize(&sample, &payload))
    throw std::runtime_error(std::string("CDR serialisation failed for ") + type.getName());
  return std::vector<std::uint8_t>(payload.data, payload.data + payload.length);
}

template <class T>
void stamp(T& sample, std::uint32_t tick) {
  sample.stamp().tick(tick);
  sample.stamp().sim_time_ns(kTickNs * tick);
  sample.stamp().source_time_ns(1'700'000'000'000'000'000LL + kTickNs * tick);
  sample.stamp().run_id(kRunId);
}

// Any type with only its stamp set: proves its schema and CDR agree in a third-party decoder.
template <class T, class PubSubType>
std::vector<std::uint8_t> stamped(std::uint32_t tick) {
  T sample;
  stamp(sample, tick);
  return to_cdr<PubSubType>(sample);
}

// The values check_node_decode.cmake expects; binary fractions, so JSON prints them exactly.
std::vector<std::uint8_t> motor_feedback(std::uint32_t tick) {
  msg::MotorFeedback sample;
  stamp(sample, tick);
  sample.position_m(0.125 + 0.25 * tick);
  sample.velocity_mps(-1.5);
  sample.i_q_a(2.5);
  sample.thrust_force_n(30.0);
  sample.applied_force_n(29.5);
  sample.applied_command_tick(tick);
  sample.status(64 | 128);    // STATUS_SIMULATED | STATUS_FAULT
  sample.power_state(6);      // POWER_FAULT_REACTION_ACTIVE
  sample.error_code(0x8611);  // CiA 402 "following error"
  sample.load_sensor(2);      // LOAD_SENSOR_ACCELEROMETER
  sample.load_acceleration_mps2(-3.25);
  return to_cdr<msg::MotorFeedbackPubSubType>(sample);
}

std::vector<std::uint8_t> drive_state(std::uint32_t tick) {
  msg::DriveState sample;
  stamp(sample, tick);
  sample.drive_name("plant_sim");
  sample.power_state(7);  // POWER_FAULT
  sample.statusword(0x0218);
  sample.error_code(0x8611);
  sample.fault_reason("following error 0.5 mm");
  sample.request_id(41);
  sample.request_accepted(true);
  sample.request_message("enable operation: done");
  sample.refused_requests(3);
  sample.faults(2);
  sample.safe_ticks(1500);
  sample.watchdog_armed(false);
  return to_cdr<msg::DriveStatePubSubType>(sample);
}

std::vector<std::uint8_t> drive_control(std::uint32_t tick) {
  msg::DriveControl sample;
  stamp(sample, tick);
  sample.drive_name("*");
  sample.command(6);  // COMMAND_FAULT_RESET
  sample.request_id(42);
  sample.requester("operator@host-b");
  return to_cdr<msg::DriveControlPubSubType>(sample);
}

std::vector<std::uint8_t> force_command(std::uint32_t tick) {
  msg::ForceCommand sample;
  stamp(sample, tick);
  sample.feedback_tick(tick);
  sample.force_n(12.5);
  sample.pi_force_n(10.25);
  sample.compensation_force_n(2.25);
  sample.velocity_error_mps(-0.5);
  sample.saturated(tick % 2 == 1);
  return to_cdr<msg::ForceCommandPubSubType>(sample);
}

std::vector<std::uint8_t> node_status(std::uint32_t tick) {
  msg::NodeStatus sample;
  stamp(sample, tick);
  sample.node_name("plant_sim");
  sample.host_name("host-a");
  sample.pid(4242);
  sample.state(2);
  sample.ticks(tick);
  sample.max_loop_time_us(12.75);
  sample.message("running");
  return to_cdr<msg::NodeStatusPubSubType>(sample);
}

std::vector<std::uint8_t> network_weights(std::uint32_t tick) {
  msg::NetworkWeights sample;
  stamp(sample, tick);
  sample.version(7);
  sample.layer_sizes({3, 6, 6, 3, 1});
  sample.weights({0.5, -0.25, 1.0, 2.0});
  sample.input_scale(0.001);
  sample.gain_n(40.0);
  sample.cost(-1.0);
  sample.source("test");
  return to_cdr<msg::NetworkWeightsPubSubType>(sample);
}

std::vector<std::uint8_t> training_setup(std::uint32_t tick) {
  msg::TrainingSetup sample;
  stamp(sample, tick);
  sample.run_id(99);
  sample.system_yaml("plant: {}\n");
  sample.system_overrides({"controller.kp=1"});
  msg::TrainingScenarioText scenario;
  scenario.yaml("steps: []\n");
  scenario.origin("step.yaml");
  scenario.weight(2.0);
  sample.scenarios({scenario, scenario});
  sample.cost_velocity("truth");
  return to_cdr<msg::TrainingSetupPubSubType>(sample);
}

using Generator = std::function<std::vector<std::uint8_t>(std::uint32_t tick)>;

std::map<std::string, Generator> generators() {
  return {
      {"pmlsm_msgs::msg::MotorFeedback", motor_feedback},
      {"pmlsm_msgs::msg::ForceCommand", force_command},
      {"pmlsm_msgs::msg::NodeStatus", node_status},
      {"pmlsm_msgs::msg::NetworkWeights", network_weights},
      {"pmlsm_msgs::msg::TrainingSetup", training_setup},
      {"pmlsm_msgs::msg::DriveState", drive_state},
      {"pmlsm_msgs::msg::DriveControl", drive_control},
      {"pmlsm_msgs::msg::CurrentFeedback", stamped<msg::CurrentFeedback, msg::CurrentFeedbackPubSubType>},
      {"pmlsm_msgs::msg::VoltageCommand", stamped<msg::VoltageCommand, msg::VoltageCommandPubSubType>},
      {"pmlsm_msgs::msg::PlantTruth", stamped<msg::PlantTruth, msg::PlantTruthPubSubType>},
      {"pmlsm_msgs::msg::VelocityReference", stamped<msg::VelocityReference, msg::VelocityReferencePubSubType>},
      {"pmlsm_msgs::msg::EstimatedState", stamped<msg::EstimatedState, msg::EstimatedStatePubSubType>},
      {"pmlsm_msgs::msg::CompensatorOutput", stamped<msg::CompensatorOutput, msg::CompensatorOutputPubSubType>},
      {"pmlsm_msgs::msg::TrainerProgress", stamped<msg::TrainerProgress, msg::TrainerProgressPubSubType>},
      {"pmlsm_msgs::msg::EvaluationRequest", stamped<msg::EvaluationRequest, msg::EvaluationRequestPubSubType>},
      {"pmlsm_msgs::msg::EvaluationResult", stamped<msg::EvaluationResult, msg::EvaluationResultPubSubType>},
      {"pmlsm_msgs::msg::WorkerStatus", stamped<msg::WorkerStatus, msg::WorkerStatusPubSubType>},
      {"pmlsm_msgs::msg::VelocitySetpoint", stamped<msg::VelocitySetpoint, msg::VelocitySetpointPubSubType>},
      {"pmlsm_msgs::msg::AgentAnnounce", stamped<msg::AgentAnnounce, msg::AgentAnnouncePubSubType>},
      {"pmlsm_msgs::msg::LaunchRequest", stamped<msg::LaunchRequest, msg::LaunchRequestPubSubType>},
      {"pmlsm_msgs::msg::NodeOutput", stamped<msg::NodeOutput, msg::NodeOutputPubSubType>},
      {"pmlsm_msgs::msg::NodeExit", stamped<msg::NodeExit, msg::NodeExitPubSubType>},
      {"pmlsm_msgs::msg::ParameterRequest", stamped<msg::ParameterRequest, msg::ParameterRequestPubSubType>},
      {"pmlsm_msgs::msg::ParameterEvent", stamped<msg::ParameterEvent, msg::ParameterEventPubSubType>},
  };
}

int run(const std::string& compression_name, const std::string& output, const std::string& truncated_output,
        pmlsm::dds::RecordingProfile profile) {
  pmlsm::mcap::WriterOptions options;
  options.compression = pmlsm::mcap::parse_compression(compression_name);
  options.profile = profile == pmlsm::dds::RecordingProfile::kRos2 ? "ros2" : "";
  pmlsm::mcap::Writer writer(output, options);

  const std::map<std::string, Generator> make = generators();
  struct Topic {
    std::uint16_t channel_id;
    const Generator* generator;
    bool every_tick;  // the control loop's topics; the others every 10th tick
  };
  std::vector<Topic> topics;
  for (const pmlsm::dds::CatalogEntry& entry : pmlsm::dds::catalog()) {
    const auto generator = make.find(entry.type_name);
    if (generator == make.end()) {
      std::fprintf(stderr, "mcap_write_cdr_sample: no sample for %s; add one\n", entry.type_name.c_str());
      return 1;
    }
    const pmlsm::dds::RecordedSchema schema = pmlsm::dds::recorded_schema(entry, profile);
    const std::uint16_t schema_id = writer.add_schema(schema.name, schema.encoding, schema.data);
    const std::string topic = pmlsm::dds::display_name(entry.spec.name);
    const std::uint16_t channel_id = writer.add_channel(schema_id, topic, "cdr");
    topics.push_back(
        {channel_id, &generator->second, topic == "/pmlsm/motor_feedback" || topic == "/pmlsm/force_command"});
  }

  std::uint64_t truncate_at_bytes = 0;
  std::uint32_t sequence = 0;
  for (std::uint32_t tick = 0; tick < kTicks; ++tick) {
    for (const Topic& topic : topics) {
      if (!topic.every_tick && tick % 10 != 0) continue;
      const std::vector<std::uint8_t> cdr = (*topic.generator)(tick);
      const std::uint64_t time_ns = 1'700'000'000'000'000'000ULL + static_cast<std::uint64_t>(kTickNs) * tick;
      writer.write(topic.channel_id, sequence++, time_ns, time_ns, cdr.data(), cdr.size());
    }
    if ((tick + 1) % kTicksPerChunk == 0) {
      writer.flush_chunk();
      // Cut 50 bytes into the fifth chunk: four whole chunks (40 ticks) before the cut.
      if (tick + 1 == 4 * kTicksPerChunk) truncate_at_bytes = writer.statistics().file_bytes + 50;
    }
  }
  writer.close();

  std::ifstream in(output, std::ios::binary);
  const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (truncate_at_bytes >= bytes.size()) throw std::logic_error("the cut point lies past the end of the file");
  std::ofstream out(truncated_output, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(truncate_at_bytes));
  if (!out) throw std::runtime_error("cannot write " + truncated_output);

  std::printf("%s: %u messages on %zu topics, %llu chunks, %llu bytes (message bytes %llu)\n", output.c_str(), sequence,
              topics.size(), static_cast<unsigned long long>(writer.statistics().chunk_count),
              static_cast<unsigned long long>(writer.statistics().file_bytes),
              static_cast<unsigned long long>(writer.statistics().uncompressed_message_bytes));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4 && argc != 5) {
    std::fprintf(stderr, "usage: %s none|zstd|lz4 OUTPUT.mcap TRUNCATED_OUTPUT.mcap [omgidl|ros2]\n", argv[0]);
    return 2;
  }
  try {
    return run(argv[1], argv[2], argv[3], pmlsm::dds::recording_profile_from_string(argc == 5 ? argv[4] : "omgidl"));
  } catch (const std::exception& error) {
    std::fprintf(stderr, "mcap_write_cdr_sample: %s\n", error.what());
    return 1;
  }
}
