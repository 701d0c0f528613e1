// The in-process path between the components of one container.
//
// Every component keeps its own participant, writers and readers on DDS (its identity, its
// permissions, its place in discovery), and the container adds a LocalBus beside them: a
// sample a component writes is copied straight into the queue of every reader of that topic
// in the same process, whose Wakeup is signalled; no serialisation, no socket, no
// acknowledgement, no system call. The writer hands the sample to DDS only when a reader
// outside the process is matched (a recorder, the Foxglove bridge, a node on another host),
// or when the topic keeps its newest sample as state for late joiners (TRANSIENT_LOCAL with a
// history of one: DriveState, NetworkWeights). A reader drops what arrives over DDS from a
// writer of its own process: it had that sample from the queue already.
//
// Each topic keeps its semantics in the queue: the reader's history QoS sets its capacity;
// KEEP_LAST overwrites the oldest sample when full, KEEP_ALL refuses the newest (both
// counted, as DDS would drop or refuse them); samples arrive in the order they were written.
// A local reader made after a sample was written does not get it (in a container every
// component is made before any runs).
//
// Threads: deliveries, takes and (un)registrations happen on the container's chain thread;
// Fast DDS's threads only report matches to the remote-reader count, under its own lock.
#pragma once

#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/rtps/common/Guid.h>
#include <fastdds/rtps/common/InstanceHandle.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <typeinfo>
#include <vector>

#include "pmlsm/dds/fiber_scheduler.hpp"
#include "pmlsm/dds/outbox.hpp"

namespace pmlsm::dds {

class Wakeup;
using Guid = eprosima::fastrtps::rtps::GUID_t;

/// Signals a Wakeup (defined in participant.cpp, which knows Wakeup).
void notify_wakeup(Wakeup& wakeup);
/// Wall-clock time as Fast DDS stamps samples.
eprosima::fastrtps::rtps::Time_t wall_clock_now();

/// Samples a topic's in-process readers lost, over the container's run (the queues of
/// components that ended included).
struct LocalLosses {
  std::uint64_t overwritten = 0;  ///< KEEP_LAST: the oldest sample made room for a new one
  std::uint64_t refused = 0;      ///< KEEP_ALL: the newest sample did not fit
};

/// What a topic's local endpoints share, whatever the message type.
class LocalTopicBase {
 public:
  LocalTopicBase(std::string name, const std::type_info& type) : name_(std::move(name)), type_(type) {}
  virtual ~LocalTopicBase() = default;
  const std::string& name() const { return name_; }
  const std::type_info& type() const { return type_; }

  /// True when `writer` is a writer of this topic in this process. (Its samples reach this
  /// process's readers through their queues.)
  bool is_local_writer(const Guid& writer) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::find(writers_.begin(), writers_.end(), writer) != writers_.end();
  }
  bool is_local_reader(const eprosima::fastrtps::rtps::InstanceHandle_t& reader) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::find(reader_handles_.begin(), reader_handles_.end(), reader) != reader_handles_.end();
  }
  /// Counted on the chain thread by its queues.
  const LocalLosses& losses() const { return losses_; }

 protected:
  friend class LocalBus;
  friend class RemoteReaders;
  std::string name_;
  const std::type_info& type_;
  mutable std::mutex mutex_;  ///< guards the two lists below (Fast DDS's threads read them)
  std::vector<Guid> writers_;
  std::vector<eprosima::fastrtps::rtps::InstanceHandle_t> reader_handles_;
  LocalLosses losses_;
};

/// One in-process reader's queue: a ring of preallocated samples (no allocation per sample for
/// fixed-size messages) with their writer and times.
template <typename Message>
class LocalQueue {
 public:
  /// `topic_losses`: where the topic's losses are summed too (none: this queue's only).
  /// @throws std::invalid_argument for a capacity of 0.
  LocalQueue(std::size_t capacity, bool keep_all, Wakeup& wakeup, LocalLosses* topic_losses = nullptr)
      : slots_(capacity), keep_all_(keep_all), wakeup_(wakeup), topic_losses_(topic_losses) {
    if (capacity == 0) throw std::invalid_argument("LocalQueue: capacity must be at least 1");
  }

