// Thin typed layer over Fast DDS: a participant made from an XML profile,
// writers and readers whose QoS come from named XML profiles, and a Wakeup
// that a node's loop thread waits on while readers' listeners signal it.
//
// Following the Fast DDS examples: entities are created in order and every
// null is an error (std::runtime_error naming what failed); the participant
// deletes its contained entities on destruction. Following the realtime
// demos: listeners only signal; the loop thread takes the samples.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/dds/fiber_scheduler.hpp"
#include "pmlsm/dds/local_bus.hpp"
#include "pmlsm/dds/outbox.hpp"
#include "pmlsm/dds/raw_type.hpp"
#include "pmlsm/dds/ros2_graph.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/dds/topics.hpp"

namespace pmlsm::dds {

/// Signalled by readers' listeners when data arrives; the loop thread waits on it. In a
/// container (a scheduler given) the loop is a fiber and waiting hands the chain thread to the
/// next component (see fiber_scheduler.hpp); spinning is then pointless and not done.
class Wakeup {
 public:
  /// spin: how long wait_for() polls (yielding the core) before it sleeps.
  /// batch: when positive, wait_for() sleeps this long whatever arrives and
  /// notify() wakes nobody. For observers off the control chain: they then
  /// take a batch of samples per wake-up instead of waking the loop thread for
  /// every sample (on a virtual machine a wake-up costs tens of microseconds
  /// of the cores the chain needs).
  explicit Wakeup(std::chrono::nanoseconds spin = std::chrono::nanoseconds(0),
                  std::chrono::nanoseconds batch = std::chrono::nanoseconds(0), FiberScheduler* scheduler = nullptr)
      : spin_(spin), batch_(batch), scheduler_(scheduler) {
    if (spin.count() < 0 || batch.count() < 0) {
      throw std::invalid_argument("Wakeup: spin and batch must not be negative, got " + std::to_string(spin.count()) +
                                  " ns and " + std::to_string(batch.count()) + " ns");
    }
  }
  /// A counter read before draining the readers; wait_for() returns at once if
  /// anything arrived after it was read, so no notification is lost.
  std::uint64_t generation() const;
  /// Waits until the generation moves past `seen` or the timeout passes (with
  /// a batch: sleeps min(batch, timeout), then reports whether it moved).
  /// @return false on timeout.
  bool wait_for(std::uint64_t seen, std::chrono::nanoseconds timeout);
  void notify();
  /// Sleeps until the CLOCK_MONOTONIC time `ns` (in a container: lets the other components run).
  void sleep_until_ns(std::int64_t ns);

  /// This wakeup's generation and the value `seen` of it, for wait_any.
  GenerationWatch watch(std::uint64_t seen) const { return {&generation_, seen}; }
  /// Waits until any watched generation moves or the timeout passes (an executor waiting for the
  /// inputs of several components at once); false on timeout. One watch of this wakeup: as
  /// wait_for (its spin and batch). In a container's fiber: one suspension for all (batches are
  /// the caller's to apply). @throws std::logic_error for watches of other wakeups outside a
  /// container, where nothing would wake this thread for them.
  bool wait_any(const GenerationWatch* watches, std::size_t count, std::chrono::nanoseconds timeout);
  /// How long wait_for() sleeps whatever arrives (0: it wakes on arrival).
  std::chrono::nanoseconds batch() const { return batch_; }

 private:
  /// In a fiber of the container's scheduler (false before the container runs).
  bool cooperative() const { return scheduler_ != nullptr && scheduler_->on_scheduler_thread(); }

