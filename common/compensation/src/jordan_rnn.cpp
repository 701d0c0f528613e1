#include "pmlsm/compensation/jordan_rnn.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "pmlsm/util/validate.hpp"

namespace pmlsm {

namespace {

[[noreturn]] void bad_size(std::size_t index, const std::string& what, int value) {
  throw std::invalid_argument("layer_sizes[" + std::to_string(index) + "]: " + what + ", got " + std::to_string(value));
}

void check_layer_sizes(const std::vector<int>& sizes) {
  if (sizes.size() < 2) {
    throw std::invalid_argument("layer_sizes: must have at least 2 layers (inputs and output), got " +
                                std::to_string(sizes.size()));
  }
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    if (sizes[i] < 1) bad_size(i, "must be >= 1", sizes[i]);
    if (sizes[i] > JordanRnn::kMaxLayerSize) {
      bad_size(i, "must be <= " + std::to_string(JordanRnn::kMaxLayerSize), sizes[i]);
    }
  }
  if (sizes.front() < 2) {
    bad_size(0, "must be >= 2 (at least one external input and the state unit)", sizes.front());
  }
  if (sizes.back() != 1) bad_size(sizes.size() - 1, "the output layer must have 1 neuron", sizes.back());
}

}  // namespace

// ---------------------------------------------------------------- JordanRnn

std::size_t JordanRnn::parameter_count(const std::vector<int>& layer_sizes) {
  check_layer_sizes(layer_sizes);
  std::size_t count = 0;
  for (std::size_t l = 1; l < layer_sizes.size(); ++l) {
    count += static_cast<std::size_t>(layer_sizes[l]) * (static_cast<std::size_t>(layer_sizes[l - 1]) + 1);
  }
  return count;
}

std::vector<double> JordanRnn::linear_chain_weights(const std::vector<int>& layer_sizes, double gain) {
  std::vector<double> weights(parameter_count(layer_sizes), 0.0);
  if (!std::isfinite(gain) || gain == 0.0) {
    throw std::invalid_argument("gain: must be finite and not 0, got " + format_value(gain));
  }
  const std::size_t links = layer_sizes.size() - 1;
  const double link = std::pow(std::abs(gain), 1.0 / static_cast<double>(links));
  if (!(link <= kMaxAbsWeight)) {
    throw std::invalid_argument("gain: " + format_value(gain) + " needs links of " + format_value(link) +
                                ", above the largest weight " + format_value(kMaxAbsWeight));
  }
  // Neuron 0 of each layer: its incoming weights start the layer's rows, input 0 first.
  std::size_t offset = 0;
  for (std::size_t l = 1; l <= links; ++l) {
    weights[offset] = l == links ? std::copysign(link, gain) : link;
    offset += static_cast<std::size_t>(layer_sizes[l]) * (static_cast<std::size_t>(layer_sizes[l - 1]) + 1);
  }
  return weights;
}

JordanRnn::JordanRnn(std::vector<int> layer_sizes) : sizes_(std::move(layer_sizes)) {
  weights_.assign(parameter_count(sizes_), 0.0);
  no_signal_.assign(external_input_count(), 0.0);
  activation_offset_.resize(sizes_.size());
  weight_offset_.assign(sizes_.size(), 0);
  std::size_t a = 0, w = 0;
  for (std::size_t l = 0; l < sizes_.size(); ++l) {
    activation_offset_[l] = a;
    a += static_cast<std::size_t>(sizes_[l]);
    if (l > 0) {
      weight_offset_[l] = w;
      w += static_cast<std::size_t>(sizes_[l]) * (static_cast<std::size_t>(sizes_[l - 1]) + 1);
    }
  }
  activations_.assign(a, 0.0);
  delta_.assign(a, 0.0);
}

void JordanRnn::set_weights(const std::vector<double>& weights) {
  if (weights.size() != weights_.size()) {
    throw std::invalid_argument("weights: expected " + std::to_string(weights_.size()) + " values, got " +
                                std::to_string(weights.size()));
  }
  for (std::size_t i = 0; i < weights.size(); ++i) {
    if (!std::isfinite(weights[i])) {
      throw std::invalid_argument("weights[" + std::to_string(i) + "]: must be finite, got " +
                                  format_value(weights[i]));
    }
    if (!(std::fabs(weights[i]) <= kMaxAbsWeight)) {
      throw std::invalid_argument("weights[" + std::to_string(i) + "]: must be within +-" +
                                  format_value(kMaxAbsWeight) + " (beyond, tanh only switches: a bang-bang), got " +
                                  format_value(weights[i]));
    }
  }
  std::copy(weights.begin(), weights.end(), weights_.begin());
}