  void push(const Message& sample, const Guid& writer, const eprosima::fastrtps::rtps::Time_t& written) {
    if (size_ == slots_.size()) {
      if (keep_all_) {
        ++refused_;  // KEEP_ALL: the held samples stay, the newest is refused
        if (topic_losses_ != nullptr) ++topic_losses_->refused;
        return;
      }
      head_ = (head_ + 1) % slots_.size();  // KEEP_LAST: the oldest makes room
      --size_;
      ++overwritten_;
      if (topic_losses_ != nullptr) ++topic_losses_->overwritten;
    }
    Slot& slot = slots_[(head_ + size_) % slots_.size()];
    slot.sample = sample;
    slot.writer = writer;
    slot.written = written;
    ++size_;
    notify_wakeup(wakeup_);
  }

  /// The oldest sample, with an info as DDS would give it (valid, writer, times); false when empty.
  bool pop(Message& out, eprosima::fastdds::dds::SampleInfo* info) {
    if (size_ == 0) return false;
    Slot& slot = slots_[head_];
    out = slot.sample;
    if (info != nullptr) {
      info->valid_data = true;
      info->sample_identity.writer_guid(slot.writer);
      info->publication_handle = eprosima::fastrtps::rtps::InstanceHandle_t(slot.writer);
      info->source_timestamp = slot.written;
      info->reception_timestamp = slot.written;  // delivered as it was written
    }
    head_ = (head_ + 1) % slots_.size();
    --size_;
    return true;
  }

  std::uint64_t overwritten() const { return overwritten_; }
  std::uint64_t refused() const { return refused_; }

 private:
  struct Slot {
    Message sample;
    Guid writer;
    eprosima::fastrtps::rtps::Time_t written;
  };
  std::vector<Slot> slots_;
  bool keep_all_;
  Wakeup& wakeup_;
  LocalLosses* topic_losses_;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
  std::uint64_t overwritten_ = 0;
  std::uint64_t refused_ = 0;
};

template <typename Message>
class LocalTopic final : public LocalTopicBase {
 public:
  using LocalTopicBase::LocalTopicBase;

  /// Copies `sample` into every local reader's queue (the writing component's own readers of
  /// the topic included, as DDS delivers to them).
  void deliver(const Message& sample, const Guid& writer) {
    const auto now = wall_clock_now();
    for (LocalQueue<Message>* queue : queues_) queue->push(sample, writer, now);
  }

 private:
  friend class LocalBus;
  std::vector<LocalQueue<Message>*> queues_;
};

/// Counts the readers matched with one of a container's DDS writers that are not in the
/// container: the writer hands samples to DDS only while there is one. Fast DDS reports every
/// match and unmatch here (the writer's listener).
class RemoteReaders final : public eprosima::fastdds::dds::DataWriterListener {
 public:
  explicit RemoteReaders(const LocalTopicBase& topic) : topic_(topic) {}
  void on_publication_matched(eprosima::fastdds::dds::DataWriter*,
                              const eprosima::fastdds::dds::PublicationMatchedStatus& info) override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (info.current_count_change > 0) {
      matched_.push_back(info.last_subscription_handle);
    } else if (info.current_count_change < 0) {
      matched_.erase(std::remove(matched_.begin(), matched_.end(), info.last_subscription_handle), matched_.end());
    }
    recount_locked();
  }
  /// A local reader was added or removed: it may be among the matched ones.
  void recount() {
    std::lock_guard<std::mutex> lock(mutex_);
    recount_locked();
  }
  int count() const { return remote_.load(std::memory_order_acquire); }

 private:
  void recount_locked() {
    int remote = 0;
    for (const auto& handle : matched_) {
      if (!topic_.is_local_reader(handle)) ++remote;
    }
    remote_.store(remote, std::memory_order_release);
  }
  const LocalTopicBase& topic_;
  std::mutex mutex_;
  std::vector<eprosima::fastrtps::rtps::InstanceHandle_t> matched_;
  std::atomic<int> remote_{0};
};

/// A container's in-process topics. Endpoints are registered by the participants that own them
/// and removed with them (remove_owner), so a component that ends takes its queues along.
class LocalBus {
 public:
  /// `publish_period`: the outbox's (0: samples for readers outside written on the chain thread).
  explicit LocalBus(FiberScheduler& scheduler, std::chrono::microseconds publish_period = Outbox::kDefaultPeriod)
      : scheduler_(scheduler), outbox_(publish_period) {}
  LocalBus(const LocalBus&) = delete;
  LocalBus& operator=(const LocalBus&) = delete;