  std::chrono::nanoseconds spin_;
  std::chrono::nanoseconds batch_;
  FiberScheduler* scheduler_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::atomic<std::uint64_t> generation_{0};
};

class SharedParticipant;

struct ParticipantOptions {
  std::string profiles_file = "configs/dds/profiles.xml";
  std::string participant_profile = "pmlsm_default";
  int domain_id = 0;
  std::string node_name;
  /// Fast DDS data-sharing (zero-copy through /dev/shm between processes it
  /// believes share a host). Off by default: it shares locks with its peers
  /// (see configs/dds/profiles.xml), and it breaks where /dev/shm is not
  /// shared although the host looks the same (network namespaces).
  bool data_sharing = false;
  /// Told about every writer and reader discovered in the domain (`pmlsm topic list`); must
  /// outlive the participant. Set at creation so that no discovery event is missed.
  eprosima::fastdds::dds::DomainParticipantListener* listener = nullptr;
  /// DDS Security: the keystore made by `pmlsm security` (see common/security's
  /// keystore_layout.hpp). Set: the participant authenticates as `identity`, is allowed only
  /// what that identity's permissions grant, and its traffic is protected as the governance
  /// says; a file missing or refused is an error, never an open participant. Empty: an open
  /// participant, as without security.
  std::string keystore;
  /// The identity in the keystore (default: node_name).
  std::string identity;
  /// The container's in-process path (local_bus.hpp); nullptr for a node alone in its process.
  /// Must outlive the participant.
  LocalBus* local_bus = nullptr;
  /// A container's participant, shared by its components (one DDS participant a process, as
  /// rclcpp has it); nullptr: the participant makes its own. Must outlive the participant.
  SharedParticipant* shared = nullptr;
  /// In a container running lockstep: a writer with readers outside the process lets them keep
  /// up (see Writer::write). A lockstep chain in one process runs far faster than a reader
  /// behind a socket takes samples, and a reliable writer's KEEP_LAST history would drop what
  /// they have not acknowledged yet. Never in realtime: the chain does not wait for observers.
  bool pace_remote_readers = false;
};

/// Bad security input (keystore file missing or refused, identity absent, an option that
/// cannot be combined with security): programs exit with code 2 (bad config or input).
class SecurityConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The environment variable that names the keystore when --keystore does not.
inline constexpr const char* kKeystoreEnv = "PMLSM_KEYSTORE";
/// --keystore value that keeps a participant open even when PMLSM_KEYSTORE is set.
inline constexpr const char* kNoKeystore = "none";

/// The keystore a --keystore value means: "none" -> "" (open, whatever the environment says);
/// "" -> $PMLSM_KEYSTORE ("" when unset); anything else itself.
std::string resolve_keystore(const std::string& option_value);

class Participant;

/// A process's one DDS participant: the Fast DDS DomainParticipant made from an XML profile (secure
/// when a keystore is given), its topics, and its ROS 2 graph announcement. A node alone in its
/// process has its own (made by its Participant); a container's components share the container's
/// (SharedParticipant), each with its own publisher, subscriber, writers and readers.
class ProcessParticipant {
 public:
  /// Authenticates as `identity` when options.keystore is set.
  /// @throws std::runtime_error naming the file or profile that failed; SecurityConfigError.
  ProcessParticipant(const ParticipantOptions& options, const std::string& identity);
  ~ProcessParticipant();
  ProcessParticipant(const ProcessParticipant&) = delete;
  ProcessParticipant& operator=(const ProcessParticipant&) = delete;

  eprosima::fastdds::dds::DomainParticipant* entity() { return participant_; }
  GraphAnnouncer& graph() { return *graph_; }
  /// The topic `name`, made on first use with `type` (registered under ROS 2's name for it when
  /// ros2_name). Thread-safe: components are made one after the other, tools may read meanwhile.
  eprosima::fastdds::dds::Topic* topic(const std::string& name,
                                       const std::function<eprosima::fastdds::dds::TypeSupport()>& type,
                                       bool ros2_name);
  const std::string& identity() const { return identity_; }

 private:
  eprosima::fastdds::dds::DomainParticipant* participant_ = nullptr;
  eprosima::fastdds::dds::Publisher* graph_publisher_ = nullptr;
  std::unique_ptr<GraphAnnouncer> graph_;
  std::string identity_;
  std::mutex mutex_;
  std::map<std::string, eprosima::fastdds::dds::Topic*> topics_;
};

/// A container's participant, made by the first component that asks for one, with its options;
/// every later component must ask for the same domain, profiles, keystore and data-sharing (a
/// container is one process on one domain). Secure, it authenticates as the container's identity,
/// whose permissions are the union of its components' (configs/security/policy.yaml, containers:);
/// each component is still held to its own identity's grant when it makes an endpoint.
class SharedParticipant {
 public:
  /// `name`: the participant's name on the domain (the container's); `identity`: the keystore
  /// identity it authenticates as when secure.
  SharedParticipant(std::string name, std::string identity) : name_(std::move(name)), identity_(std::move(identity)) {}
  /// The participant for a component with `options`. @throws std::invalid_argument naming the
  /// option that differs from the first component's; as ProcessParticipant's constructor.
  std::shared_ptr<ProcessParticipant> get(const ParticipantOptions& options);

