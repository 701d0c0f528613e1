// foxglove_bridge: the running system, live in Foxglove. A Foxglove WebSocket server
// (foxglove.websocket.v1) advertises the project's topics, each as a "cdr" channel with its
// flattened IDL ("omgidl") schema, and forwards the samples exactly as they are on the wire
// (CDR with its encapsulation header), so Foxglove decodes them itself.
//
// Threads: DDS listeners only signal the Wakeup; this node's main thread takes the samples
// and hands them to the server (foxglove_server.hpp), whose network thread sends them. A slow
// client loses frames (counted), it never holds up the main thread, and nothing here ever
// holds up a DDS writer.
//
// Cost to the control loop, which shares the machine: the bridge lowers its own scheduling
// priority (--nice) and drains its readers in batches (--batch-ms) rather than waking its
// threads for every sample: a live plot needs no better than a few milliseconds.
//
// Readers are made lazily: a topic is read only while some client subscribes to it. Every
// matched reader costs each write of that topic one more datagram, in the writer's own
// thread (the control topics publish synchronously), so with no viewer attached the control
// loop pays nothing, and a viewer of two topics costs only those two. The readers are
// best-effort (no acknowledgements or repairs for the writer to serve) and volatile (no burst
// of the writer's history when a viewer subscribes): the built-in profile below. A live plot
// does not need a sample it missed; --reader-profile picks another one for those who do.
//
// A component with a cycle (made from its command line: topics chosen, participant, server bound;
// then updated by its executor, one pass an update). It sleeps between batches and lowers its
// thread's priority, so it runs alone in its process, never on a container's chain thread.
#include <sys/resource.h>
#include <unistd.h>

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/rtps/common/SerializedPayload.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "NodeStatusPubSubTypes.h"
#include "foxglove_bridge_command_line.hpp"
#include "foxglove_server.hpp"
#include "cycle_component.hpp"
#include "pmlsm/dds/catalog.hpp"

namespace {

using namespace pmlsm;
namespace pdds = pmlsm::dds;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;
using ReturnCode = eprosima::fastrtps::types::ReturnCode_t;

constexpr const char* kNodeName = "foxglove_bridge";

/// The bridge's reader QoS (see the header comment), built in so that any --profiles file
/// works. A profile of this name in --profiles wins: that file is loaded first (Fast DDS then
/// logs that it cannot add this one).
using node::kLiveReaderProfile;
constexpr char kLiveReaderProfileXml[] = R"xml(<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <data_reader profile_name="pmlsm_bridge_live">
      <topic>
        <historyQos><kind>KEEP_LAST</kind><depth>256</depth></historyQos>
      </topic>
      <qos>
        <reliability><kind>BEST_EFFORT</kind></reliability>
        <durability><kind>VOLATILE</kind></durability>
      </qos>
    </data_reader>
  </profiles>
</dds>
)xml";

/// Samples taken from one reader before looking at the others and at the clock again.
constexpr std::size_t kMaxSamplesPerPass = 256;

using BridgeOptions = node::FoxgloveBridgeOptions;

struct BridgedTopic {
  const pdds::CatalogEntry* entry = nullptr;
  foxglove::ChannelId channel = 0;
  std::string display_name;                                 // "/pmlsm/motor_feedback", the Foxglove topic
  std::optional<pdds::Reader<pdds::RawPubSubType>> reader;  // while some client subscribes
  std::uint64_t samples_taken = 0;
};

/// The topics named on the command line (any of "rt/pmlsm/x", "/pmlsm/x", "pmlsm/x"), in
/// catalog order, or all of them.
/// @throws ConfigError naming the unknown topic and listing the known ones.
std::vector<BridgedTopic> select_topics(const std::vector<std::string>& names) {
  std::vector<const pdds::CatalogEntry*> chosen;
  for (const auto& name : names) {
    const pdds::CatalogEntry* entry = pdds::find_topic(name);
    if (entry == nullptr) {
      throw ConfigError("--topics: unknown topic '" + name + "'; known topics:\n" + pdds::known_topics_list());
    }
    chosen.push_back(entry);
  }
  std::vector<BridgedTopic> topics;
  foxglove::ChannelId next_channel = 1;
  for (const auto& entry : pdds::catalog()) {
    const bool wanted = names.empty() || std::find(chosen.begin(), chosen.end(), &entry) != chosen.end();
    if (!wanted) continue;
    BridgedTopic t;
    t.entry = &entry;
    t.channel = next_channel++;
    t.display_name = pdds::display_name(entry.spec.name);
    topics.push_back(std::move(t));
  }
  return topics;
}

