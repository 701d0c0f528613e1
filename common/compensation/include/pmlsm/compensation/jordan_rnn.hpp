// The recurrent-network compensator of section 3.2: a Jordan network (the
// output fed back as a "state unit" input with fixed weight +1, tanh in every
// neuron (15)) and the online learning rule (16)-(19) that adapts it while it
// runs, with the velocity error V_ref - V_load as the training error.
//
// JordanRnn is the bare network (forward pass, d output / d weights);
// RnnCompensator wraps it into the component of Fig. 4: it keeps the history
// of the normalised load acceleration, scales the output by G_n and, when
// enabled, applies the extended back-propagation update (19) each tick.
//
// A network's biases give it an output at rest: with no signal its state unit settles on the
// fixed point u* = N(0, ..., 0, u*) (the shipped set: u* = 0.021, 14 N of G_n). During a move
// the velocity loop absorbs it (and a set searched on one direction of travel uses it as its
// friction feed-forward), but once the motor sticks at rest nothing does: it pushes a held motor
// with a steady 7-33 N. So, once the reference has rested for rest_settle_s, the force is
//   F = G_n s_o (u_n - w u*),   w: 0 -> 1 over rest_fade_s, back to 0 the tick the reference moves.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm {

/// Jordan network (paper 3.2): inputs = external inputs + one state unit that
/// carries the network's previous output u_n(k-1) with fixed weight +1; tanh in
/// every neuron including the output (15), so |u_n| <= 1. A bias into every neuron.
///
/// Flat weight order (also the file/topic order): layer by layer from the first
/// hidden layer; within a layer neuron by neuron; per neuron its incoming weights
/// in the order of the previous layer's neurons, then its bias. The input layer's
/// order is the external inputs first, the state unit last. For 3-6-6-3-1:
/// 4*6 + 7*6 + 7*3 + 4*1 = 91 (Table 1).
///
/// Not thread-safe: forward() and gradient() use preallocated scratch buffers.
class JordanRnn {
 public:
  /// Largest accepted layer width (guards against nonsense sizes from files).
  static constexpr int kMaxLayerSize = 4096;
  /// Largest accepted |weight| of a set handed in (files, the NetworkWeights topic, the
  /// optimisers' candidates). tanh is saturated beyond |net| = 5 and the network's inputs
  /// are about +-1.4 (the input scale maps the test accelerations there), so weights far
  /// beyond 100 only switch neurons between -1 and +1: the compensator becomes a +-G_n
  /// bang-bang. The shipped set's largest is 2.7 and DE starts in [-1, 1] (Table 1).
  static constexpr double kMaxAbsWeight = 100.0;

  /// layer_sizes: inputs first (including the state unit), output last; >= 2
  /// layers, every size in [1, kMaxLayerSize], last == 1, first >= 2 (at least
  /// one external input + state unit). Weights start at zero.
  /// @throws std::invalid_argument naming the bad entry ("layer_sizes[2]: must be >= 1, got 0").
  explicit JordanRnn(std::vector<int> layer_sizes);

  /// The weights of a network that acts, for small inputs, as the linear law u_n = gain x_0 (x_0
  /// its first external input; the other inputs and the state unit unused): one chain through the
  /// first neuron of every layer, every link |gain|^(1/L) (L = layer_sizes.size() - 1 links, the
  /// output's carrying the sign), every other weight and bias 0; tanh'(0) = 1, so the chain's gain
  /// is the product. Spread evenly, no link amplifies what a search adds upstream more than the
  /// law needs. tanh bends the chain as the signal grows and saturates it towards +-1 (the force
  /// limit G_n is reached at |x_0| = 1 / |gain|). A search can start from a known linear law
  /// (acceleration feedback) and look for better.
  /// @throws std::invalid_argument for invalid sizes, a zero or non-finite gain, or a link above
  /// kMaxAbsWeight.
  static std::vector<double> linear_chain_weights(const std::vector<int>& layer_sizes, double gain);