 private:
  std::string name_;
  std::string identity_;
  ParticipantOptions first_;
  std::shared_ptr<ProcessParticipant> participant_;
};

/// CLOCK_MONOTONIC in ns (pmlsm/util/clock.hpp's, without pulling it into every node).
std::int64_t monotonic_ns_now();

template <typename PubSubType>
class Writer {
 public:
  using Message = typename PubSubType::type;
  /// @return false when Fast DDS refuses the sample (counted by the caller). In a realtime
  /// container a sample for readers outside the process is queued for the publisher thread
  /// (outbox.hpp) and true is returned: what happens to it later is counted there.
  bool write(const Message& sample) {
    if (local_ != nullptr) {
      local_->deliver(sample, guid_);
      // DDS only for readers outside the process, or for state a late joiner must get.
      if (!keeps_state_ && remote_->count() == 0) return true;
      if (outbox_ != nullptr) {
        outbox_->push(sample);
        return true;
      }
      if (pace_ && ++since_paced_ >= kPaceEvery) {
        since_paced_ = 0;
        wait_for_acknowledgments(kPaceTimeout);
      }
    }
    return writer_->write(const_cast<Message*>(&sample));
  }
  eprosima::fastdds::dds::DataWriter* entity() { return writer_; }
  /// Blocks until every matched reliable reader acknowledged all samples (in a realtime
  /// container: first until the publisher thread handed them all to DDS), or the timeout passes.
  /// Call before exiting: a writer deleted with samples still unacknowledged takes them with it
  /// (the last tick's command, say). After a stop request the wait ends by the stop's grace
  /// (shutdown.hpp), whatever the timeout: a reader that never acknowledges does not hold it.
  bool wait_for_acknowledgments(std::chrono::duration<double> timeout) {
    const std::int64_t deadline =
        within_stop_grace(monotonic_ns_now() + std::chrono::duration_cast<std::chrono::nanoseconds>(timeout).count());
    const bool cooperative = scheduler_ != nullptr && scheduler_->on_scheduler_thread();
    // Waits in slices: in a container the other components run between; alone, a stop request
    // arriving meanwhile is seen.
    const std::int64_t slice_ns = cooperative ? 200000 : 20000000;
    for (;;) {
      const bool queued = outbox_ != nullptr && outbox_->pending() > 0;
      if (!queued && writer_->wait_for_acknowledgments(
                         eprosima::fastrtps::Duration_t(0, cooperative ? 0U : static_cast<std::uint32_t>(slice_ns))) ==
                         eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
        return true;
      }
      const std::int64_t now = monotonic_ns_now();
      const std::int64_t cut = within_stop_grace(deadline);  // a stop may have come meanwhile
      if (now >= cut) return false;
      if (cooperative) {
        scheduler_->sleep_until(std::min(cut, now + slice_ns));
      } else if (queued) {
        std::this_thread::sleep_for(std::chrono::nanoseconds(std::min(cut - now, slice_ns)));
      }
    }
  }
  /// Number of matched readers, for waiting on discovery.
  std::size_t matched_readers() const;

 private:
  friend class Participant;
  explicit Writer(eprosima::fastdds::dds::DataWriter* writer) : writer_(writer) {}
  eprosima::fastdds::dds::DataWriter* writer_;
  // In a container:
  /// Lockstep pacing: every this many samples to DDS, wait until the readers outside acknowledged
  /// all (far below the writers' history of 4096, so none is dropped unacknowledged).
  static constexpr unsigned kPaceEvery = 256;
  /// A reader outside that stops acknowledging (a tool gone without its participant being
  /// removed, held until its lease ends: 10 s for @foxglove/rtps) holds a pace this long at most,
  /// well below the peers' timeout (10 s by default), which would otherwise end the run first.
  static constexpr std::chrono::seconds kPaceTimeout{2};
  bool pace_ = false;
  unsigned since_paced_ = 0;
  LocalTopic<Message>* local_ = nullptr;
  RemoteReaders* remote_ = nullptr;
  /// Realtime: the publisher thread's queue for readers outside (nullptr in lockstep).
  OutboxChannel<Message>* outbox_ = nullptr;
  FiberScheduler* scheduler_ = nullptr;
  Guid guid_;
  bool keeps_state_ = false;
};

template <typename PubSubType>
class Reader {
 public:
  using Message = typename PubSubType::type;
  /// Takes the next valid sample, if any, without blocking. In a container, samples of writers
  /// in the process come from the local queue; DDS brings those of writers outside (and copies
  /// of the local ones while a reader outside makes the local writers write to DDS: dropped).
  bool take(Message& out) {
    eprosima::fastdds::dds::SampleInfo info;
    return take(out, info);
  }
  /// As take(), with the sample's info (source and reception times, writer and sequence number).
  bool take(Message& out, eprosima::fastdds::dds::SampleInfo& info) {
    if (local_ == nullptr) return take_from_dds(out, info);
    // DDS only when its listener said something came: an empty DDS take costs locks every tick.
    if (dds_pending_->exchange(false, std::memory_order_acq_rel)) dds_backlog_ = true;
    if (dds_backlog_) {
      if (take_from_dds(out, info)) return true;
      dds_backlog_ = false;
    }
    return local_->pop(out, &info);
  }
  std::size_t matched_writers() const;
  eprosima::fastdds::dds::DataReader* entity() { return reader_; }

