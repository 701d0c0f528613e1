#include "pmlsm/drive/drive_loop.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace pmlsm::drive {
namespace {

std::int64_t to_ns(double seconds) { return static_cast<std::int64_t>(std::llround(seconds * 1e9)); }

void require_positive(const char* name, double value) {
  if (!(std::isfinite(value) && value > 0.0)) {
    throw std::invalid_argument(std::string(name) + ": must be finite and > 0, got " + std::to_string(value));
  }
}

}  // namespace

const char* to_string(Verdict verdict) noexcept {
  switch (verdict) {
    case Verdict::kAccepted: return "accepted";
    case Verdict::kStale: return "stale";
    case Verdict::kFutureTick: return "future tick";
    case Verdict::kNonFinite: return "non-finite force";
    case Verdict::kOtherRun: return "another run";
    case Verdict::kForeignWriter: return "foreign writer";
  }
  return "unknown";
}

void DriveLoopParams::validate() const {
  require_positive("period_s", period_s);
  require_positive("watchdog_s", watchdog_s);
  require_positive("controller_lost_s", controller_lost_s);
  require_positive("first_command_timeout_s", first_command_timeout_s);
  if (watchdog_arm_ticks < 1) throw std::invalid_argument("watchdog_arm_ticks: must be >= 1, got 0");
  if (watchdog_s < period_s) {
    throw std::invalid_argument("watchdog_s: must be at least one period (" + std::to_string(period_s) + " s), got " +
                                std::to_string(watchdog_s));
  }
}

DriveLoop::DriveLoop(const DriveLoopParams& params, Drive& drive)
    : params_((params.validate(), params)),
      drive_(drive),
      statistics_(params.expected_ticks),
      published_wall_ns_(kRing, 0),
      published_mono_ns_(kRing, 0),
      watchdog_ticks_(std::max<std::uint64_t>(
          1, static_cast<std::uint64_t>(std::floor(params.watchdog_s / params.period_s + 1e-9)))) {}

void DriveLoop::track_power_state(std::int64_t now_mono_ns) {
  const bool enabled = drive_.power_state() == PowerState::kOperationEnabled;
  if (enabled && !was_enabled_) {
    // Entered operation enabled: a fresh start for the watchdog, ownership and liveness.
    ever_enabled_ = true;
    armed_ = false;
    consecutive_fresh_ = 0;
    owner_set_ = false;
    watchdog_latched_ = false;
    lost_reported_ = false;
    last_accept_mono_ns_ = now_mono_ns;
  }
  if (!enabled && was_enabled_) {
    armed_ = false;
    owner_set_ = false;
  }
  was_enabled_ = enabled;
}

void DriveLoop::check_watchdog(std::int64_t now_mono_ns, bool at_tick_start) {
  if (!params_.realtime || !armed_ || drive_.power_state() != PowerState::kOperationEnabled) return;
  if (any_stall_ && tick_ <= grace_until_tick_) return;
  // The oldest unanswered feedback: tick applied + 1, never before arming, and within the ring
  // of remembered publish times (beyond it the oldest remembered, which is younger: the trip
  // comes no earlier). At a tick's start the current tick is not published yet.
  const std::uint64_t newest_published = published_this_tick_ ? tick_ : tick_ - 1;
  if (tick_ == 0 && !published_this_tick_) return;
  const std::uint64_t ring_start = newest_published + 1 >= kRing ? newest_published + 1 - kRing : 0;
  const std::uint64_t oldest = std::max({applied_tick_ + 1, arm_tick_, ring_start});
  if (oldest > newest_published) return;
  // At a tick's start the deadline counts in ticks (the feedback of tick n is due answered
  // before tick n + watchdog / period starts: publish times and wake-ups jitter alike, and a
  // comparison of the two against exactly 3 ms would miss every other time); after the command
  // deadline, in time since the feedback was published.
  const bool overdue = at_tick_start ? tick_ - oldest >= watchdog_ticks_
                                     : now_mono_ns - published_mono_ns_[oldest % kRing] >= to_ns(params_.watchdog_s);
  if (!overdue) return;
  drive_.fault(kErrorCommandTimeout);
  watchdog_latched_ = true;
  armed_ = false;
  ++counters_.watchdog_trips;
  events_.watchdog_tripped = true;
  events_.unanswered_tick = oldest;
  events_.tripped_mono_ns = now_mono_ns;
}

const TickReport& DriveLoop::begin_tick(std::uint64_t tick, std::int64_t now_mono_ns, std::int64_t scheduled_mono_ns) {
  tick_ = tick;
  events_ = TickEvents{};
  published_this_tick_ = false;
  // Started more than a period late: the drive's own thread was held (by the host); the
  // controller gets until the drive is back on time before the watchdog counts again.
  // The tick after the last late one is spared too: the controller, held with the drive, needs
  // that long to answer what it could not.
  if (params_.realtime && now_mono_ns - scheduled_mono_ns > to_ns(params_.period_s)) {
    ++counters_.drive_stalls;
    any_stall_ = true;
    grace_until_tick_ = tick + 1;
  }
  tick_start_mono_ns_ = now_mono_ns;
  answered_ = false;
  fresh_ = false;
  accepted_this_tick_ = false;
  statistics_.record_tick_start(tick, now_mono_ns);
  if (!liveness_started_) {
    liveness_started_ = true;
    last_accept_mono_ns_ = now_mono_ns;
  }
  report_.measurement = drive_.sample();
  check_watchdog(now_mono_ns, true);
  track_power_state(now_mono_ns);
  const PowerState state = drive_.power_state();
  std::uint32_t bits = 0;
  if (state != PowerState::kOperationEnabled) bits |= status::kSafeState;
  if (state == PowerState::kFault || state == PowerState::kFaultReactionActive) bits |= status::kFault;
  if (watchdog_latched_) bits |= status::kWatchdogTripped;
  if (params_.realtime && !last_fresh_) bits |= status::kCommandLate;
  if (drive_.simulated()) bits |= status::kSimulated;
  if (foreign_seen_) bits |= status::kForeignCommand;
  if (report_.measurement.load_sensor_saturated) bits |= status::kLoadSensorSaturated;
  report_.tick = tick;
  report_.applied_force_n =
      std::isfinite(report_.measurement.applied_force_n) ? report_.measurement.applied_force_n : last_applied_force_n_;
  report_.applied_command_tick = applied_tick_;
  report_.status = bits;
  report_.power_state = state;
  report_.error_code = drive_.error_code();
  return report_;
}

