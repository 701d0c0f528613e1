// The compensators an in-process run can put in the loop, by the names the tools take
// (closed_loop --compensator, the robustness sweep, the weight search's checks). One place
// maps a name to a compensator, so every in-process tool compares the same set.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/scenario.hpp"
#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

enum class CompensatorKind {
  kNone,   ///< the velocity PI alone
  kAccel,  ///< load-acceleration feedback F_c = -K_a a_L
  kRnn,    ///< the paper's Jordan RNN (weights from a file)
  kState,  ///< state feedback with inverse-model feedforward (StateFeedback)
};

const char* to_string(CompensatorKind kind);
/// @throws std::invalid_argument on an unknown name, listing the known ones.
CompensatorKind compensator_kind_from_string(const std::string& name);
/// "none, accel, rnn, state": for option help and error messages.
std::string compensator_kind_names();

struct CompensatorSetup {
  CompensatorKind kind = CompensatorKind::kNone;
  std::vector<double> rnn_weights;  ///< kRnn: the flat weight vector (weights_file.hpp)
  bool online_learning = false;     ///< kRnn: eqs. (16)-(19) during the run
};

/// A whole scenario (or its first max_ticks ticks) with the compensator in the loop,
/// its force applied one tick late (run_compensated). Thread-safe: each call builds its own loop.
/// @throws std::invalid_argument from the parameters, the scenario or a wrong-size weight set.
std::vector<TickRecord> run_with_compensator(const SystemParams& params, const Scenario& scenario,
                                             const CompensatorSetup& setup, std::uint64_t max_ticks = UINT64_MAX);

}  // namespace pmlsm