 private:
  friend class Participant;
  explicit Reader(eprosima::fastdds::dds::DataReader* reader) : reader_(reader) {}
  bool take_from_dds(Message& out, eprosima::fastdds::dds::SampleInfo& info) {
    while (reader_->take_next_sample(&out, &info) == eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      // A writer of this process: the queue had the sample already.
      if (topic_ != nullptr && topic_->is_local_writer(info.sample_identity.writer_guid())) continue;
      return true;
    }
    return false;
  }
  eprosima::fastdds::dds::DataReader* reader_;
  // In a container:
  LocalQueue<Message>* local_ = nullptr;
  const LocalTopicBase* topic_ = nullptr;
  std::atomic<bool>* dds_pending_ = nullptr;  ///< set by the DDS reader's listener on every arrival
  bool dds_backlog_ = true;                   ///< DDS may hold samples: drain before the queue
};

class Participant {
 public:
  /// Loads the XML profiles and creates the participant.
  /// @throws std::runtime_error naming the file or profile that failed.
  explicit Participant(const ParticipantOptions& options);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  /// The type is the topic's (topics.hpp).
  template <typename PubSubType>
  Writer<PubSubType> make_writer(const Topic<PubSubType>& spec) {
    using Message = typename PubSubType::type;
    if (local_bus_ == nullptr) return Writer<PubSubType>(create_writer(topic_for<PubSubType>(spec), spec.qos_profile));
    // The listener must be there from the start: it counts the readers outside the process.
    LocalTopic<Message>& local = local_bus_->topic<Message>(spec.name);
    RemoteReaders& remote = local_bus_->track_writer(this, local);
    auto* entity = create_writer(topic_for<PubSubType>(spec), spec.qos_profile, &remote);
    Writer<PubSubType> writer(entity);
    writer.local_ = &local;
    writer.guid_ = entity->guid();
    local_bus_->add_writer(remote, writer.guid_);
    writer.remote_ = &remote;
    writer.scheduler_ = &local_bus_->scheduler();
    writer.keeps_state_ = keeps_state(entity);
    writer.pace_ = pace_remote_readers_;
    // Realtime (not paced): the chain hands what leaves the process to the publisher thread.
    if (!pace_remote_readers_ && local_bus_->outbox().enabled())
      writer.outbox_ = &local_bus_->outbox().add<Message>(this, spec.name, entity);
    return writer;
  }

  /// The reader's listener notifies `wakeup` on every arrival. `qos_profile`
  /// replaces the topic's own, e.g. the deep observer profile for a monitor.
  template <typename PubSubType>
  Reader<PubSubType> make_reader(const Topic<PubSubType>& spec, Wakeup& wakeup, const char* qos_profile = nullptr) {
    using Message = typename PubSubType::type;
    Reader<PubSubType> reader(
        create_reader(topic_for<PubSubType>(spec), qos_profile != nullptr ? qos_profile : spec.qos_profile, wakeup));
    if (local_bus_ != nullptr) {
      LocalTopic<Message>& local = local_bus_->topic<Message>(spec.name);
      const QueueShape shape = queue_shape(reader.entity());
      reader.local_ =
          &local_bus_->add_reader(this, local, reader.entity()->guid(), shape.capacity, shape.keep_all, wakeup);
      reader.topic_ = &local;
      reader.dds_pending_ = &last_arrival_flag();
    }
    return reader;
  }