  FiberScheduler& scheduler() { return scheduler_; }
  /// The publisher thread of a realtime container (its thread starts with the first writer).
  Outbox& outbox() { return outbox_; }
  const Outbox& outbox() const { return outbox_; }

  /// The topic `name` carrying `Message`. @throws std::invalid_argument when the name is
  /// already used by another message type.
  template <typename Message>
  LocalTopic<Message>& topic(const std::string& name) {
    auto found = topics_.find(name);
    if (found == topics_.end()) {
      found = topics_.emplace(name, std::make_unique<LocalTopic<Message>>(name, typeid(Message))).first;
    }
    if (found->second->type() != typeid(Message)) {
      throw std::invalid_argument("local topic '" + name + "' carries " + found->second->type().name() + ", not " +
                                  typeid(Message).name());
    }
    return static_cast<LocalTopic<Message>&>(*found->second);
  }

  /// The remote-reader count of a writer about to be made on `topic` by `owner`: give it to
  /// the DDS writer as its listener (owned here, so it outlives the writer), then name the
  /// writer with add_writer().
  RemoteReaders& track_writer(const void* owner, LocalTopicBase& topic) {
    trackers_.push_back({owner, &topic, Guid(), std::make_unique<RemoteReaders>(topic)});
    return *trackers_.back().remote;
  }
  /// The writer counted by `tracker` exists with `guid`: its samples reach the local readers
  /// through their queues, so they drop its DDS copies.
  void add_writer(RemoteReaders& tracker, const Guid& guid) {
    for (auto& entry : trackers_) {
      if (entry.remote.get() != &tracker) continue;
      entry.guid = guid;
      std::lock_guard<std::mutex> lock(entry.topic->mutex_);
      entry.topic->writers_.push_back(guid);
      return;
    }
    throw std::logic_error("LocalBus::add_writer: unknown tracker");
  }

  /// A local reader of `topic` (its DDS reader's GUID) with a queue of `capacity` samples.
  template <typename Message>
  LocalQueue<Message>& add_reader(const void* owner, LocalTopic<Message>& topic, const Guid& guid, std::size_t capacity,
                                  bool keep_all, Wakeup& wakeup) {
    auto queue = std::make_unique<LocalQueue<Message>>(capacity, keep_all, wakeup, &topic.losses_);
    LocalQueue<Message>& ref = *queue;
    topic.queues_.push_back(&ref);
    {
      std::lock_guard<std::mutex> lock(topic.mutex_);
      topic.reader_handles_.push_back(eprosima::fastrtps::rtps::InstanceHandle_t(guid));
    }
    readers_.push_back({owner, &topic, guid, std::shared_ptr<void>(std::move(queue)), [&topic, &ref] {
                          topic.queues_.erase(std::remove(topic.queues_.begin(), topic.queues_.end(), &ref),
                                              topic.queues_.end());
                        }});
    recount(topic);
    return ref;
  }

  /// Removes every endpoint `owner` registered (a participant being destroyed).
  void remove_owner(const void* owner);

  /// Every topic whose in-process readers lost samples, by name, with its losses.
  std::vector<std::pair<std::string, LocalLosses>> losses() const {
    std::vector<std::pair<std::string, LocalLosses>> out;
    for (const auto& [name, topic] : topics_) {
      if (topic->losses().overwritten + topic->losses().refused > 0) out.emplace_back(name, topic->losses());
    }
    return out;
  }

 private:
  struct WriterEntry {
    const void* owner;
    LocalTopicBase* topic;
    Guid guid;
    std::unique_ptr<RemoteReaders> remote;
  };
  struct ReaderEntry {
    const void* owner;
    LocalTopicBase* topic;
    Guid guid;
    std::shared_ptr<void> queue;
    std::function<void()> detach;
  };
  void recount(const LocalTopicBase& topic);

  FiberScheduler& scheduler_;
  Outbox outbox_;
  std::map<std::string, std::unique_ptr<LocalTopicBase>> topics_;
  std::vector<WriterEntry> trackers_;
  std::vector<ReaderEntry> readers_;
};

}  // namespace pmlsm::dds