bool JordanRnn::add_to_weights(const double* delta) {
  for (std::size_t i = 0; i < weights_.size(); ++i) {
    if (!std::isfinite(weights_[i] + delta[i])) return false;
  }
  for (std::size_t i = 0; i < weights_.size(); ++i) weights_[i] += delta[i];
  return true;
}

void JordanRnn::reset_state(double u) {
  state_unit_ = u;
  std::fill(activations_.begin(), activations_.end(), 0.0);
}

double JordanRnn::output_with_no_signal(double state_unit) {
  const double kept = state_unit_;
  state_unit_ = state_unit;
  const double u = forward(no_signal_.data());
  reset_state(kept);
  return u;
}

std::optional<double> JordanRnn::rest_output() {
  double u = 0.0;
  for (int i = 0; i < kRestIterations; ++i) {
    const double next = output_with_no_signal(u);
    if (std::abs(next - u) <= 1e-12) return next;
    u = next;
  }
  return std::nullopt;
}

double JordanRnn::forward(const double* external_inputs) {
  const std::size_t m = external_input_count();
  for (std::size_t i = 0; i < m; ++i) activations_[i] = external_inputs[i];
  activations_[m] = state_unit_;  // the state unit: fixed weight +1 from u_n(k-1)
  for (std::size_t l = 1; l < sizes_.size(); ++l) {
    const std::size_t n_in = static_cast<std::size_t>(sizes_[l - 1]);
    const std::size_t n_out = static_cast<std::size_t>(sizes_[l]);
    const double* in = &activations_[activation_offset_[l - 1]];
    double* out = &activations_[activation_offset_[l]];
    const double* w = &weights_[weight_offset_[l]];
    for (std::size_t j = 0; j < n_out; ++j, w += n_in + 1) {
      double z = w[n_in];  // bias
      for (std::size_t i = 0; i < n_in; ++i) z += w[i] * in[i];
      out[j] = std::tanh(z);  // (15)
    }
  }
  return activations_.back();
}

void JordanRnn::gradient(double* g) const {
  // Back-propagation of the single output: delta_j = d u_n / d z_j, with
  // tanh'(z) = 1 - tanh(z)^2 taken from the stored activations.
  //   output:  delta = 1 - u_n^2
  //   hidden:  delta_i = (1 - a_i^2) * sum_j w_ji delta_j   (j over the next layer)
  //   weights: d u_n / d w_ji = delta_j * a_i,  d u_n / d b_j = delta_j.
  // The inputs (including the state unit u_n(k-1)) are held fixed: no BPTT.
  const std::size_t last = sizes_.size() - 1;
  const double u = activations_.back();
  delta_.back() = 1.0 - u * u;
  for (std::size_t l = last; l >= 1; --l) {
    const std::size_t n_in = static_cast<std::size_t>(sizes_[l - 1]);
    const std::size_t n_out = static_cast<std::size_t>(sizes_[l]);
    const double* in = &activations_[activation_offset_[l - 1]];
    const double* d_out = &delta_[activation_offset_[l]];
    const double* w = &weights_[weight_offset_[l]];
    double* gw = g + weight_offset_[l];
    for (std::size_t j = 0; j < n_out; ++j) {
      const std::size_t row = j * (n_in + 1);
      for (std::size_t i = 0; i < n_in; ++i) gw[row + i] = d_out[j] * in[i];
      gw[row + n_in] = d_out[j];
    }
    if (l > 1) {  // deltas of the previous (hidden) layer
      double* d_in = &delta_[activation_offset_[l - 1]];
      for (std::size_t i = 0; i < n_in; ++i) {
        double s = 0.0;
        for (std::size_t j = 0; j < n_out; ++j) s += w[j * (n_in + 1) + i] * d_out[j];
        d_in[i] = (1.0 - in[i] * in[i]) * s;
      }
    }
  }
}

// ----------------------------------------------------------- RnnCompensator

