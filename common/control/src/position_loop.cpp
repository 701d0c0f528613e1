#include "pmlsm/control/position_loop.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

const char* to_string(PositionFeedback feedback) {
  switch (feedback) {
    case PositionFeedback::kNone: return "none";
    case PositionFeedback::kMotor: return "motor";
    case PositionFeedback::kLoad: return "load";
  }
  return "none";
}

PositionFeedback position_feedback_from_string(const std::string& name) {
  if (name == "none") return PositionFeedback::kNone;
  if (name == "motor") return PositionFeedback::kMotor;
  if (name == "load") return PositionFeedback::kLoad;
  throw std::invalid_argument("must be one of none, motor, load, got '" + name + "'");
}

void PositionLoopParams::validate() const { check_declared_ranges(*this); }

PositionLoop::PositionLoop(const PositionLoopParams& params) : params_(params) { params_.validate(); }

void PositionLoop::set_params(const PositionLoopParams& params) {
  params.validate();
  if (params.closes_on != params_.closes_on) {
    throw std::invalid_argument(std::string("closes_on: read at start, cannot change from ") +
                                to_string(params_.closes_on) + " to " + to_string(params.closes_on));
  }
  params_ = params;
}

PositionLoopOutput PositionLoop::step(const PositionLoopInput& in) noexcept {
  if (params_.closes_on == PositionFeedback::kNone) return {};
  if (!all_finite(in.x_ref_m, in.motor_position_m)) {
    ++counters_.rejected_inputs;
    return last_;
  }
  ++counters_.steps;
  const bool load_now = params_.closes_on == PositionFeedback::kLoad && std::isfinite(in.load_position_m);
  const double encoder_m = load_now ? in.load_position_m : in.motor_position_m;
  if (!started_) {
    origin_m_ = encoder_m - in.x_ref_m;
  } else if (load_now != on_load_) {
    // Bumpless: the error goes on from the last tick's (the tick's own motion, micrometres, is
    // the step it does not see).
    origin_m_ = encoder_m - (in.x_ref_m - last_.position_error_m);
    if (!load_now) ++counters_.switches_to_motor;
  }
  started_ = true;
  on_load_ = load_now;
  if (params_.closes_on == PositionFeedback::kLoad && !load_now) ++counters_.ticks_on_motor;
  PositionLoopOutput out;
  out.on_load = load_now;
  out.position_error_m = in.x_ref_m - (encoder_m - origin_m_);
  const double unlimited = params_.gain_per_s * out.position_error_m;
  out.correction_mps = std::clamp(unlimited, -params_.max_correction_mps, params_.max_correction_mps);
  if (out.correction_mps != unlimited) ++counters_.saturated;
  last_ = out;
  return out;
}

}  // namespace pmlsm