std::vector<foxglove::Channel> channels_of(const std::vector<BridgedTopic>& topics) {
  std::vector<foxglove::Channel> channels;
  for (const auto& t : topics) {
    foxglove::Channel c;
    c.id = t.channel;
    c.topic = t.display_name;
    c.schema_name = t.entry->type_name;
    c.schema = t.entry->schema_idl;
    channels.push_back(std::move(c));
  }
  return channels;
}

/// NodeStatus through a raw writer. The bridge reads /pmlsm/node_status raw, and one
/// participant holds one type support per topic: the typed StatusPublisher of the other
/// nodes would clash with it. Same type name, same bytes on the wire.
class RawStatusPublisher {
 public:
  explicit RawStatusPublisher(pdds::Participant& participant)
      : writer_(participant.make_raw_writer(*pdds::find_topic(pdds::topics::kNodeStatus.name))),
        payload_(type_.m_typeSize) {
    char host[64] = {};
    gethostname(host, sizeof host - 1);
    status_.node_name(kNodeName);
    status_.host_name(host);
    status_.pid(static_cast<std::uint32_t>(getpid()));
  }

  pmlsm_msgs::msg::NodeStatus& status() { return status_; }

  /// `heartbeat`: the count of status messages, as the stamp's tick, `period_s` apart.
  void publish(std::uint8_t state, std::uint64_t heartbeat, double period_s, std::string message) {
    status_.stamp(node::make_stamp(heartbeat, period_s));
    status_.state(state);
    constexpr std::size_t kMaxMessageChars = 127;  // string<128> in NodeStatus.idl
    if (message.size() > kMaxMessageChars) message.resize(kMaxMessageChars);
    status_.message(message);
    payload_.length = 0;
    payload_.pos = 0;
    if (!type_.serialize(&status_, &payload_)) {
      std::fprintf(stderr, "%s: cannot serialize NodeStatus\n", kNodeName);
      return;
    }
    sample_.bytes.assign(payload_.data, payload_.data + payload_.length);
    writer_.write(sample_);
  }

  void flush(std::chrono::duration<double> timeout) { writer_.wait_for_acknowledgments(timeout); }

 private:
  pdds::Writer<pdds::RawPubSubType> writer_;
  pmlsm_msgs::msg::NodeStatusPubSubType type_;
  eprosima::fastrtps::rtps::SerializedPayload_t payload_;
  pdds::RawSample sample_;
  pmlsm_msgs::msg::NodeStatus status_;
};

/// Opens the reader of every topic some client subscribes to, closes the others'.
void match_readers_to_subscriptions(std::vector<BridgedTopic>& topics, const foxglove::Server& server,
                                    pdds::Participant& participant, pdds::Wakeup& wakeup, const char* profile) {
  bool changed = false;
  for (auto& t : topics) {
    const std::size_t subscribers = server.subscriber_count(t.channel);
    if (subscribers > 0 && !t.reader) {
      t.reader = participant.make_raw_reader(*t.entry, wakeup, profile);
      std::printf("%s: reading %s (%zu subscriber%s)\n", kNodeName, t.display_name.c_str(), subscribers,
                  subscribers == 1 ? "" : "s");
      changed = true;
    } else if (subscribers == 0 && t.reader) {
      participant.delete_reader(*t.reader);
      t.reader.reset();
      std::printf("%s: stopped reading %s (no subscribers)\n", kNodeName, t.display_name.c_str());
      changed = true;
    }
  }
  if (changed) {
    const auto open =
        std::count_if(topics.begin(), topics.end(), [](const BridgedTopic& t) { return t.reader.has_value(); });
    std::printf("%s: reading %zu of %zu topics\n", kNodeName, static_cast<std::size_t>(open), topics.size());
  }
}

/// Takes up to kMaxSamplesPerPass samples of one topic and hands them to the server.
std::size_t forward_samples(BridgedTopic& t, foxglove::Server& server, pdds::RawSample& sample,
                            eprosima::fastdds::dds::SampleInfo& info) {
  std::size_t taken = 0;
  while (taken < kMaxSamplesPerPass && t.reader->take(sample, info)) {
    ++taken;
    // Foxglove's message time: when the sample reached us (wall clock, as Foxglove shows it).
    std::int64_t receive_time_ns = info.reception_timestamp.to_ns();
    if (receive_time_ns <= 0) receive_time_ns = wall_time_ns();
    server.publish(t.channel, static_cast<std::uint64_t>(receive_time_ns), sample.bytes.data(), sample.bytes.size());
  }
  t.samples_taken += taken;
  return taken;
}

