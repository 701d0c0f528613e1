// The velocity command from outside (another node, `pmlsm setpoint`): what a rig accepts of
// it and what it does when the source goes quiet. Pure policy, no DDS; the controller node
// offers it the VelocitySetpoint samples and steps it once a control tick.
//
// Rules:
//  - a setpoint is rejected (and counted by reason) when non-finite, beyond the speed limit,
//    with a non-finite or negative acceleration limit, out of order within its session, or
//    from another session while the current one is still fresh (one source at a time: a
//    second publisher cannot take over a move; it can once the first has gone quiet);
//  - the newest accepted setpoint is the target while it is fresh: received no longer ago
//    than the timeout, on the receiver's clock (clocks of two hosts need not agree);
//  - stale (never any, or none for longer than the timeout): the target is zero;
//  - the command approaches the target at most accel * T a tick, accel the scenario's limit
//    or the setpoint's own when lower: never a jump, also when it goes stale. A source lost
//    with a non-zero target is counted (lost_while_moving): the run must not read as success.
#pragma once

#include <cstdint>

namespace pmlsm {

struct ExternalReferenceParams {
  double timeout_s = 0;       ///< a setpoint older than this no longer holds
  double max_speed_mps = 0;   ///< |setpoint| above this is rejected
  double max_accel_mps2 = 0;  ///< the command's rate limit
  double period_s = 0;        ///< control period
  /// @throws std::invalid_argument naming the first invalid parameter.
  void validate() const;
};

struct Setpoint {
  double velocity_mps = 0;
  double accel_limit_mps2 = 0;  ///< 0: the configured limit; lower: this one
  std::uint64_t session = 0;    ///< drawn by the source at its start
  std::uint64_t sequence = 0;   ///< increasing within a session
};

enum class SetpointVerdict { kAccepted, kNonFinite, kBeyondLimit, kBadAccelLimit, kOutOfOrder, kOtherSource };
const char* to_string(SetpointVerdict verdict);

struct ExternalReferenceOutput {
  double command_mps = 0;  ///< c(t_k), rate-limited
  double accel_mps2 = 0;   ///< its slope over the last tick
  double target_mps = 0;   ///< what it heads for (0 when stale)
  bool stale = true;
};

struct ExternalReferenceCounters {
  std::uint64_t accepted = 0;
  std::uint64_t rejected = 0;           ///< all reasons
  std::uint64_t rejected_invalid = 0;   ///< non-finite, beyond the limit, bad accel limit
  std::uint64_t stale_episodes = 0;     ///< fresh -> stale transitions
  std::uint64_t lost_while_moving = 0;  ///< ... of them with a non-zero target
};

class ExternalReference {
 public:
  /// @throws std::invalid_argument from the parameters.
  explicit ExternalReference(const ExternalReferenceParams& params);
  /// A setpoint received at now_s (receiver's clock, seconds, monotonic).
  SetpointVerdict offer(const Setpoint& setpoint, double now_s);
  /// One control tick at now_s.
  ExternalReferenceOutput step(double now_s);
  const ExternalReferenceCounters& counters() const { return counters_; }
  const ExternalReferenceParams& params() const { return params_; }

 private:
  bool fresh(double now_s) const { return have_setpoint_ && now_s - received_s_ <= params_.timeout_s; }

  ExternalReferenceParams params_;
  ExternalReferenceCounters counters_;
  bool have_setpoint_ = false;
  Setpoint last_;
  double received_s_ = 0;
  bool was_fresh_ = false;
  double command_mps_ = 0;
};

}  // namespace pmlsm
