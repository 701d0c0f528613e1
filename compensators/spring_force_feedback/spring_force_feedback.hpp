// Spring-force feedback, the compensator docs/writing-a-compensator.md builds: F_c = -K_s F_s,
// with F_s the Kalman filter's estimate of the force in the load's spring, k (x_M - x_L), through
// a first-order low-pass.
//
// Why it damps: the stiff velocity PI makes the motor almost a velocity source, so a force F_c
// moves the motor's velocity by about F_c / Kp. With F_s = m_L a_L the load then obeys
//   m_L j_L + k (K_s m_L / Kp) a_L + k v_L = k v_ref,
// a damping ratio zeta = (K_s m_L / Kp) sqrt(k / m_L) / 2: 0.47 at K_s = 40 with Table 2's
// m_L = 4 kg and k = 13700 N/m and Table 3's Kp = 10000 N s/m. It is acceleration feedback
// (accel_feedback, K_a = K_s m_L) that needs no model of the load's mass, and like it, it acts on
// the commanded accelerations too (the load lags V_ref by about K_s m_L / Kp).
//
// The low-pass, y_k = y_(k-1) + alpha (F_s,k - y_(k-1)) with alpha = 1 - exp(-2 pi f_c T), is
// exact for a first-order lag at any cutoff (no Nyquist limit on f_c); at f_c = 100 Hz it delays the
// 10.2 Hz mode by 6 degrees and takes the estimate's noise at 500 Hz (the 1 ms loop's highest
// frequency) to about a fifth.
#pragma once

#include <cmath>
#include <string>

#include "pmlsm/sim/compensator_law.hpp"

namespace pmlsm {

class SpringForceFeedback {
 public:
  static constexpr const char* kSummary = "Spring-force feedback F_c = -K_s F_s on DDS (the compensator tutorial's)";

  struct Params {
    double gain = 40.0;        ///< K_s [N per N of spring force]
    double cutoff_hz = 100.0;  ///< f_c of the low-pass on F_s
    /// Each entry once: its key, its range and why, and whether `live_at` takes it live.
    template <typename Self, typename Visitor>
    static void declare(const std::string& at, Self& p, Visitor& v, const char* live_at) {
      v.real(at + ".gain", p.gain, {0.0, 1000.0, "0 (off) to 1000 N per newton of spring force", live_at});
      v.real(at + ".cutoff_hz", p.cutoff_hz, {0.1, 1e5, "a low-pass on the estimate between 0.1 Hz and 100 kHz"});
    }
  };

  /// @throws std::invalid_argument naming the value refused.
  SpringForceFeedback(const Params& params, double control_period_s) : period_s_(control_period_s) {
    require_positive("control_period_s", control_period_s);
    set_params(params);
  }

  double step(const CompensatorView& view) {
    filtered_n_ += alpha_ * (view.spring_force_n - filtered_n_);
    return -params_.gain * filtered_n_;
  }

  /// Takes effect from the next step; the filter's state is kept.
  void set_params(const Params& params) {
    check_law_params("spring_force_feedback", params);
    params_ = params;
    alpha_ = 1.0 - std::exp(-2.0 * M_PI * params.cutoff_hz * period_s_);
  }

 private:
  double period_s_;
  Params params_;
  double alpha_ = 0;
  double filtered_n_ = 0;  ///< F_s through the low-pass
};

PMLSM_COMPENSATOR(spring_force_feedback, SpringForceFeedback);

}  // namespace pmlsm