std::string counters_text(const foxglove::ServerCounters& c, std::size_t topics_read, std::size_t topics) {
  return "clients " + std::to_string(c.clients_connected) + ", reading " + std::to_string(topics_read) + "/" +
         std::to_string(topics) + " topics, sent " + std::to_string(c.frames_sent) + ", dropped " +
         std::to_string(c.frames_dropped) + ", bad requests " + std::to_string(c.bad_requests) +
         ", closed for bad input " + std::to_string(c.closed_for_bad_input);
}

/// When to hand the batch over and publish the heartbeat (CLOCK_MONOTONIC ns, the executor's
/// clock), and what the passes cost.
struct PassClock {
  std::int64_t status_period_ns = 0, batch_period_ns = 0;
  std::int64_t next_status_ns = 0;
  std::uint64_t samples_taken = 0;
  double pass_time_sum_us = 0.0, pass_time_max_us = 0.0;
  std::uint64_t passes = 0;
};

class FoxgloveBridgeComponent final : public node::CycleComponent {
 public:
  FoxgloveBridgeComponent(BridgeOptions options, std::vector<BridgedTopic> topics)
      : opt_(std::move(options)),
        topics_(std::move(topics)),
        participant_(node::named(opt_.dds, kNodeName)),
        status_(participant_),
        server_(
            server_options(opt_), channels_of(topics_),
            [](const std::string& line) { std::printf("%s: %s\n", kNodeName, line.c_str()); },
            [this] { wakeup_.notify(); }) {
    if (opt_.reader_profile == kLiveReaderProfile &&
        eprosima::fastdds::dds::DomainParticipantFactory::get_instance()->load_XML_profiles_string(
            kLiveReaderProfileXml, sizeof kLiveReaderProfileXml - 1) != ReturnCode::RETCODE_OK) {
      // Reader creation names the profile if it is missing altogether.
      std::fprintf(stderr, "%s: note: built-in reader profile '%s' not loaded; it must come from '%s'\n", kNodeName,
                   kLiveReaderProfile, opt_.dds.profiles_file.c_str());
    }
    status_.publish(node_state::STATE_STARTING, heartbeats_++, opt_.status_period_s, "starting");
    try {
      server_.start();
    } catch (const std::invalid_argument& e) {
      throw ConfigError(e.what());
    }
    std::printf("%s: listening on ws://%s:%u (%zu topics, DDS domain %d)\n", kNodeName, opt_.address.c_str(),
                static_cast<unsigned>(server_.port()), topics_.size(), opt_.dds.domain_id);
  }

  void activate() override;
  Update update() override;
  /// A bridge serves its clients as long as it runs.
  std::chrono::duration<double> input_timeout() const override { return node::kNoInputTimeout; }
  int inputs_lost() override { return kExitPeerMissing; }
  int finish(int exit_code) override;
  pdds::Wakeup& wakeup() override { return wakeup_; }

 private:
  static foxglove::ServerOptions server_options(const BridgeOptions& opt) {
    foxglove::ServerOptions o;
    o.address = opt.address;
    o.port = static_cast<std::uint16_t>(opt.port);
    o.name = std::string("pmlsm ") + kNodeName;
    o.metadata = {{"dds_domain", std::to_string(opt.dds.domain_id)}};
    o.queue_frames = opt.queue_frames;
    o.max_buffered_bytes = opt.client_buffer_kib * 1024;
    o.max_clients = opt.max_clients;
    return o;
  }
  std::size_t topics_read() const {
    return static_cast<std::size_t>(
        std::count_if(topics_.begin(), topics_.end(), [](const BridgedTopic& t) { return t.reader.has_value(); }));
  }
  void publish_status(std::int64_t now_ns);

  BridgeOptions opt_;
  std::vector<BridgedTopic> topics_;
  pdds::Wakeup wakeup_;  // outlives the participant, whose listeners signal it until its readers are gone
  pdds::Participant participant_;
  RawStatusPublisher status_;
  foxglove::Server server_;
  std::uint64_t heartbeats_ = 0;
  PassClock clock_{};
  pdds::RawSample sample_;
  eprosima::fastdds::dds::SampleInfo info_;
};

void FoxgloveBridgeComponent::activate() {
  clock_.status_period_ns = std::llround(opt_.status_period_s * 1e9);
  clock_.batch_period_ns = std::llround(opt_.batch_ms * 1e6);
  clock_.next_status_ns = monotonic_ns();
}

