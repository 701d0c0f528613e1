#include "pmlsm/dds/participant.hpp"
#include "pmlsm/dds/ros2_names.hpp"

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

#include "pmlsm/security/keystore_layout.hpp"
#include "pmlsm/util/clock.hpp"

namespace pmlsm::dds {

using eprosima::fastdds::dds::DomainParticipantFactory;
using ReturnCode = eprosima::fastrtps::types::ReturnCode_t;

std::int64_t monotonic_ns_now() { return monotonic_ns(); }

void notify_wakeup(Wakeup& wakeup) { wakeup.notify(); }

eprosima::fastrtps::rtps::Time_t wall_clock_now() {
  eprosima::fastrtps::rtps::Time_t t;
  eprosima::fastrtps::rtps::Time_t::now(t);
  return t;
}

std::uint64_t Wakeup::generation() const { return generation_.load(std::memory_order_acquire); }

void Wakeup::sleep_until_ns(std::int64_t ns) {
  if (cooperative()) {
    scheduler_->sleep_until(ns);
  } else {
    sleep_until_monotonic_ns(ns);
  }
}

bool Wakeup::wait_for(std::uint64_t seen, std::chrono::nanoseconds timeout) {
  if (cooperative()) {
    const std::int64_t now = monotonic_ns();
    if (batch_.count() > 0) {
      scheduler_->sleep_until(now + std::min(timeout, batch_).count());
      return generation_.load(std::memory_order_acquire) != seen;
    }
    return scheduler_->wait(generation_, seen, now + timeout.count());
  }
  if (batch_.count() > 0) {
    std::this_thread::sleep_for(std::min(timeout, batch_));
    return generation_.load(std::memory_order_acquire) != seen;
  }
  // Spin (yielding) for a short while before sleeping: an answer usually comes
  // within a few tens of microseconds, and a condition-variable wake-up costs
  // about as much again on a virtual machine.
  const auto now = std::chrono::steady_clock::now();
  const auto spin_end = now + std::min<std::chrono::nanoseconds>(timeout, spin_);
  while (std::chrono::steady_clock::now() < spin_end) {
    if (generation_.load(std::memory_order_acquire) != seen) return true;
    std::this_thread::yield();
  }
  std::unique_lock<std::mutex> lock(mutex_);
  return cv_.wait_until(lock, now + timeout, [&] { return generation_.load(std::memory_order_acquire) != seen; });
}

bool Wakeup::wait_any(const GenerationWatch* watches, std::size_t count, std::chrono::nanoseconds timeout) {
  if (count == 1 && watches[0].generation == &generation_) return wait_for(watches[0].seen, timeout);
  if (cooperative()) return scheduler_->wait_any(watches, count, monotonic_ns() + timeout.count());
  if (count == 0) {
    if (timeout.count() > 0) sleep_until_monotonic_ns(monotonic_ns() + timeout.count());
    return false;
  }
  throw std::logic_error("Wakeup::wait_any: " + std::to_string(count) +
                         " watches of other wakeups outside a container's fiber: nothing would wake this thread");
}

void Wakeup::notify() {
  if (scheduler_ != nullptr && scheduler_->on_scheduler_thread()) {
    // A component of the container wrote: its readers' fibers look at the generation.
    generation_.fetch_add(1, std::memory_order_acq_rel);
    return;
  }
  if (scheduler_ != nullptr) {
    // From Fast DDS's threads (a sample from outside): the chain thread may be idle.
    {
      std::lock_guard<std::mutex> lock(mutex_);
      generation_.fetch_add(1, std::memory_order_acq_rel);
    }
    cv_.notify_all();
    scheduler_->wake();
    return;
  }
  if (batch_.count() > 0) {
    generation_.fetch_add(1, std::memory_order_acq_rel);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    generation_.fetch_add(1, std::memory_order_acq_rel);
  }
  cv_.notify_all();
}

std::string resolve_keystore(const std::string& option_value) {
  if (option_value == kNoKeystore) return "";
  if (!option_value.empty()) return option_value;
  const char* env = std::getenv(kKeystoreEnv);
  return env != nullptr ? env : "";
}

namespace {

/// Adds the DDS Security properties of `identity` in `keystore` to `qos`, after checking that
/// every file it names can be read (Fast DDS would only say that it failed).
void make_secure(eprosima::fastdds::dds::DomainParticipantQos& qos, const std::string& keystore,
                 const std::string& identity) {
  const security::KeystoreLayout layout(keystore);
  if (::access(keystore.c_str(), F_OK) != 0) {
    throw SecurityConfigError("keystore '" + keystore + "' does not exist (make one with `pmlsm security create " +
                              keystore + "`)");
  }
  if (::access(layout.identity_dir(identity).c_str(), F_OK) != 0) {
    throw SecurityConfigError("keystore '" + keystore + "' has no identity '" + identity + "' (" +
                              layout.identity_dir(identity) + " is missing): create it with `pmlsm security " +
                              "create-identity --keystore " + keystore + " " + identity + "`");
  }
  for (const auto& [path, what] : layout.participant_files(identity)) {
    if (::access(path.c_str(), R_OK) != 0) {
      throw SecurityConfigError("keystore '" + keystore + "': cannot read the " + what + " '" + path +
                                "': " + std::strerror(errno));
    }
  }
  auto& properties = qos.properties().properties();
  for (const auto& [name, value] : layout.participant_properties(identity)) properties.emplace_back(name, value);
}

}  // namespace

class Participant::NotifyingListener : public eprosima::fastdds::dds::DataReaderListener {
 public:
  explicit NotifyingListener(Wakeup& wakeup) : wakeup_(wakeup) {}
  void on_data_available(eprosima::fastdds::dds::DataReader*) override {
    arrived.store(true, std::memory_order_release);
    wakeup_.notify();
  }
  /// Something arrived over DDS since the reader last looked (a container's reader looks at DDS
  /// only then).
  std::atomic<bool> arrived{true};
  void on_subscription_matched(eprosima::fastdds::dds::DataReader*,
                               const eprosima::fastdds::dds::SubscriptionMatchedStatus&) override {
    wakeup_.notify();
  }