void RnnCompensatorParams::validate() const {
  JordanRnn::parameter_count(layer_sizes);  // throws "layer_sizes[i]: ..." (the shape, beyond each size's range)
  check_declared_ranges(*this);
  require_positive("period_s", period_s);  // the system's, not declared here
  if (!(momentum * kc_limit_mps < 1.0)) {
    throw std::invalid_argument(
        "kc_limit_mps: momentum * kc_limit_mps must be < 1 so that the momentum term of (19) "
        "contracts, got " +
        format_value(momentum) + " * " + format_value(kc_limit_mps) + " = " + format_value(momentum * kc_limit_mps));
  }
}

RnnCompensator::RnnCompensator(const RnnCompensatorParams& params)
    : params_((params.validate(), params)), net_(params_.layer_sizes) {
  inputs_.assign(net_.external_input_count(), 0.0);
  grad_.assign(net_.parameter_count(), 0.0);
  dw_.assign(net_.parameter_count(), 0.0);
  next_dw_.assign(net_.parameter_count(), 0.0);
}

void RnnCompensator::set_weights(const std::vector<double>& w) {
  net_.set_weights(w);
  std::fill(dw_.begin(), dw_.end(), 0.0);
  rest_output_ = net_.rest_output().value_or(0.0);
}

void RnnCompensator::set_learning(const RnnCompensatorParams& params) {
  params.validate();
  const auto needs_restart = [](const char* what) {
    throw std::invalid_argument(std::string(what) + ": the network was built on it; a change needs a restart");
  };
  if (params.layer_sizes != params_.layer_sizes) needs_restart("layer_sizes");
  if (params.input_scale_s2_per_m != params_.input_scale_s2_per_m) needs_restart("input_scale_s2_per_m");
  if (params.on_reference_error != params_.on_reference_error) needs_restart("on_reference_error");
  if (params.gain_n != params_.gain_n) needs_restart("gain_n");
  if (params.period_s != params_.period_s) needs_restart("period_s");
  if (params.online_learning != params_.online_learning) needs_restart("online_learning");
  if (params.remove_rest_output != params_.remove_rest_output) needs_restart("remove_rest_output");
  params_ = params;
}

double RnnCompensator::rest_share() const noexcept {
  if (!params_.remove_rest_output || rest_ticks_ == 0) return 0.0;
  const double rested_s = static_cast<double>(rest_ticks_) * params_.period_s - params_.rest_settle_s;
  if (rested_s <= 0.0) return 0.0;
  return params_.rest_fade_s > 0.0 ? std::min(1.0, rested_s / params_.rest_fade_s) : 1.0;
}

void RnnCompensator::reset() {
  net_.reset_state(0.0);
  u_prev2_ = 0.0;
  rest_ticks_ = 0;
  std::fill(inputs_.begin(), inputs_.end(), 0.0);
  std::fill(dw_.begin(), dw_.end(), 0.0);
}