// One pass: readers opened and closed to follow the subscriptions, a batch of every topic read
// handed to the server, the heartbeat when due. Then it sleeps out the batch period while samples
// flow, or waits for the next sample or heartbeat.
node::CycleComponent::Update FoxgloveBridgeComponent::update() {
  if (server_.failed()) return Update::finished(kExitError);
  match_readers_to_subscriptions(topics_, server_, participant_, wakeup_, opt_.reader_profile.c_str());
  bool more_waiting = false;
  std::size_t taken_this_pass = 0;
  const std::int64_t pass_start_ns = monotonic_ns();
  for (auto& t : topics_) {
    if (!t.reader) continue;
    const std::size_t taken = forward_samples(t, server_, sample_, info_);
    taken_this_pass += taken;
    more_waiting = more_waiting || taken == kMaxSamplesPerPass;
  }
  const std::int64_t now_ns = monotonic_ns();
  if (taken_this_pass > 0) {
    clock_.samples_taken += taken_this_pass;
    const double pass_us = static_cast<double>(now_ns - pass_start_ns) * 1e-3;
    clock_.pass_time_sum_us += pass_us;
    clock_.pass_time_max_us = std::max(clock_.pass_time_max_us, pass_us);
    ++clock_.passes;
  }
  if (now_ns >= clock_.next_status_ns) publish_status(now_ns);
  if (more_waiting) return Update::worked();
  if (taken_this_pass > 0 && clock_.batch_period_ns > 0) {
    // Samples are flowing: let the next batch gather instead of waking for each sample. The
    // readers' history (256 per topic) holds a batch even of a lockstep run.
    return Update::sleeping_until(pass_start_ns + clock_.batch_period_ns);
  }
  return Update::waiting_until(clock_.next_status_ns);
}

void FoxgloveBridgeComponent::publish_status(std::int64_t now_ns) {
  PassClock& clock = clock_;
  const auto c = server_.counters();
  const std::size_t read = topics_read();
  auto& s = status_.status();
  s.ticks(clock.samples_taken);
  s.late(c.frames_dropped);  // frames a slow client did not get in time
  s.rejected(c.bad_requests);
  s.max_loop_time_us(clock.pass_time_max_us);
  s.mean_loop_time_us(clock.passes > 0 ? clock.pass_time_sum_us / static_cast<double>(clock.passes) : 0.0);
  status_.publish(read > 0 ? node_state::STATE_RUNNING : node_state::STATE_WAITING, heartbeats_++, opt_.status_period_s,
                  counters_text(c, read, topics_.size()));
  clock.next_status_ns += clock.status_period_ns;
  if (clock.next_status_ns < now_ns) clock.next_status_ns = now_ns + clock.status_period_ns;  // after a stall: no burst
}

int FoxgloveBridgeComponent::finish(int exit_code) {
  const PassClock& clock = clock_;
  const bool network_failed = server_.failed();
  server_.stop();
  const auto c = server_.counters();
  status_.status().ticks(clock.samples_taken);
  status_.status().late(c.frames_dropped);
  status_.status().rejected(c.bad_requests);
  status_.publish(network_failed ? node_state::STATE_ERROR : node_state::STATE_STOPPING, heartbeats_++,
                  opt_.status_period_s, network_failed ? "network thread failed" : "done");
  // A short flush: the heartbeat is for monitors, and a dead one must not hold up the exit.
  status_.flush(std::chrono::seconds(2));
  std::printf(
      "%s: %llu samples read, %llu frames sent, %llu dropped, %llu bad requests, %llu connections closed for "
      "bad input, %llu handshakes refused, %llu connections\n",
      kNodeName, static_cast<unsigned long long>(clock.samples_taken), static_cast<unsigned long long>(c.frames_sent),
      static_cast<unsigned long long>(c.frames_dropped), static_cast<unsigned long long>(c.bad_requests),
      static_cast<unsigned long long>(c.closed_for_bad_input), static_cast<unsigned long long>(c.handshakes_failed),
      static_cast<unsigned long long>(c.connections_total));
  return network_failed ? kExitError : exit_code;
}

}  // namespace

namespace pmlsm::node {

PMLSM_COMPONENT(foxglove_bridge, make_foxglove_bridge, kRunsAlone);

MadeComponent make_foxglove_bridge(const ComponentContext& /*context*/, int argc, char** argv) {
  BridgeOptions opt;
  if (const auto code = parse_foxglove_bridge_command_line(argc, argv, opt)) return {nullptr, *code};
  std::vector<BridgedTopic> topics = select_topics(opt.topics);
  // Before any thread exists (DDS, network): Linux sets the niceness per thread, and new
  // threads inherit their creator's.
  if (opt.nice > 0 && setpriority(PRIO_PROCESS, 0, opt.nice) != 0) {
    std::fprintf(stderr, "%s: note: cannot set niceness %d (%s); running at the default priority\n", kNodeName,
                 opt.nice, std::strerror(errno));
  }
  return {std::make_unique<FoxgloveBridgeComponent>(std::move(opt), std::move(topics))};
}

}  // namespace pmlsm::node