  /// Number of weights and biases of a network of these sizes.
  /// @throws std::invalid_argument as the constructor for invalid sizes.
  static std::size_t parameter_count(const std::vector<int>& layer_sizes);
  std::size_t parameter_count() const { return weights_.size(); }
  const std::vector<int>& layer_sizes() const { return sizes_; }
  /// layer_sizes[0] - 1: the inputs besides the state unit.
  std::size_t external_input_count() const { return static_cast<std::size_t>(sizes_[0]) - 1; }

  /// Replaces all weights; the state unit is kept.
  /// @throws std::invalid_argument on wrong size ("weights: expected 91 values, got 90")
  /// or a non-finite value ("weights[17]: must be finite, got nan"); the old weights stay.
  void set_weights(const std::vector<double>& weights);
  const std::vector<double>& weights() const { return weights_; }

  /// w += delta (parameter_count() values) if every resulting weight is finite;
  /// otherwise leaves the weights unchanged and returns false. No allocation.
  bool add_to_weights(const double* delta);

  /// Forward pass with the current state unit; stores the activations for
  /// gradient(); returns u_n(k) but does NOT advance the state unit.
  /// external_inputs: external_input_count() values. No allocation.
  double forward(const double* external_inputs);
  /// Output of the last forward() (0 before the first).
  double output() const { return activations_.back(); }

  /// Makes the last forward() output the state unit for the next step: u_n(k-1) <- u_n(k).
  void commit_output() { state_unit_ = activations_.back(); }
  double state_unit() const { return state_unit_; }
  /// Sets the state unit (u_n(k-1)) and clears the stored activations.
  void reset_state(double u = 0.0);

  /// The network's output at rest: the fixed point u* = N(0, ..., 0, u*) of its state unit with
  /// every external input 0, iterated from 0 (at most kRestIterations forward passes, until a pass
  /// moves it by 1e-12 or less); nullopt when it does not settle (a network that oscillates with
  /// no signal has no output at rest). The state unit is kept; the stored activations are not.
  std::optional<double> rest_output();
  static constexpr int kRestIterations = 1000;
  /// N(0, ..., 0, state_unit): one forward pass with every external input 0 from this state unit
  /// (a step of rest_output()'s iteration). The state unit is kept; the stored activations are
  /// not. No allocation.
  double output_with_no_signal(double state_unit);

  /// d u_n / d w for the last forward(), state unit held fixed (one-step
  /// back-propagation, no back-propagation through time, as the paper's BP).
  /// Writes parameter_count() values in the flat weight order; no allocation.
  void gradient(double* d_output_d_weights) const;

 private:
  std::vector<int> sizes_;
  std::vector<std::size_t> activation_offset_;  ///< per layer, into activations_
  std::vector<std::size_t> weight_offset_;      ///< per layer (index 0 unused), into weights_
  std::vector<double> weights_;
  std::vector<double> no_signal_;      ///< external_input_count() zeros, never written
  std::vector<double> activations_;    ///< all layers, inputs first, output last
  mutable std::vector<double> delta_;  ///< dU/dz per neuron (same layout as activations_)
  double state_unit_ = 0.0;
};