// The online rule (16)-(19), derived.
//
// There is no target for u_n, so the training error is the control error
// e = V_ref - V_L and the cost is E = e^2 / 2. Gradient descent:
//   dE/dw = -e * dV_L/dw = -e * (dV_L/dU_n) * (du_n/dw)
//   Delta w = -eta dE/dw = eta * e * (du_n/dw) * (dV_L/dU_n).
// Back-propagation with the output error e gives exactly the first factors:
// delta_out o = e * f'(z_out) * o, and for hidden weights delta_j o_i =
// e * du_n/dw_ji, so eta (delta o) of (16) is eta * e * du_n/dw (gradient()).
// The missing plant sensitivity dV_L/dU_n is what (17) supplies:
//   dV_L/dU_n ~ (dV_L/dt) / (dU_n/dt) = a_L / U_n_dot = k_c,
// with U_n_dot from the backward difference (18). Hence (19):
//   Delta w(n+1) = eta * e * (du_n/dw) * k_c + alpha * k_c * Delta w(n).
// Here U_n is the network output u_n (G_n is a constant factor that eta absorbs).
// The approximation holds when V_L follows U_n quasi-statically; the sign of
// k_c carries the sign of the plant's response, so a plant that moves the
// other way reverses the update.
//
// Timing of (18): a_L(k) is measured at tick k, before u_n(k) acts; it is the
// response to the force applied over the last period, i.e. to the change
// u_n(k-1) - u_n(k-2). So k_c pairs a_L(k) with that change:
//   U_n_dot(k) = (u_n(k-1) - u_n(k-2)) / T_s.
// Pairing it with u_n(k) - u_n(k-1) (a change that has had no effect yet)
// makes k_c's sign follow the network's tick-to-tick zig-zag rather than the
// plant: on the toy plant of rnn_test.cpp the learning then drives the network
// into saturation instead of reducing the error.
//
// Guards (the paper argues k_c stays bounded because updates stop inside the
// tolerance; a running controller needs it explicitly):
//   - |U_n_dot| < du_deadband: k_c is undefined (0/0 near steady state or a
//     saturated network): no update this tick, momentum kept (counted kc_deadband).
//     Note that the output then only moves through its inputs: with constant
//     inputs a converged network stays put even if the error grows again;
//   - |k_c| > kc_limit: clamped to +-kc_limit (counted kc_clamped). With
//     alpha * kc_limit < 1 the momentum term alpha k_c Delta w(n) contracts,
//     so Delta w cannot grow by the momentum alone;
//   - an update that would make any weight non-finite is not applied and the
//     momentum is cleared (counted reverted_updates).
CompensatorStep RnnCompensator::step(const CompensatorInput& in) {
  CompensatorStep out;
  ++counters_.steps;
  const double s = params_.input_scale_s2_per_m;
  const double signal_mps2 =
      params_.on_reference_error ? in.load_accel_mps2 - in.reference_accel_mps2 : in.load_accel_mps2;
  const double x = s * signal_mps2;
  if (!all_finite(in.load_accel_mps2, in.v_ref_mps, in.v_load_mps, x)) {
    ++counters_.rejected_inputs;
    out.input_rejected = true;
    return out;
  }
  // Inputs: s a_L(k), s a_L(k-1), ..., s a_L(k-m+1) (or of the error); the state unit is inside net_.
  for (std::size_t i = inputs_.size() - 1; i > 0; --i) inputs_[i] = inputs_[i - 1];
  inputs_[0] = x;

  const double u_prev = net_.state_unit();  // u_n(k-1)
  const double u = net_.forward(inputs_.data());
  out.u_n = u;
  const bool at_rest =
      std::abs(in.command_mps) <= params_.rest_velocity_mps && std::abs(in.v_ref_mps) <= params_.rest_velocity_mps;
  rest_ticks_ = at_rest ? rest_ticks_ + 1 : 0;
  out.force_n = params_.gain_n * params_.output_scale * (u - rest_share() * rest_output_);
  const double e = in.v_ref_mps - in.v_load_mps;
  out.training_error_mps = e;

  if (params_.online_learning && std::abs(e) > params_.tolerance_mps) {
    const double du_dt = (u_prev - u_prev2_) / params_.period_s;  // (18), see above
    if (!(std::abs(du_dt) >= params_.du_deadband_per_s)) {
      ++counters_.kc_deadband;
      out.kc_guarded = true;
    } else {
      double kc = in.load_accel_mps2 / du_dt;  // (17)
      if (!(std::abs(kc) <= params_.kc_limit_mps)) {
        kc = std::copysign(params_.kc_limit_mps, kc);
        ++counters_.kc_clamped;
        out.kc_guarded = true;
      }
      out.k_c_mps = kc;
      net_.gradient(grad_.data());
      const double eta = params_.learning_rate, alpha = params_.momentum;
      for (std::size_t i = 0; i < grad_.size(); ++i) {
        next_dw_[i] = eta * e * grad_[i] * kc + alpha * kc * dw_[i];  // (19)
      }
      if (net_.add_to_weights(next_dw_.data())) {
        dw_.swap(next_dw_);
        ++counters_.updates;
        out.weights_updated = true;
      } else {
        std::fill(dw_.begin(), dw_.end(), 0.0);
        ++counters_.reverted_updates;
      }
    }
  }
  u_prev2_ = u_prev;
  net_.commit_output();
  if (params_.online_learning && params_.remove_rest_output) {
    // The weights move, and u* with them: one pass of the fixed-point iteration a tick (from the
    // last u*) follows it without a thousand passes in the loop.
    const double next = net_.output_with_no_signal(rest_output_);
    if (std::isfinite(next)) rest_output_ = next;
  }
  return out;
}

}  // namespace pmlsm
