#include "pmlsm/control/external_reference.hpp"

#include <algorithm>
#include <cmath>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

void ExternalReferenceParams::validate() const {
  require_in_range("period_s", period_s, 1e-6, 1.0);
  require_in_range("timeout_s", timeout_s, period_s, 60.0);
  require_positive("max_speed_mps", max_speed_mps);
  require_positive("max_accel_mps2", max_accel_mps2);
}

const char* to_string(SetpointVerdict verdict) {
  switch (verdict) {
    case SetpointVerdict::kAccepted: return "accepted";
    case SetpointVerdict::kNonFinite: return "not finite";
    case SetpointVerdict::kBeyondLimit: return "beyond the speed limit";
    case SetpointVerdict::kBadAccelLimit: return "acceleration limit not finite or negative";
    case SetpointVerdict::kOutOfOrder: return "out of order";
    case SetpointVerdict::kOtherSource: return "another source holds the reference";
  }
  return "?";
}

ExternalReference::ExternalReference(const ExternalReferenceParams& params) : params_(params) { params_.validate(); }

SetpointVerdict ExternalReference::offer(const Setpoint& sp, double now_s) {
  SetpointVerdict verdict = SetpointVerdict::kAccepted;
  if (!std::isfinite(sp.velocity_mps)) {
    verdict = SetpointVerdict::kNonFinite;
  } else if (std::abs(sp.velocity_mps) > params_.max_speed_mps) {
    verdict = SetpointVerdict::kBeyondLimit;
  } else if (!(sp.accel_limit_mps2 >= 0.0) || !std::isfinite(sp.accel_limit_mps2)) {
    verdict = SetpointVerdict::kBadAccelLimit;
  } else if (have_setpoint_ && sp.session == last_.session && sp.sequence <= last_.sequence) {
    verdict = SetpointVerdict::kOutOfOrder;
  } else if (have_setpoint_ && sp.session != last_.session && fresh(now_s)) {
    verdict = SetpointVerdict::kOtherSource;
  }
  if (verdict != SetpointVerdict::kAccepted) {
    ++counters_.rejected;
    if (verdict == SetpointVerdict::kNonFinite || verdict == SetpointVerdict::kBeyondLimit ||
        verdict == SetpointVerdict::kBadAccelLimit) {
      ++counters_.rejected_invalid;
    }
    return verdict;
  }
  ++counters_.accepted;
  have_setpoint_ = true;
  last_ = sp;
  received_s_ = now_s;
  return verdict;
}

ExternalReferenceOutput ExternalReference::step(double now_s) {
  ExternalReferenceOutput out;
  out.stale = !fresh(now_s);
  if (out.stale && was_fresh_) {
    ++counters_.stale_episodes;
    if (last_.velocity_mps != 0.0) ++counters_.lost_while_moving;
  }
  was_fresh_ = !out.stale;
  out.target_mps = out.stale ? 0.0 : last_.velocity_mps;
  // The setpoint may ask for a gentler rate, never a steeper one; stale: the configured rate.
  double accel = params_.max_accel_mps2;
  if (!out.stale && last_.accel_limit_mps2 > 0.0) accel = std::min(accel, last_.accel_limit_mps2);
  const double max_step = accel * params_.period_s;
  const double previous = command_mps_;
  command_mps_ += std::clamp(out.target_mps - command_mps_, -max_step, max_step);
  out.command_mps = command_mps_;
  out.accel_mps2 = (command_mps_ - previous) / params_.period_s;
  return out;
}

}  // namespace pmlsm