struct RnnCompensatorParams {
  std::vector<int> layer_sizes;     ///< Table 1's 3-6-6-3-1 in the shipped file; inputs first, output last
  double input_scale_s2_per_m = 0;  ///< x = input_scale * a_L normalises the load acceleration, > 0
  /// The network's signal: false, the paper's a_L; true, the error a_L - dV_ref/dt, so that a
  /// commanded acceleration is no vibration to the network (AccelFeedbackParams says why).
  bool on_reference_error = false;
  double gain_n = 0;  ///< G_n: force = G_n u_n, > 0
  /// The force is G_n s_o u_n: s_o rescales a set trained on one load for another (the
  /// commissioned compensator.rnn.output_scale times the gain schedule on the model's load mass,
  /// SystemParams::rnn_compensator_params), > 0.
  double output_scale = 0;
  double period_s = 0;  ///< T_s of (18), > 0
  bool online_learning = false;
  double learning_rate = 0;      ///< eta (16), >= 0
  double momentum = 0;           ///< alpha (16), in [0, 1)
  double tolerance_mps = 0;      ///< update only while |V_ref - V_load| > tolerance, >= 0
  double kc_limit_mps = 0;       ///< |k_c| clamp, > 0, and momentum * kc_limit_mps < 1
  double du_deadband_per_s = 0;  ///< |dU_n| below this: k_c undefined -> no update this tick, > 0
  /// The network's output at rest taken out (above) once the reference has rested rest_settle_s;
  /// false: the paper's bare network, its output at rest kept. Read at start.
  bool remove_rest_output = false;
  double rest_settle_s = 0;  ///< |c| and |V_ref| at or below rest_velocity_mps this long: at rest, >= 0
  double rest_fade_s = 0;    ///< u* taken out over this long, >= 0 (0: at once)
  /// The reference at rest: the standstill gate's compensator.standstill.rest_velocity_mps (the
  /// system's; one definition of rest for both), >= 0.
  double rest_velocity_mps = 0;
  /// @throws std::invalid_argument naming the first invalid parameter.
  void validate() const;
  /// Its own entries under `at` ("compensator.rnn"): the network's shape and scales (read at
  /// start), the online rule's settings and the output scale (taken live by `live_at`); the
  /// period, the schedule's gain and whether it learns come from the system and the node.
  template <typename Self, typename Visitor>
  static void declare(const std::string& at, Self& p, Visitor& v, const char* live_at) {
    v.integer_list(at + ".layer_sizes", p.layer_sizes, {1.0, 1000.0, "neurons of a layer: a whole number, 1 to 1000"});
    v.real(at + ".input_scale_s2_per_m", p.input_scale_s2_per_m,
           {1e-6, 1e3, "maps accelerations of 1 mm/s^2 to 1000 km/s^2 into tanh's range"});
    v.real(at + ".gain_n", p.gain_n, {1e-3, 1e5, "1 mN to 100 kN, the range of the force limit"});
    v.real(at + ".output_scale", p.output_scale, {0.05, 20.0, "a twentieth to twenty times the force", live_at});
    v.real(at + ".learning_rate", p.learning_rate,
           {0.0, 100.0,
            "eta of (16), in (m/s)^-2 (the step is eta e k_c dU_n/dw): at 100, errors of 0.1 m/s move a weight by 1 "
            "a tick",
            live_at});
    v.real(at + ".momentum", p.momentum, {0.0, 0.999, "alpha of (16): below 1 to contract", live_at});
    v.real(at + ".tolerance_mps", p.tolerance_mps, {0.0, 1.0, "0 to 1 m/s of dead band", live_at});
    v.real(at + ".kc_limit_mps", p.kc_limit_mps, {1e-6, 1e3, "1 um/s to 1 km/s", live_at});
    v.real(at + ".du_deadband_per_s", p.du_deadband_per_s, {1e-6, 1e6, "1e-6 to 1e6 1/s", live_at});
    v.flag(at + ".on_reference_error", p.on_reference_error);
    v.flag(at + ".remove_rest_output", p.remove_rest_output);
    v.real(at + ".rest_settle_s", p.rest_settle_s, {0.0, 3600.0, "0 (at once) to an hour at rest", live_at});
    v.real(at + ".rest_fade_s", p.rest_fade_s, {0.0, 60.0, "0 (at once) to a minute", live_at});
  }
};

struct CompensatorInput {
  double load_accel_mps2 = 0;       ///< a_L(k), e.g. the Kalman filter's (36)
  double v_ref_mps = 0;             ///< V_ref(k)
  double v_load_mps = 0;            ///< V_load(k) (estimated)
  double reference_accel_mps2 = 0;  ///< dV_ref/dt(k) (used when on_reference_error)
  double command_mps = 0;           ///< c(k), the command into the reference model (rest)
};

struct CompensatorStep {
  double force_n = 0;             ///< G_n s_o (u_n(k) - w u*)
  double u_n = 0;                 ///< network output u_n(k), |u_n| <= 1
  double training_error_mps = 0;  ///< e = V_ref - V_load
  double k_c_mps = 0;             ///< k_c (17) after the clamp; 0 when not computed this tick
  bool input_rejected = false;    ///< non-finite input: output 0 force, state/weights untouched
  bool weights_updated = false;
  bool kc_guarded = false;  ///< k_c clamped or dead-banded
};

