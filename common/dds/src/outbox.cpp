#include "pmlsm/dds/outbox.hpp"

#include <algorithm>
#include <stdexcept>

#include "pmlsm/util/clock.hpp"

namespace pmlsm::dds {

namespace {

/// Empty passes in a row before the outbox sleeps longer.
constexpr int kQuietPasses = 20;

void add_counts(OutboxCounts& sum, const OutboxCounts& c) {
  sum.queued += c.queued;
  sum.published += c.published;
  sum.dropped += c.dropped;
  sum.refused += c.refused;
  sum.undelivered += c.undelivered;
}

/// Sleeps until `ns`: cooperatively in a fiber of `scheduler`, else the thread.
void sleep_until(std::int64_t ns, FiberScheduler* scheduler) {
  if (scheduler != nullptr && scheduler->on_scheduler_thread()) {
    scheduler->sleep_until(ns);
  } else {
    sleep_until_monotonic_ns(ns);
  }
}

}  // namespace

Outbox::Outbox(std::chrono::microseconds period) : period_(period) {
  if (period.count() != 0 && (period < std::chrono::microseconds(10) || period > std::chrono::milliseconds(100))) {
    throw std::invalid_argument("Outbox: period must be 0 (off) or 10 us .. 100 ms, got " +
                                std::to_string(period.count()) + " us");
  }
}

Outbox::~Outbox() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void Outbox::start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] { loop(); });
}

void Outbox::loop() {
  std::int64_t next = monotonic_ns();
  const std::int64_t period_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(period_).count();
  const std::int64_t idle_ns =
      std::max(period_ns, std::chrono::duration_cast<std::chrono::nanoseconds>(kIdlePeriod).count());
  std::int64_t sleep_ns = period_ns;
  int quiet_passes = 0;
  while (!stop_.load(std::memory_order_acquire)) {
    std::size_t written = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (auto& channel : channels_) written += channel->drain();
    }
    // Traffic (a 1 kHz stream leaves no 20 passes in a row empty): every period. A quiet spell:
    // twice as long each pass, up to idle_ns; the first sample after it starts the period again.
    quiet_passes = written > 0 ? 0 : quiet_passes + 1;
    sleep_ns = quiet_passes <= kQuietPasses ? period_ns : std::min(idle_ns, 2 * sleep_ns);
    // A fixed grid; after a stall, the next slot from now (no burst of catch-up wake-ups).
    next += sleep_ns;
    const std::int64_t now = monotonic_ns();
    if (next < now) next = now + sleep_ns;
    sleep_until_monotonic_ns(next);
  }
}

bool Outbox::wait_drained(const OutboxChannelBase& channel, std::int64_t deadline_ns, FiberScheduler* scheduler) const {
  const std::int64_t step_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(period_).count();
  for (;;) {
    if (channel.pending() == 0) return true;
    const std::int64_t now = monotonic_ns();
    if (now >= deadline_ns) return false;
    sleep_until(std::min(deadline_ns, now + step_ns), scheduler);
  }
}

void Outbox::remove_owner(const void* owner, FiberScheduler* scheduler) {
  const std::int64_t deadline =
      monotonic_ns() + std::chrono::duration_cast<std::chrono::nanoseconds>(kCloseDrain).count();
  std::vector<const OutboxChannelBase*> mine;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& c : channels_) {
      if (c->owner() == owner) mine.push_back(c.get());
    }
  }
  if (mine.empty()) return;
  for (const auto* c : mine) wait_drained(*c, deadline, scheduler);
  // Between drains only: the thread must not write to a writer about to be deleted. The thread
  // holds the lock for one pass over the channels at a time, so this wait is short; in a fiber
  // it sleeps instead of blocking the chain thread.
  std::unique_lock<std::mutex> lock(mutex_, std::defer_lock);
  while (!lock.try_lock()) sleep_until(monotonic_ns() + 50000, scheduler);
  for (auto it = channels_.begin(); it != channels_.end();) {
    if ((*it)->owner() != owner) {
      ++it;
      continue;
    }
    OutboxCounts c = (*it)->counts();
    c.undelivered = (*it)->pending();
    add_counts(closed_[(*it)->topic()], c);
    it = channels_.erase(it);
  }
}

std::map<std::string, OutboxCounts> Outbox::totals() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::map<std::string, OutboxCounts> out = closed_;
  for (const auto& c : channels_) {
    OutboxCounts open = c->counts();
    open.undelivered = c->pending();
    add_counts(out[c->topic()], open);
  }
  return out;
}

}  // namespace pmlsm::dds
