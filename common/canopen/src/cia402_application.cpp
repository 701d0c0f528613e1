#include "pmlsm/canopen/cia402_application.hpp"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"

namespace pmlsm::canopen {

void DriveOwnLoopsParams::validate() const {
  velocity.validate();
  if (!std::isfinite(position_gain_per_s) || position_gain_per_s <= 0.0) {
    throw std::invalid_argument("position_gain_per_s: must be finite and > 0, got " +
                                std::to_string(position_gain_per_s));
  }
}

DriveOwnLoopsParams DriveOwnLoopsParams::like_controller(const VelocityPiParams& pi, double period_s) {
  DriveOwnLoopsParams p;
  p.velocity = pi;
  p.velocity.period_s = period_s;
  return p;
}

Cia402Application::Cia402Application(const Cia402ApplicationParams& params, ObjectDictionary& dictionary,
                                     drive::Drive& drive, Cia402ApplicationEvents& events)
    : params_(params), scaling_(params.scaling), od_(dictionary), drive_(drive), events_(events) {
  if (params_.own_loops) {
    params_.own_loops->validate();
    velocity_loop_.emplace(params_.own_loops->velocity);
  } else if ((static_cast<std::uint32_t>(od_.get_or(kObjectSupportedDriveModes, 0, 0)) & ~kSupportedModesTorque) != 0) {
    throw std::invalid_argument(
        "supported drive modes 0x6502 offer velocity or position, but the drive has no own loops");
  }
  measurement_ = drive_.sample();
  update_objects();
}

double Cia402Application::commanded_force() {
  const auto mode = static_cast<std::int8_t>(od_.get_or(kObjectModesOfOperation, 0, 0));
  const bool enabled_now = enabled();
  if (velocity_loop_ && (mode != mode_ || (enabled_now && !was_enabled_))) velocity_loop_->reset();
  mode_ = mode;
  was_enabled_ = enabled_now;
  const auto torque_offset = static_cast<std::int16_t>(od_.get_or(kObjectTorqueOffset, 0, 0));
  const double offset_n = scaling_.per_mille_to_force(torque_offset);
  if (mode != kModeCyclicSynchronousVelocity && mode != kModeCyclicSynchronousPosition) {
    const auto per_mille = static_cast<std::int16_t>(od_.get_or(kObjectTargetTorque, 0, 0));
    return scaling_.per_mille_to_force(per_mille) + offset_n;
  }
  // 0x6060 accepts velocity and position only when 0x6502 offers them, which needs own loops.
  if (!velocity_loop_) return 0.0;
  const auto velocity_offset = static_cast<std::int32_t>(od_.get_or(kObjectVelocityOffset, 0, 0));
  double velocity_command_mps = scaling_.increments_to_velocity(velocity_offset);
  if (mode == kModeCyclicSynchronousVelocity) {
    const auto target = static_cast<std::int32_t>(od_.get_or(kObjectTargetVelocity, 0, 0));
    velocity_command_mps += scaling_.increments_to_velocity(target);
  } else {
    const auto target = static_cast<std::int32_t>(od_.get_or(kObjectTargetPosition, 0, 0));
    velocity_command_mps +=
        params_.own_loops->position_gain_per_s * (scaling_.increments_to_metres(target) - measurement_.position_m);
  }
  if (!enabled_now) return 0.0;  // the loop runs only while its force is applied (no windup)
  return velocity_loop_->step({velocity_command_mps, measurement_.velocity_mps, offset_n}).force_n;
}

void Cia402Application::update_objects() {
  const drive::PowerState s = drive_.power_state();
  const bool faulted = s == drive::PowerState::kFault || s == drive::PowerState::kFaultReactionActive;
  od_.set(kObjectStatusword, 0, drive::statusword_of(s));
  od_.set(kObjectErrorCode, 0, drive_.error_code());
  od_.set(kObjectErrorRegister, 0, faulted ? kErrorRegisterGeneric : 0);
  od_.set(kObjectModesOfOperationDisplay, 0, od_.get_or(kObjectModesOfOperation, 0, 0));
  od_.set(kObjectPositionActual, 0, scaling_.metres_to_increments(measurement_.position_m).value);
  od_.set(kObjectVelocityActual, 0, scaling_.velocity_to_increments(measurement_.velocity_mps).value);
  // Torque actual, as a drive measures it: the force its current loop produces, K_f i_q.
  od_.set(kObjectTorqueActual, 0, scaling_.force_to_per_mille(measurement_.thrust_force_n).value);
  // Torque demand: the force the period applied (the own loops' output in velocity and position).
  od_.set(kObjectTorqueDemand, 0, scaling_.force_to_per_mille(applied_force_n_).value);
  // The load's sensor, where the drive has one (NaN: it measures no such thing; an object the
  // dictionary lacks is simply not set).
  if (std::isfinite(measurement_.load_position_m)) {
    od_.set(kObjectAdditionalPositionActual, 1, scaling_.metres_to_increments(measurement_.load_position_m).value);
  }
  if (std::isfinite(measurement_.load_acceleration_mps2)) {
    const double units = std::clamp(measurement_.load_acceleration_mps2 / kLoadAccelerationPerUnit,
                                    static_cast<double>(INT32_MIN), static_cast<double>(INT32_MAX));
    od_.set(kObjectLoadAcceleration, 0, std::llround(units));
  }
  od_.set(kObjectPeriodsStepped, 0, static_cast<std::int64_t>(periods_ & 0xFFFFFFFFULL));
}

void Cia402Application::raise_fault(std::uint16_t code, const std::string& why, std::int64_t now_ns) {
  const std::uint64_t before = drive_.fault_count();
  drive_.fault(code);
  if (drive_.fault_count() == before) return;  // already faulted: the first cause is kept
  update_objects();
  events_.emergency(code);
  char line[320];
  std::snprintf(line, sizeof line, "FAULT 0x%04X (%s): %s at period %" PRIu64 "; force off, emergency sent",
                static_cast<unsigned>(code), describe_emcy(code), why.c_str(), periods_);
  events_.log(true, line, now_ns);
}

void Cia402Application::apply_controlword(std::int64_t now_ns) {
  const auto cw = static_cast<std::uint16_t>(od_.get_or(kObjectControlword, 0, 0));
  const std::optional<drive::DriveCommand> command = drive::decode_controlword(cw, previous_controlword_);
  const bool changed = cw != previous_controlword_;
  previous_controlword_ = cw;
  if (!command) return;
  const drive::TransitionResult r = drive_.request(*command);
  char line[256];
  if (r.accepted && r.to != r.from) {
    std::snprintf(line, sizeof line, "controlword 0x%04X (%s): %s -> %s%s", static_cast<unsigned>(cw),
                  drive::to_string(*command), drive::to_string(r.from), drive::to_string(r.to),
                  r.to == drive::PowerState::kOperationEnabled ? "" : ", zero force");
    events_.log(false, line, now_ns);
    if (r.to == drive::PowerState::kOperationEnabled) enabled_since_ns_ = now_ns;
  } else if (!r.accepted && changed) {
    std::snprintf(line, sizeof line, "controlword 0x%04X (%s) refused in %s: %s", static_cast<unsigned>(cw),
                  drive::to_string(*command), drive::to_string(r.from), r.reason);
    events_.log(false, line, now_ns);
  }
  const bool was_fault = r.from == drive::PowerState::kFault;
  update_objects();
  if (was_fault && r.accepted && r.to != r.from) events_.emergency(kEmcyNoError);  // errors gone
}

void Cia402Application::step_period(std::int64_t now_ns) {
  if (params_.inject_fault_at_period && periods_ == *params_.inject_fault_at_period && !injected_) {
    injected_ = true;
    raise_fault(kEmcyDeviceHardware, "injected (--inject-fault-at-tick)", now_ns);
  }
  const double commanded_n = commanded_force();
  applied_force_n_ = drive_.power_state() == drive::PowerState::kOperationEnabled ? commanded_n : 0.0;
  drive_.apply(commanded_n);  // the backend applies it in operation enabled only
  ++periods_;
  measurement_ = drive_.sample();
  update_objects();
}

}  // namespace pmlsm::canopen