struct CompensatorCounters {
  std::uint64_t steps = 0;
  std::uint64_t rejected_inputs = 0;
  std::uint64_t updates = 0;           ///< ticks whose update (19) was applied
  std::uint64_t kc_clamped = 0;        ///< |k_c| > kc_limit: clamped, update applied
  std::uint64_t kc_deadband = 0;       ///< |dU_n| < du_deadband: no update
  std::uint64_t reverted_updates = 0;  ///< an update would have made a weight non-finite
};

/// The network compensator of Fig. 4 with online learning (16)-(19).
///
/// Tick k: x = [s a_L(k), s a_L(k-1), ..., s a_L(k-m+1), u_n(k-1)] (a_L - dV_ref/dt in
/// place of a_L when on_reference_error) with
/// m = external_input_count() (m = 2 in the paper), u_n(k) = network(x),
/// force = G_n u_n(k). Then, when online learning is on and |e| > tolerance,
/// e = V_ref - V_load, the weights are updated by (17)-(19) with
/// k_c = a_L(k) / dU_n, dU_n = (u_n(k-1) - u_n(k-2)) / T_s (the last applied
/// change, the one a_L(k) responds to; see jordan_rnn.cpp for the derivation and
/// the k_c guards); the update affects the next tick.
class RnnCompensator {
 public:
  /// Weights are zero until set. @throws std::invalid_argument naming the bad parameter.
  explicit RnnCompensator(const RnnCompensatorParams& params);

  /// Validates (throws std::invalid_argument, old weights kept), replaces the
  /// weights and resets the momentum Delta w(n); the state unit is kept. Finds the new
  /// weights' output at rest (JordanRnn::rest_output: up to 1000 forward passes).
  void set_weights(const std::vector<double>& w);
  const std::vector<double>& weights() const { return net_.weights(); }

  /// One tick. Never throws, no allocation.
  CompensatorStep step(const CompensatorInput& in);

  /// State unit 0, a_L history 0, momentum 0 (weights and counters kept).
  void reset();

  /// The online rule's settings changed live (learning rate, momentum, tolerance, k_c clamp and
  /// dead-band), the weights, the state unit and the momentum kept. What the network and its
  /// weights were built on (layer sizes, input scale, input kind, G_n, output scale, period,
  /// online learning on or off) needs a restart.
  /// @throws std::invalid_argument naming the invalid value or the entry that needs a restart;
  /// the old settings kept.
  void set_learning(const RnnCompensatorParams& params);

  /// u*, the network's output at rest (0 when it has none); with online learning it follows the
  /// weights one forward pass a tick.
  double rest_output() const { return rest_output_; }
  /// G_n s_o u*: the force the network holds a load at rest with, before any is taken out.
  double rest_force_n() const { return params_.gain_n * params_.output_scale * rest_output_; }
  const CompensatorCounters& counters() const { return counters_; }
  const RnnCompensatorParams& params() const { return params_; }
  const JordanRnn& network() const { return net_; }

 private:
  /// w of F = G_n s_o (u_n - w u*): 0 until the reference has rested rest_settle_s, then up to 1
  /// over rest_fade_s.
  double rest_share() const noexcept;
  RnnCompensatorParams params_;
  JordanRnn net_;
  std::vector<double> inputs_;    ///< s a_L(k), s a_L(k-1), ...: the external inputs
  std::vector<double> grad_;      ///< d u_n / d w of this tick
  std::vector<double> dw_;        ///< Delta w(n): the last applied update (momentum)
  std::vector<double> next_dw_;   ///< Delta w(n+1) being formed
  double u_prev2_ = 0.0;          ///< u_n(k-2), for dU_n of (18)
  double rest_output_ = 0.0;      ///< u*
  std::uint64_t rest_ticks_ = 0;  ///< ticks the reference has rested
  CompensatorCounters counters_;
};

}  // namespace pmlsm
