// A realtime container's publisher thread: what the chain writes for readers outside the
// process goes through here, so the chain thread never calls into Fast DDS for them (no
// serialisation, no socket, no writer lock shared with Fast DDS's own threads).
//
// Each DDS writer of a component gets a channel: a DropOldestRing the chain thread pushes into
// (never waits; a full ring drops the oldest sample, counted per topic) and this thread drains,
// writing each sample to the DDS writer. The thread wakes every `period` (polling: a wake-up
// signalled by the chain would be a system call on it), and while nothing comes it wakes less
// often, up to every kIdlePeriod (a run nobody outside listens to costs no wake-ups a tick); the
// in-process path is not touched.
//
// Lockstep containers do not use it: there a writer paces itself to its outside readers so that
// they see every tick (local_bus.hpp), and nothing runs against a clock.
//
// Threads: add() and remove_owner() on the chain thread (or before it runs), push() on the chain
// thread, drain on the outbox's own thread; totals() after the run, from any thread.
#pragma once

#include <fastdds/dds/publisher/DataWriter.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "pmlsm/dds/fiber_scheduler.hpp"
#include "pmlsm/util/drop_oldest_ring.hpp"

namespace pmlsm::dds {

/// What one topic's outside readers were sent through the outbox over the run (every writer of
/// the topic in the process summed).
struct OutboxCounts {
  std::uint64_t queued = 0;       ///< handed over by the chain
  std::uint64_t published = 0;    ///< written to DDS
  std::uint64_t dropped = 0;      ///< the queue was full: the oldest went (or, rarely, the newest)
  std::uint64_t refused = 0;      ///< Fast DDS refused the write
  std::uint64_t undelivered = 0;  ///< still queued when the writer was closed (its drain deadline passed)
  std::uint64_t lost() const { return dropped + refused + undelivered; }
};

class OutboxChannelBase {
 public:
  OutboxChannelBase(const void* owner, std::string topic) : owner_(owner), topic_(std::move(topic)) {}
  virtual ~OutboxChannelBase() = default;
  /// Writes everything queued to DDS (the outbox's thread); how many samples it wrote.
  virtual std::size_t drain() = 0;
  virtual std::uint64_t pending() const = 0;
  /// The channel's counts so far.
  virtual OutboxCounts counts() const = 0;
  const void* owner() const { return owner_; }
  const std::string& topic() const { return topic_; }

 private:
  const void* owner_;
  std::string topic_;
};

template <typename Message>
class OutboxChannel final : public OutboxChannelBase {
 public:
  OutboxChannel(const void* owner, std::string topic, eprosima::fastdds::dds::DataWriter* writer, std::size_t capacity)
      : OutboxChannelBase(owner, std::move(topic)), ring_(capacity), writer_(writer) {}
  /// The chain thread: never blocks, never calls Fast DDS.
  void push(const Message& sample) { ring_.push(sample); }
  std::size_t drain() override {
    std::size_t n = 0;
    for (; ring_.pop(scratch_); ++n) {
      if (writer_->write(&scratch_)) {
        published_.fetch_add(1, std::memory_order_relaxed);
      } else {
        refused_.fetch_add(1, std::memory_order_relaxed);
      }
    }
    return n;
  }
  std::uint64_t pending() const override { return ring_.pending(); }
  OutboxCounts counts() const override {
    OutboxCounts c;
    c.queued = ring_.pushed() + ring_.dropped_busy();
    c.published = published_.load(std::memory_order_relaxed);
    c.refused = refused_.load(std::memory_order_relaxed);
    c.dropped = ring_.overwritten() + ring_.dropped_busy();
    return c;
  }

 private:
  DropOldestRing<Message> ring_;
  Message scratch_;  ///< the outbox thread's copy of the sample it writes
  eprosima::fastdds::dds::DataWriter* writer_;
  std::atomic<std::uint64_t> published_{0};
  std::atomic<std::uint64_t> refused_{0};
};

class Outbox {
 public:
  /// Samples a channel holds: at 1 kHz a quarter of a second of a stalled network.
  static constexpr std::size_t kDefaultCapacity = 256;
  /// How long closing a writer waits for its queue to go out before counting the rest as
  /// undelivered.
  static constexpr std::chrono::milliseconds kCloseDrain{200};
  /// The longest sleep while nothing is queued: the first sample after a quiet spell waits at most
  /// this long, those after it one period.
  static constexpr std::chrono::milliseconds kIdlePeriod{4};

  static constexpr std::chrono::microseconds kDefaultPeriod{250};
  /// A period of 0 turns the outbox off: writers hand samples to DDS on the chain thread, as a
  /// lockstep container does (kept to compare against). @throws std::invalid_argument for a
  /// period outside 10 us .. 100 ms (0 apart).
  explicit Outbox(std::chrono::microseconds period = kDefaultPeriod);
  bool enabled() const { return period_.count() > 0; }
  ~Outbox();
  Outbox(const Outbox&) = delete;
  Outbox& operator=(const Outbox&) = delete;

  /// A channel for `writer` (of `owner`, a participant), drained to it from the next period on.
  /// Starts the thread with the first channel. @throws std::logic_error when not enabled().
  template <typename Message>
  OutboxChannel<Message>& add(const void* owner, const std::string& topic, eprosima::fastdds::dds::DataWriter* writer,
                              std::size_t capacity = kDefaultCapacity) {
    if (!enabled()) throw std::logic_error("Outbox::add: the outbox is off (period 0)");
    auto channel = std::make_unique<OutboxChannel<Message>>(owner, topic, writer, capacity);
    OutboxChannel<Message>& ref = *channel;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      channels_.push_back(std::move(channel));
    }
    start();
    return ref;
  }

  /// Closes `owner`'s channels before its writers are deleted: waits up to kCloseDrain for their
  /// queues to go out (in a fiber of `scheduler`, sleeping cooperatively), counts what is left as
  /// undelivered, and removes them once the thread is between drains.
  void remove_owner(const void* owner, FiberScheduler* scheduler);

  /// Waits until `channel` has nothing queued or `deadline_ns` (CLOCK_MONOTONIC) passes. False on
  /// the deadline.
  bool wait_drained(const OutboxChannelBase& channel, std::int64_t deadline_ns, FiberScheduler* scheduler) const;

  /// Per topic, over the run: channels removed and those still open.
  std::map<std::string, OutboxCounts> totals() const;

 private:
  void start();
  void loop();

  std::chrono::microseconds period_;
  mutable std::mutex mutex_;  ///< the channel list; held by the thread while it drains
  std::vector<std::unique_ptr<OutboxChannelBase>> channels_;
  std::map<std::string, OutboxCounts> closed_;  ///< counts of removed channels, by topic
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace pmlsm::dds
