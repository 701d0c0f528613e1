// The Kalman filter of section 3.5.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "pmlsm/closed_loop.hpp"
#include "pmlsm/kalman_filter.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

TEST(Kalman, ModelMatrices34) {
  const KalmanParams p = test::shipped_params().kalman_params();
  const Eigen::Matrix3d a = KalmanFilter::continuous_a(p);
  EXPECT_DOUBLE_EQ(a(0, 2), -1.0 / 20.0);
  EXPECT_DOUBLE_EQ(a(1, 2), 1.0 / 4.0);
  EXPECT_DOUBLE_EQ(a(2, 0), 13700.0);
  EXPECT_DOUBLE_EQ(a(2, 1), -13700.0);
  EXPECT_DOUBLE_EQ(KalmanFilter::continuous_b(p)(0), 1.0 / 20.0);
}

TEST(Kalman, IsConsistentOnItsOwnLinearModel) {
  // Monte Carlo on (26)-(27) simulated exactly, w ~ N(0, Q), v ~ N(0, R) with
  // the paper's Q and R, x_0 ~ N(0, P_0): for a correct filter the normalised
  // estimation error squared e^T P^-1 e is chi-square with 3 degrees of freedom,
  // mean 3. Independent runs, because within one run the errors of v_L and F_s
  // wander slowly (the paper's Q makes their variance large) and successive
  // samples are far from independent.
  const KalmanParams p = test::shipped_params().kalman_params();
  KalmanFilter kf(p);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int runs = 1000, steps = 300;
  double nees_sum = 0;
  for (int run = 0; run < runs; ++run) {
    Eigen::Vector3d x;
    for (int i = 0; i < 3; ++i) x(i) = std::sqrt(p.initial_covariance_diag(i)) * normal(rng);
    kf.reset(Eigen::Vector3d::Zero());
    double u_prev = 0;
    for (int k = 0; k < steps; ++k) {
      x = kf.phi() * x + kf.gamma() * u_prev;
      for (int i = 0; i < 3; ++i) x(i) += std::sqrt(p.process_noise_diag(i)) * normal(rng);
      const double y = x(0) + std::sqrt(p.measurement_noise) * normal(rng);
      kf.step({y, u_prev});
      u_prev = 200.0 * std::sin(0.05 * k);
    }
    const Eigen::Vector3d e = x - kf.state();
    nees_sum += e.dot(kf.covariance().ldlt().solve(e));
  }
  // Standard deviation of the mean: sqrt(6 / 1000) = 0.077; the band is 4 of them.
  EXPECT_NEAR(nees_sum / runs, 3.0, 0.31);
}

TEST(Kalman, TracksLoadVelocityAndSpringForceOnTheNoisyPlant) {
  // The nonlinear plant with encoder noise, friction and ripple, under the
  // pulse reference: the paper's filter (Q, R of eqs. 35) must follow the true
  // load velocity and spring force it never measures.
  SystemParams params = test::shipped_params();
  params.plant.encoder.position_noise_std_m = 2e-6;
  params.plant.encoder.noise_seed = 11;
  const Scenario scenario = test::shipped_scenario("pulse");
  const auto trace = run_scenario(params, scenario);
  double err_v = 0, err_f = 0, sig_v = 0, sig_f = 0;
  std::size_t n = 0;
  for (const TickRecord& r : trace) {
    if (r.time_s < 0.1) continue;  // past the start-up transient
    err_v += std::pow(r.est_load_velocity_mps - r.load_velocity_mps, 2);
    err_f += std::pow(r.est_spring_force_n - r.spring_force_n, 2);
    sig_v += r.load_velocity_mps * r.load_velocity_mps;
    sig_f += r.spring_force_n * r.spring_force_n;
    ++n;
  }
  const double rel_v = std::sqrt(err_v / sig_v), rel_f = std::sqrt(err_f / sig_f);
  std::printf("[ kalman     ] pulse, noisy plant: v_L rms error %.1f %% of rms v_L, F_s %.1f %%\n",
              100 * rel_v, 100 * rel_f);
  EXPECT_LT(rel_v, 0.15);  // measured 8.7 %
  EXPECT_LT(rel_f, 0.25);  // measured 14.8 %
}

TEST(Kalman, RejectsNonFiniteMeasurementAndInput) {
  KalmanFilter kf(test::shipped_params().kalman_params());
  KalmanFilter reference(test::shipped_params().kalman_params());
  kf.step({0.1, 10.0});
  reference.step({0.1, 10.0});
  const KalmanEstimate e = kf.step({std::numeric_limits<double>::quiet_NaN(), 10.0});
  EXPECT_FALSE(e.measurement_used);
  EXPECT_TRUE(kf.state().allFinite());
  kf.step({0.1, std::numeric_limits<double>::infinity()});
  EXPECT_TRUE(kf.state().allFinite());
  EXPECT_EQ(kf.counters().rejected_measurements, 1u);
  EXPECT_EQ(kf.counters().rejected_inputs, 1u);
  // The rejected input was replaced by the last finite one (10 N).
  reference.step({std::numeric_limits<double>::quiet_NaN(), 10.0});
  reference.step({0.1, 10.0});
  EXPECT_LT((kf.state() - reference.state()).norm(), 1e-12);
}

}  // namespace
}  // namespace pmlsm