void DriveLoop::published(std::int64_t wall_ns, std::int64_t mono_ns) {
  published_wall_ns_[tick_ % kRing] = wall_ns;
  published_mono_ns_[tick_ % kRing] = mono_ns;
  published_this_tick_ = true;
}

Verdict DriveLoop::offer(const ForceCommandIn& c) {
  if (c.run_id != run_id_) {
    ++counters_.rejected;
    ++counters_.other_run;
    return Verdict::kOtherRun;
  }
  if (owner_set_ && c.writer_id != owner_writer_id_) {
    ++counters_.foreign;
    if (!foreign_seen_ || new_foreign_writer_ != c.writer_id) {
      new_foreign_ = true;
      new_foreign_writer_ = c.writer_id;
    }
    foreign_seen_ = true;
    return Verdict::kForeignWriter;
  }
  const bool finite = std::isfinite(c.force_n) && std::isfinite(c.feedforward_force_n) &&
                      std::isfinite(c.velocity_mps) && std::isfinite(c.position_m);
  if (!params_.realtime) {
    if (c.feedback_tick != tick_) {
      ++counters_.late;  // an answer to another tick: stale or out of order
      return c.feedback_tick > tick_ ? Verdict::kFutureTick : Verdict::kStale;
    }
    answered_ = true;
    if (!finite) {
      ++counters_.rejected;  // the tick is answered; the last finite force stays applied
      return Verdict::kNonFinite;
    }
  } else {
    if (!finite) {
      ++counters_.rejected;
      return Verdict::kNonFinite;
    }
    if (c.feedback_tick > tick_) {
      ++counters_.rejected;
      return Verdict::kFutureTick;
    }
    if (any_command_ && c.feedback_tick <= applied_tick_) {
      ++counters_.rejected;
      return Verdict::kStale;
    }
  }
  setpoint_ = {c.force_n, c.feedforward_force_n, c.velocity_mps, c.position_m};
  applied_tick_ = c.feedback_tick;
  any_command_ = true;
  accepted_this_tick_ = true;
  last_accept_mono_ns_ = tick_start_mono_ns_;
  if (was_enabled_ && !owner_set_) {
    owner_set_ = true;
    owner_writer_id_ = c.writer_id;
  }
  if (applied_tick_ == tick_) {
    fresh_ = true;
    answered_ = true;
  }
  if (tick_ - applied_tick_ < kRing) {
    const std::int64_t received = c.received_wall_ns;
    statistics_.record_latency_ns(received - published_wall_ns_[applied_tick_ % kRing]);
  }
  return Verdict::kAccepted;
}

TickEvents DriveLoop::end_tick(std::int64_t now_mono_ns, bool apply_force) {
  const bool enabled = drive_.power_state() == PowerState::kOperationEnabled;
  if (params_.realtime) {
    if (!fresh_) ++counters_.late;
    if (enabled && !armed_) {
      consecutive_fresh_ = fresh_ ? consecutive_fresh_ + 1 : 0;
      if (consecutive_fresh_ >= params_.watchdog_arm_ticks) {
        armed_ = true;
        arm_tick_ = tick_ + 1;  // feedback from here on counts
      }
    } else {
      check_watchdog(now_mono_ns, false);
    }
    const double limit_s = any_command_ ? params_.controller_lost_s : params_.first_command_timeout_s;
    if (!lost_reported_ && now_mono_ns - last_accept_mono_ns_ > to_ns(limit_s)) {
      lost_reported_ = true;
      events_.controller_lost = true;
    }
  }
  if (!accepted_this_tick_ && !(applied_tick_ == tick_ && any_command_)) ++counters_.uncommanded_ticks;
  last_fresh_ = fresh_;
  const bool still_enabled = drive_.power_state() == PowerState::kOperationEnabled;
  if (ever_enabled_ && !still_enabled) ++counters_.safe_ticks;
  Setpoint out = setpoint_;
  if (!still_enabled) out.force_n = out.feedforward_force_n = 0.0;  // force off; the references go on
  last_applied_force_n_ = out.force_n;
  if (apply_force) drive_.apply_setpoint(out);
  return events_;
}

TransitionResult DriveLoop::request(DriveCommand command, std::int64_t now_mono_ns) {
  const TransitionResult result = drive_.request(command);
  track_power_state(now_mono_ns);
  return result;
}

bool DriveLoop::take_new_foreign_writer(std::uint64_t& writer_id) {
  if (!new_foreign_) return false;
  new_foreign_ = false;
  writer_id = new_foreign_writer_;
  return true;
}

}  // namespace pmlsm::drive
