// participant_churn: DDS participants that come and go in batches on a running system, as a
// container's components or a handful of tools would: each cycle creates `--batch` participants
// (the shipped participant profile), each reading /pmlsm/motor_feedback and
// /pmlsm/force_command reliably, keeps them `--life-ms`, then deletes them one after the other.
//
// It is the reproducer of a Fast DDS 2.9.1 abort (PDP.cpp, check_remote_participant_liveliness:
// `GUID_t::unknown() != remote_participant->m_guid`): a peer's lease check that runs while peers
// leave. `--lease-ms` below `--life-ms` makes every peer's lease check run during each life, and
// the batches (of this and other churn processes) abort within a few hundred cycles; with the
// shipped lease (20 s) no check runs in a life and none aborts. bench/participant_churn_bench.sh
// measures both.
//
//   participant_churn --domain D [--profiles F] [--participant-profile P] [--cycles N] [--batch B]
//                     [--life-ms L] [--lease-ms 0 (the profile's)]
// Prints one summary line; exits 0 when every cycle ran (or SIGINT/SIGTERM ended it between two),
// 1 when Fast DDS refused an entity.
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "ForceCommandPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "pmlsm/dds/ros2_names.hpp"
#include "pmlsm/dds/shutdown.hpp"

namespace {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

struct Options {
  int domain = -1;
  std::string profiles = PMLSM_SOURCE_DIR "/configs/dds/profiles.xml";
  std::string participant_profile = "pmlsm_default";
  int cycles = 100;
  int batch = 4;
  int life_ms = 150;
  int lease_ms = 0;
};

bool parse(int argc, char** argv, Options& o) {
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--domain") {
      o.domain = std::atoi(value.c_str());
    } else if (key == "--profiles") {
      o.profiles = value;
    } else if (key == "--participant-profile") {
      o.participant_profile = value;
    } else if (key == "--cycles") {
      o.cycles = std::atoi(value.c_str());
    } else if (key == "--batch") {
      o.batch = std::atoi(value.c_str());
    } else if (key == "--life-ms") {
      o.life_ms = std::atoi(value.c_str());
    } else if (key == "--lease-ms") {
      o.lease_ms = std::atoi(value.c_str());
    } else {
      std::fprintf(stderr, "participant_churn: unknown option %s\n", key.c_str());
      return false;
    }
  }
  if (argc % 2 != 1 || o.domain < 0 || o.domain > 232 || o.cycles < 1 || o.batch < 1 || o.life_ms < 1 ||
      o.lease_ms < 0) {
    std::fprintf(stderr,
                 "participant_churn: need --domain 0..232, and --cycles, --batch, --life-ms above 0, --lease-ms 0 or "
                 "above\n");
    return false;
  }
  return true;
}

/// One participant of a batch and its two readers (deleted in reverse by `leave`).
struct Peer {
  fdds::DomainParticipant* participant = nullptr;
  fdds::DataReader* feedback = nullptr;
};

Peer join(const Options& o, const fdds::DomainParticipantQos& qos) {
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  Peer peer;
  peer.participant = factory->create_participant(o.domain, qos);
  if (peer.participant == nullptr) return peer;
  fdds::TypeSupport feedback_type(new pmlsm_msgs::msg::MotorFeedbackPubSubType());
  fdds::TypeSupport command_type(new pmlsm_msgs::msg::ForceCommandPubSubType());
  // Under the names the nodes use (ROS 2's, as on the wire).
  feedback_type->setName(pmlsm::dds::ros2_type_name(feedback_type.get_type_name()).c_str());
  command_type->setName(pmlsm::dds::ros2_type_name(command_type.get_type_name()).c_str());
  feedback_type.register_type(peer.participant);
  command_type.register_type(peer.participant);
  auto* feedback_topic =
      peer.participant->create_topic("rt/pmlsm/motor_feedback", feedback_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  auto* command_topic =
      peer.participant->create_topic("rt/pmlsm/force_command", command_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  auto* subscriber = peer.participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (feedback_topic == nullptr || command_topic == nullptr || subscriber == nullptr) return peer;
  fdds::DataReaderQos reader_qos = fdds::DATAREADER_QOS_DEFAULT;
  reader_qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  peer.feedback = subscriber->create_datareader(feedback_topic, reader_qos);
  subscriber->create_datareader(command_topic, reader_qos);
  return peer;
}

void leave(Peer& peer) {
  if (peer.participant == nullptr) return;
  peer.participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(peer.participant);
  peer = Peer{};
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (!parse(argc, argv, o)) return 2;
  pmlsm::dds::install_shutdown_handlers();
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  if (factory->load_XML_profiles_file(o.profiles) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    std::fprintf(stderr, "participant_churn: cannot load %s\n", o.profiles.c_str());
    return 2;
  }
  fdds::DomainParticipantQos qos;
  if (factory->get_participant_qos_from_profile(o.participant_profile, qos) !=
      eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    std::fprintf(stderr, "participant_churn: no participant profile %s in %s\n", o.participant_profile.c_str(),
                 o.profiles.c_str());
    return 2;
  }
  auto& discovery = qos.wire_protocol().builtin.discovery_config;
  if (o.lease_ms > 0) {
    // Announced three times a lease, as the profiles do (1 s for 3 s).
    discovery.leaseDuration = eprosima::fastrtps::Duration_t(o.lease_ms * 1e-3);
    discovery.leaseDuration_announcementperiod = eprosima::fastrtps::Duration_t(o.lease_ms * 1e-3 / 3.0);
  }
  const double lease_s = discovery.leaseDuration.to_ns() * 1e-9;
  qos.name("participant_churn");

  int matched_cycles = 0;
  int cycles_done = 0;
  std::vector<Peer> batch(static_cast<std::size_t>(o.batch));
  for (int cycle = 0; cycle < o.cycles && !pmlsm::dds::stop_requested(); ++cycle) {
    const auto end_of_life = Clock::now() + std::chrono::milliseconds(o.life_ms);
    for (Peer& peer : batch) {
      peer = join(o, qos);
      if (peer.feedback == nullptr) {
        std::fprintf(stderr, "participant_churn: Fast DDS refused a participant or a reader at cycle %d\n", cycle);
        for (Peer& p : batch) leave(p);
        return 1;
      }
    }
    bool matched = false;
    while (Clock::now() < end_of_life) {
      fdds::SubscriptionMatchedStatus status;
      batch.front().feedback->get_subscription_matched_status(status);
      matched = matched || status.current_count > 0;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (matched) ++matched_cycles;
    for (Peer& peer : batch) leave(peer);
    ++cycles_done;
  }
  std::printf(
      "participant_churn: %d cycles of %d participants (life %d ms, lease %.3f s): %d matched a MotorFeedback "
      "writer\n",
      cycles_done, o.batch, o.life_ms, lease_s, matched_cycles);
  return 0;
}
