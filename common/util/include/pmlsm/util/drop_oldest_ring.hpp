// A bounded single-producer single-consumer queue that never makes its producer wait: when it is
// full, the newest sample takes the place of the oldest unread one (counted), as a KEEP_LAST
// history does. The producer is a control loop handing observation samples to a publisher
// thread (realtime_tools' RealtimePublisher idea, without its try-lock that skips the newest).
//
// Lock-free: each slot has a state word, and whoever moves it out of kFull (the producer to
// overwrite, the consumer to copy out) owns the slot's value until it puts a state back, so a
// value is never read while it is written, whatever the type. The producer never spins and never
// waits: the one case it cannot write (the consumer is copying out exactly the slot it wants,
// which needs the queue to have wrapped round during that copy) drops the new sample instead,
// counted apart. No allocation after construction (a value type that allocates on copy does so
// only until its capacity is reached).
//
// Every sample pushed is, in the end, exactly one of: popped, overwritten, dropped busy, or still
// queued (the tests hold the queue to that).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace pmlsm {

template <typename T>
class DropOldestRing {
 public:
  enum class Push {
    kQueued,       ///< in the queue, nothing lost
    kOverwrote,    ///< in the queue; the oldest unread sample was dropped to make room
    kDroppedBusy,  ///< not queued: the consumer was copying out the slot it needed
  };

  /// @throws std::invalid_argument for a capacity under 2.
  explicit DropOldestRing(std::size_t capacity) : slots_(capacity) {
    if (capacity < 2) {
      throw std::invalid_argument("DropOldestRing: capacity must be at least 2, got " + std::to_string(capacity));
    }
  }
  DropOldestRing(const DropOldestRing&) = delete;
  DropOldestRing& operator=(const DropOldestRing&) = delete;

  /// Producer thread only. Never blocks.
  Push push(const T& value) {
    const std::uint64_t w = written_.load(std::memory_order_relaxed);
    Slot& slot = slots_[w % slots_.size()];
    std::uint32_t state = slot.state.load(std::memory_order_acquire);
    if (state == kReading || !slot.state.compare_exchange_strong(state, kWriting, std::memory_order_acq_rel)) {
      dropped_busy_.fetch_add(1, std::memory_order_relaxed);
      return Push::kDroppedBusy;
    }
    slot.value = value;
    slot.seq = w;
    slot.state.store(kFull, std::memory_order_release);
    written_.store(w + 1, std::memory_order_release);
    if (state == kFull) {
      overwritten_.fetch_add(1, std::memory_order_relaxed);
      return Push::kOverwrote;
    }
    return Push::kQueued;
  }

  /// Consumer thread only: the oldest sample still queued, false when there is none.
  bool pop(T& out) {
    const std::uint64_t n = slots_.size();
    for (;;) {
      const std::uint64_t w = written_.load(std::memory_order_acquire);
      if (read_ + n < w) read_ = w - n;  // the ones before were overwritten (counted by the producer)
      if (read_ >= w) return false;
      Slot& slot = slots_[read_ % n];
      std::uint32_t state = kFull;
      if (!slot.state.compare_exchange_strong(state, kReading, std::memory_order_acq_rel)) {
        // kWriting: the producer is putting sample read_ + n there, read_ is lost. (kEmpty cannot
        // be seen for an unread index; stepping on keeps the loop finite whatever happens.)
        ++read_;
        continue;
      }
      if (slot.seq != read_) {
        // Overwritten before the claim: it holds a newer sample; the oldest left is the one after
        // the slot's previous round.
        const std::uint64_t newer = slot.seq;
        slot.state.store(kFull, std::memory_order_release);
        read_ = newer + 1 - n;
        continue;
      }
      out = slot.value;
      slot.state.store(kEmpty, std::memory_order_release);
      ++read_;
      popped_.fetch_add(1, std::memory_order_relaxed);
      return true;
    }
  }

  std::size_t capacity() const { return slots_.size(); }
  /// Samples queued (overwritten ones included), popped, dropped; any thread (a moment's view).
  std::uint64_t pushed() const { return written_.load(std::memory_order_acquire); }
  std::uint64_t popped() const { return popped_.load(std::memory_order_relaxed); }
  std::uint64_t overwritten() const { return overwritten_.load(std::memory_order_relaxed); }
  std::uint64_t dropped_busy() const { return dropped_busy_.load(std::memory_order_relaxed); }
  /// Samples still queued (pushed, neither popped nor overwritten); any thread (a moment's view).
  std::uint64_t pending() const {
    const std::uint64_t done = popped() + overwritten();
    const std::uint64_t all = pushed();
    return all > done ? all - done : 0;
  }

 private:
  static constexpr std::uint32_t kEmpty = 0;
  static constexpr std::uint32_t kFull = 1;
  static constexpr std::uint32_t kReading = 2;
  static constexpr std::uint32_t kWriting = 3;
  struct Slot {
    std::atomic<std::uint32_t> state{kEmpty};
    std::uint64_t seq = 0;
    T value{};
  };
  std::vector<Slot> slots_;
  alignas(64) std::atomic<std::uint64_t> written_{0};  ///< the next sample's index (producer)
  std::atomic<std::uint64_t> overwritten_{0};
  std::atomic<std::uint64_t> dropped_busy_{0};
  alignas(64) std::uint64_t read_ = 0;  ///< the next index the consumer looks for (consumer only)
  std::atomic<std::uint64_t> popped_{0};
};

}  // namespace pmlsm