 private:
  Wakeup& wakeup_;
};

namespace {

/// What a permissions document (the keystore's permissions.xml of an identity) grants, per
/// role: the topics under <publish> and under <subscribe> of its allow rules. The document is the
/// one `pmlsm security` generated (policy.cpp's permissions_xml), so a plain scan suffices.
std::vector<std::string> granted_topics(const std::string& xml, const std::string& role) {
  std::vector<std::string> topics;
  const std::string open = "<" + role + ">";
  const std::string close = "</" + role + ">";
  for (auto at = xml.find(open); at != std::string::npos; at = xml.find(open, at)) {
    const auto end = xml.find(close, at);
    if (end == std::string::npos) break;
    for (auto t = xml.find("<topic>", at); t != std::string::npos && t < end; t = xml.find("<topic>", t)) {
      t += 7;
      topics.push_back(xml.substr(t, xml.find("</topic>", t) - t));
    }
    at = end;
  }
  return topics;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw SecurityConfigError("cannot read '" + path + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

ProcessParticipant::ProcessParticipant(const ParticipantOptions& options, const std::string& identity)
    : identity_(identity) {
  const std::string& keystore = options.keystore;
  if (!keystore.empty()) {
    if (identity_.empty()) throw SecurityConfigError("a secure participant needs an identity (--identity)");
    // Data-sharing hands samples over through shared memory, past the crypto plugin: no payload
    // protection, no access control on the reading side. Fast DDS 2.9 does not refuse it itself.
    if (options.data_sharing) {
      throw SecurityConfigError("--data-sharing cannot be combined with security (--keystore " + keystore +
                                "): data-sharing hands samples over unencrypted and unchecked");
    }
  }
  auto* factory = DomainParticipantFactory::get_instance();
  if (factory->load_XML_profiles_file(options.profiles_file) != ReturnCode::RETCODE_OK) {
    throw std::runtime_error("cannot load DDS profiles from '" + options.profiles_file + "'");
  }
  // The profile's QoS with the node's name, which discovery shows to the others (`pmlsm topic list`).
  eprosima::fastdds::dds::DomainParticipantQos qos;
  if (factory->get_participant_qos_from_profile(options.participant_profile, qos) != ReturnCode::RETCODE_OK) {
    throw std::runtime_error("no participant profile '" + options.participant_profile + "' in '" +
                             options.profiles_file + "'");
  }
  if (!options.node_name.empty()) qos.name(options.node_name);
  if (!keystore.empty()) make_secure(qos, keystore, identity_);
  participant_ = factory->create_participant(static_cast<eprosima::fastdds::dds::DomainId_t>(options.domain_id), qos,
                                             options.listener);
  if (participant_ == nullptr && !keystore.empty()) {
    throw SecurityConfigError("identity '" + identity_ + "' of keystore '" + keystore +
                              "' was refused: its certificate, key, governance or permissions did not verify "
                              "(`pmlsm security check " +
                              keystore + " " + identity_ + "` says which)");
  }
  if (participant_ == nullptr) {
    throw std::runtime_error("cannot create participant with profile '" + options.participant_profile + "' on domain " +
                             std::to_string(options.domain_id));
  }
  graph_publisher_ = participant_->create_publisher(eprosima::fastdds::dds::PUBLISHER_QOS_DEFAULT);
  try {
    if (graph_publisher_ == nullptr) throw std::runtime_error("cannot create a publisher");
    graph_ = std::make_unique<GraphAnnouncer>(*participant_, *graph_publisher_, !keystore.empty());
  } catch (...) {
    participant_->delete_contained_entities();
    factory->delete_participant(participant_);
    throw;
  }
}

ProcessParticipant::~ProcessParticipant() {
  // The nodes' publishers and subscribers are gone (each Participant deletes its own); what is
  // left is the graph's writer and the topics.
  graph_.reset();
  participant_->delete_contained_entities();
  DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

eprosima::fastdds::dds::Topic* ProcessParticipant::topic(
    const std::string& name, const std::function<eprosima::fastdds::dds::TypeSupport()>& make_type, bool ros2_name) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto found = topics_.find(name);
  if (found != topics_.end()) return found->second;
  eprosima::fastdds::dds::TypeSupport type = make_type();
  if (ros2_name) type->setName(ros2_type_name(type->getName()).c_str());
  if (type.register_type(participant_) != ReturnCode::RETCODE_OK) {
    throw std::runtime_error("cannot register type '" + type.get_type_name() + "'");
  }
  auto* topic = participant_->create_topic(name, type.get_type_name(), eprosima::fastdds::dds::TOPIC_QOS_DEFAULT);
  if (topic == nullptr) throw std::runtime_error("cannot create topic '" + name + "'");
  topics_[name] = topic;
  return topic;
}

std::shared_ptr<ProcessParticipant> SharedParticipant::get(const ParticipantOptions& options) {
  if (participant_ == nullptr) {
    first_ = options;
    first_.node_name = name_;
    first_.shared = nullptr;
    first_.local_bus = nullptr;
    if (options.listener != nullptr) {
      throw std::invalid_argument("a component in a container cannot take the participant's discovery listener");
    }
    participant_ = std::make_shared<ProcessParticipant>(first_, identity_);
    return participant_;
  }
  // A container is one participant: one domain, one profile, one keystore.
  const auto differs = [&](const char* option, const std::string& mine, const std::string& first) {
    if (mine != first) {
      throw std::invalid_argument(std::string("component ") + options.node_name + ": " + option + " '" + mine +
                                  "' differs from the container's participant's '" + first +
                                  "' (a container's components share one participant)");
    }
  };
  differs("--domain", std::to_string(options.domain_id), std::to_string(first_.domain_id));
  differs("--profiles", options.profiles_file, first_.profiles_file);
  differs("--participant-profile", options.participant_profile, first_.participant_profile);
  differs("--keystore", options.keystore, first_.keystore);
  differs("--data-sharing", options.data_sharing ? "on" : "off", first_.data_sharing ? "on" : "off");
  if (options.listener != nullptr) {
    throw std::invalid_argument("a component in a container cannot take the participant's discovery listener");
  }
  return participant_;
}

Participant::Participant(const ParticipantOptions& options)
    : node_name_(options.node_name),
      keystore_(options.keystore),
      data_sharing_(options.data_sharing),
      local_bus_(options.local_bus),
      pace_remote_readers_(options.pace_remote_readers) {
  if (!keystore_.empty()) {
    identity_ = options.identity.empty() ? options.node_name : options.identity;
    if (identity_.empty()) throw SecurityConfigError("a secure participant needs an identity (--identity)");
  }
  if (options.shared == nullptr) {
    process_ = std::make_shared<ProcessParticipant>(options, identity_);
  } else {
    process_ = options.shared->get(options);
    if (!keystore_.empty()) {
      // The container authenticated as its own identity; this node is held to its own grant here.
      const security::KeystoreLayout layout(keystore_);
      if (::access(layout.identity_dir(identity_).c_str(), F_OK) != 0) {
        throw SecurityConfigError("keystore '" + keystore_ + "' has no identity '" + identity_ + "' (" +
                                  layout.identity_dir(identity_) + " is missing): create it with `pmlsm security " +
                                  "create-identity --keystore " + keystore_ + " " + identity_ + "`");
      }
      const std::string permissions = read_text(layout.permissions_xml(identity_));
      granted_publish_ = granted_topics(permissions, "publish");
      granted_subscribe_ = granted_topics(permissions, "subscribe");
      held_to_grant_ = true;
    }
  }
  auto* domain = process_->entity();
  publisher_ = domain->create_publisher(eprosima::fastdds::dds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = domain->create_subscriber(eprosima::fastdds::dds::SUBSCRIBER_QOS_DEFAULT);
  if (publisher_ == nullptr || subscriber_ == nullptr) {
    if (publisher_ != nullptr) domain->delete_publisher(publisher_);
    if (subscriber_ != nullptr) domain->delete_subscriber(subscriber_);
    throw std::runtime_error("cannot create publisher/subscriber");
  }
  graph_node_ = process_->graph().add_node(node_name_);
}

Participant::~Participant() {
  if (process_ == nullptr) return;
  // The publisher thread lets go of this participant's writers first (what it still holds goes
  // out within its close deadline, the rest is counted).
  if (local_bus_ != nullptr) local_bus_->outbox().remove_owner(this, &local_bus_->scheduler());
  // Empty every writer's history first, under the writer's lock. Fast DDS 2.9.1's
  // ~StatefulWriter releases the history's samples one by one (RTPSWriter::deinit) while
  // its periodic heartbeat event still runs; that event, fired while a matched reader has
  // samples unacknowledged (a peer that died and whose lease has not run out yet), walks
  // the half-released history in add_gaps_for_holes_in_history_ and never ends, holding
  // the writer's lock: the process hangs on exit (fixed upstream by eProsima/Fast-DDS#4076,
  // after 2.9). With an empty history deinit has nothing to release. Samples a node wanted
  // delivered were waited for (wait_for_acknowledgments) before this point.
  std::vector<eprosima::fastdds::dds::DataWriter*> writers;
  publisher_->get_datawriters(writers);
  for (auto* writer : writers) {
    std::size_t removed = 0;
    writer->clear_history(&removed);  // RETCODE_ERROR when already empty: nothing to do
  }
  process_->graph().remove_node(graph_node_);
  auto* domain = process_->entity();
  publisher_->delete_contained_entities();
  domain->delete_publisher(publisher_);
  subscriber_->delete_contained_entities();
  domain->delete_subscriber(subscriber_);
  // The last node of the process takes the participant along.
  process_.reset();
  // After the entities: the bus owns the writers' listeners.
  if (local_bus_ != nullptr) local_bus_->remove_owner(this);
}

std::atomic<bool>& Participant::last_arrival_flag() { return listeners_.back()->arrived; }

bool Participant::keeps_state(eprosima::fastdds::dds::DataWriter* writer) {
  const auto qos = writer->get_qos();
  return qos.durability().kind != eprosima::fastdds::dds::VOLATILE_DURABILITY_QOS &&
         qos.history().kind == eprosima::fastdds::dds::KEEP_LAST_HISTORY_QOS && qos.history().depth == 1;
}

Participant::QueueShape Participant::queue_shape(eprosima::fastdds::dds::DataReader* reader) {
  const auto qos = reader->get_qos();
  if (qos.history().kind == eprosima::fastdds::dds::KEEP_ALL_HISTORY_QOS) {
    const std::int32_t max = qos.resource_limits().max_samples;
    // Unlimited (<= 0): as deep as the deepest history of the profiles.
    return {static_cast<std::size_t>(max > 0 ? max : 8192), true};
  }
  return {static_cast<std::size_t>(std::max<std::int32_t>(1, qos.history().depth)), false};
}

Reader<RawPubSubType> Participant::make_raw_reader(const CatalogEntry& entry, Wakeup& wakeup, const char* qos_profile) {
  auto* topic = process_->topic(
      entry.spec.name,
      [&] {
        return eprosima::fastdds::dds::TypeSupport(new RawPubSubType(entry.wire_type_name, entry.max_serialized_size));
      },
      /*ros2_name=*/false);
  return Reader<RawPubSubType>(
      create_reader(topic, qos_profile != nullptr ? qos_profile : entry.spec.qos_profile, wakeup));
}

Writer<RawPubSubType> Participant::make_raw_writer(const CatalogEntry& entry, const char* qos_profile) {
  auto* topic = process_->topic(
      entry.spec.name,
      [&] {
        return eprosima::fastdds::dds::TypeSupport(new RawPubSubType(entry.wire_type_name, entry.max_serialized_size));
      },
      /*ros2_name=*/false);
  return Writer<RawPubSubType>(create_writer(topic, qos_profile != nullptr ? qos_profile : entry.spec.qos_profile));
}

eprosima::fastdds::dds::DataWriter* Participant::create_writer(eprosima::fastdds::dds::Topic* topic,
                                                               const std::string& profile,
                                                               eprosima::fastdds::dds::DataWriterListener* listener) {
  eprosima::fastdds::dds::DataWriterQos qos;
  if (publisher_->get_datawriter_qos_from_profile(profile, qos) != ReturnCode::RETCODE_OK) {
    throw std::runtime_error("no data_writer profile '" + profile + "' in the DDS profiles");
  }
  if (!data_sharing_) qos.data_sharing().off();
  check_grant("publish", topic->get_name());
  auto* writer = publisher_->create_datawriter(topic, qos, listener);
  if (writer == nullptr && !keystore_.empty()) throw SecurityConfigError(refusal_hint("publish", topic->get_name()));
  if (writer == nullptr) {
    throw std::runtime_error("cannot create writer on '" + topic->get_name() + "' with profile '" + profile + "'");
  }
  process_->graph().add_endpoint(graph_node_, writer->guid(), /*writer=*/true);
  return writer;
}

eprosima::fastdds::dds::DataReader* Participant::create_reader(eprosima::fastdds::dds::Topic* topic,
                                                               const std::string& profile, Wakeup& wakeup) {
  listeners_.push_back(std::make_unique<NotifyingListener>(wakeup));
  eprosima::fastdds::dds::DataReaderQos qos;
  if (subscriber_->get_datareader_qos_from_profile(profile, qos) != ReturnCode::RETCODE_OK) {
    throw std::runtime_error("no data_reader profile '" + profile + "' in the DDS profiles");
  }
  if (!data_sharing_) qos.data_sharing().off();
  check_grant("subscribe", topic->get_name());
  auto* reader = subscriber_->create_datareader(topic, qos, listeners_.back().get());
  if (reader == nullptr && !keystore_.empty()) throw SecurityConfigError(refusal_hint("subscribe", topic->get_name()));
  if (reader == nullptr) {
    throw std::runtime_error("cannot create reader on '" + topic->get_name() + "' with profile '" + profile + "'");
  }
  process_->graph().add_endpoint(graph_node_, reader->guid(), /*writer=*/false);
  return reader;
}

bool Participant::grants(const char* role, const std::string& topic) const {
  const auto& granted = std::string(role) == "publish" ? granted_publish_ : granted_subscribe_;
  return std::find(granted.begin(), granted.end(), topic) != granted.end();
}

void Participant::check_grant(const char* role, const std::string& topic) const {
  if (held_to_grant_ && !grants(role, topic)) throw SecurityConfigError(refusal_hint(role, topic));
}

std::string Participant::refusal_hint(const char* what, const std::string& topic) const {
  // In a container DDS checks the container's identity: a topic the node's own grant allows was
  // refused by the container's.
  const bool container_refused = held_to_grant_ && grants(what, topic);
  const std::string& identity = container_refused ? process_->identity() : identity_;
  return "identity '" + identity + "' may not " + what + " '" + topic + "': its permissions (" +
         security::KeystoreLayout(keystore_).permissions_xml(identity) + ") do not grant it" +
         (container_refused ? " (the container's identity: configs/security/policy.yaml, containers:)" : "");
}

void Participant::delete_reader_entity(eprosima::fastdds::dds::DataReader* reader) {
  if (local_bus_ != nullptr) {
    throw std::logic_error("deleting a reader of a component in a container: its local queue would dangle");
  }
  const auto* listener = reader->get_listener();
  const std::string topic = reader->get_topicdescription()->get_name();
  process_->graph().remove_endpoint(reader->guid());
  if (subscriber_->delete_datareader(reader) != ReturnCode::RETCODE_OK) {
    throw std::runtime_error("cannot delete the reader of '" + topic + "'");
  }
  listeners_.erase(
      std::remove_if(listeners_.begin(), listeners_.end(), [&](const auto& l) { return l.get() == listener; }),
      listeners_.end());
}

}  // namespace pmlsm::dds
