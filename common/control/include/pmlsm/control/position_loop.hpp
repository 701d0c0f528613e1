// A position loop over the velocity loop (a drive's cascade), off by default: the paper's loop
// follows V_ref alone. The velocity the PI follows is
//   V_cmd,k = V_ref,k + sat(K_x (x_ref,k - x_k), +-max_correction_mps)
// with V_ref the feed-forward (the loop only corrects what the velocity loop left) and x either
//   closes_on: load   the load's encoder, the velocity loop staying on the motor's: a drive's dual
//                     ("full-closed") loop, where the load ends where it was sent whatever the
//                     spring and the motor's friction did on the way;
//   closes_on: motor  the motor's encoder (the semi-closed loop), for comparison.
// Each is counted from its reading at the loop's first tick, where x_ref is 0. A tick without a
// believed load reading (refused, or the sensor failed) closes on the motor's encoder instead,
// its origin moved so the position, and the correction, do not jump; a believed reading again
// closes back on the load the same way. Counted.
//
// K_x is bounded by the load's mode: with the motor following V_cmd, the load's velocity is
// Q = V_L / V_M (a lightly damped mass on the spring) times the velocity loop's T = 1 - S, so the
// loop's own open loop is K_x T Q / (j w) (pmlsm/analysis/loop_tuning.hpp, position_loop_margins,
// read from the commissioning's measurement).
#pragma once

#include <cstdint>
#include <string>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

enum class PositionFeedback { kNone, kMotor, kLoad };
const char* to_string(PositionFeedback feedback);
/// @throws std::invalid_argument listing the names ("must be one of none, motor, load").
PositionFeedback position_feedback_from_string(const std::string& name);

struct PositionLoopParams {
  PositionFeedback closes_on = PositionFeedback::kNone;
  double gain_per_s = 0;          ///< K_x
  double max_correction_mps = 0;  ///< the correction's bound
  void validate() const;
  /// Its entries under `at` ("position_loop"); the gain live on `live_at` (the controller).
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v, const char* live_at) {
    v.choice(at + ".closes_on", p.closes_on, &position_feedback_from_string);
    v.real(at + ".gain_per_s", p.gain_per_s,
           {1e-3, 1e4, "a loop from 0.2 mHz to 1.6 kHz, far beyond the 1 ms velocity loop", live_at});
    v.real(at + ".max_correction_mps", p.max_correction_mps, {1e-6, 10.0, "1 um/s to 10 m/s", live_at});
  }
};

struct PositionLoopInput {
  double x_ref_m = 0;           ///< V_ref's integral since the first tick
  double motor_position_m = 0;  ///< the motor's encoder
  /// The load's encoder when believed this tick; NaN: none (refused, failed, or no sensor).
  double load_position_m = 0;
};

struct PositionLoopOutput {
  double correction_mps = 0;    ///< added to V_ref
  double position_error_m = 0;  ///< x_ref - x
  bool on_load = false;         ///< this tick closed on the load's encoder
};

struct PositionLoopCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;    ///< x_ref or the motor's position non-finite: the last output held
  std::uint64_t ticks_on_motor = 0;     ///< closes_on load, but the motor's encoder this tick
  std::uint64_t switches_to_motor = 0;  ///< the load's encoder lost
  std::uint64_t saturated = 0;          ///< the correction at its bound
};

class PositionLoop {
 public:
  /// @throws std::invalid_argument naming the first invalid parameter (closes_on none is valid:
  /// step then returns no correction).
  explicit PositionLoop(const PositionLoopParams& params);
  /// A new gain or bound from the next step on; the origins kept. @throws as the constructor,
  /// and when closes_on changes (read at start).
  void set_params(const PositionLoopParams& params);
  PositionLoopOutput step(const PositionLoopInput& in) noexcept;
  const PositionLoopParams& params() const noexcept { return params_; }
  const PositionLoopCounters& counters() const noexcept { return counters_; }

 private:
  PositionLoopParams params_;
  bool started_ = false;
  bool on_load_ = false;
  double origin_m_ = 0;  ///< subtracted from the encoder the loop closes on
  PositionLoopOutput last_;
  PositionLoopCounters counters_;
};

}  // namespace pmlsm