  /// Endpoints that carry serialized samples of a catalog topic (recorder, player, bridge).
  /// `qos_profile` as for make_reader(); nullptr = the topic's own.
  Reader<RawPubSubType> make_raw_reader(const CatalogEntry& entry, Wakeup& wakeup, const char* qos_profile = nullptr);
  Writer<RawPubSubType> make_raw_writer(const CatalogEntry& entry, const char* qos_profile = nullptr);

  /// Deletes a reader made by this participant, and its listener (a bridge opens and closes
  /// readers as viewers come and go). @throws std::runtime_error when Fast DDS refuses.
  template <typename PubSubType>
  void delete_reader(Reader<PubSubType>& reader) {
    delete_reader_entity(reader.entity());
  }

  /// The process's DDS participant (shared with the other components in a container).
  eprosima::fastdds::dds::DomainParticipant* entity() { return process_->entity(); }
  const std::string& node_name() const { return node_name_; }
  /// The node's identity (alone: the one its participant authenticated as; in a container, the
  /// one whose grant its endpoints are held to); empty for an open participant.
  const std::string& identity() const { return identity_; }

 private:
  class NotifyingListener;

  template <typename PubSubType>
  eprosima::fastdds::dds::Topic* topic_for(const TopicSpec& spec) {
    // TypeSupport owns what it is given.
    return process_->topic(
        spec.name, [] { return eprosima::fastdds::dds::TypeSupport(new PubSubType()); }, /*ros2_name=*/true);
  }
  /// In a secure container: whether the node's own identity grants `role` ("publish",
  /// "subscribe") on `topic` (its permissions file, read once); alone, DDS itself checks.
  void check_grant(const char* role, const std::string& topic) const;
  bool grants(const char* role, const std::string& topic) const;
  eprosima::fastdds::dds::DataWriter* create_writer(eprosima::fastdds::dds::Topic* topic, const std::string& profile,
                                                    eprosima::fastdds::dds::DataWriterListener* listener = nullptr);
  /// TRANSIENT_LOCAL with a history of one: the newest sample is state a late joiner must get.
  static bool keeps_state(eprosima::fastdds::dds::DataWriter* writer);
  struct QueueShape {
    std::size_t capacity;
    bool keep_all;
  };
  /// The flag the listener of the reader made last sets on every arrival.
  std::atomic<bool>& last_arrival_flag();
  /// A local queue as deep as the reader's history QoS.
  static QueueShape queue_shape(eprosima::fastdds::dds::DataReader* reader);
  eprosima::fastdds::dds::DataReader* create_reader(eprosima::fastdds::dds::Topic* topic, const std::string& profile,
                                                    Wakeup& wakeup);
  void delete_reader_entity(eprosima::fastdds::dds::DataReader* reader);

  /// Why Fast DDS may have refused an entity: with security, the identity's permissions.
  std::string refusal_hint(const char* what, const std::string& topic) const;

  std::string node_name_;
  std::string identity_;
  std::string keystore_;
  bool data_sharing_ = false;
  std::shared_ptr<ProcessParticipant> process_;
  /// In a secure container, what the node's own identity grants (DDS topic names).
  std::vector<std::string> granted_publish_;
  std::vector<std::string> granted_subscribe_;
  bool held_to_grant_ = false;
  eprosima::fastdds::dds::Publisher* publisher_ = nullptr;
  eprosima::fastdds::dds::Subscriber* subscriber_ = nullptr;
  std::vector<std::unique_ptr<NotifyingListener>> listeners_;
  /// This node on the process's ros_discovery_info.
  int graph_node_ = -1;
  /// The container's in-process path; it owns this participant's local endpoints until the
  /// participant is destroyed.
  LocalBus* local_bus_ = nullptr;
  bool pace_remote_readers_ = false;
};

template <typename PubSubType>
std::size_t Writer<PubSubType>::matched_readers() const {
  eprosima::fastdds::dds::PublicationMatchedStatus status;
  writer_->get_publication_matched_status(status);
  return static_cast<std::size_t>(status.current_count);
}

template <typename PubSubType>
std::size_t Reader<PubSubType>::matched_writers() const {
  eprosima::fastdds::dds::SubscriptionMatchedStatus status;
  reader_->get_subscription_matched_status(status);
  return static_cast<std::size_t>(status.current_count);
}

}  // namespace pmlsm::dds
