// Velocity PI, current controller, reference model and the exact discretisation.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/util/discretize.hpp"
#include "pmlsm/plant/encoder_velocity.hpp"
#include "pmlsm/control/reference_model.hpp"
#include "pmlsm/control/velocity_pi.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

const double kNan = std::numeric_limits<double>::quiet_NaN();

// e^{M} by its Taylor series with scaling and squaring: an independent check
// of Eigen's Pade-based exponential.
Eigen::MatrixXd taylor_exp(const Eigen::MatrixXd& m) {
  int squarings = 0;
  Eigen::MatrixXd scaled = m;
  while (scaled.lpNorm<Eigen::Infinity>() > 0.1) {
    scaled /= 2.0;
    ++squarings;
  }
  Eigen::MatrixXd sum = Eigen::MatrixXd::Identity(m.rows(), m.cols());
  Eigen::MatrixXd term = sum;
  for (int k = 1; k < 30; ++k) {
    term = term * scaled / static_cast<double>(k);
    sum += term;
  }
  for (int i = 0; i < squarings; ++i) sum = sum * sum;
  return sum;
}

TEST(Discretize, ScalarSystemMatchesClosedForm) {
  Eigen::MatrixXd a(1, 1), b(1, 1);
  a << -2.0;
  b << 3.0;
  const DiscreteModel d = discretize_zoh(a, b, 0.1);
  EXPECT_NEAR(d.phi(0, 0), std::exp(-0.2), 1e-15);
  EXPECT_NEAR(d.gamma(0, 0), 3.0 * (1.0 - std::exp(-0.2)) / 2.0, 1e-15);
}

TEST(Discretize, KalmanModelMatchesIndependentMatrixExponential) {
  const KalmanParams kp = test::shipped_params().kalman_params();
  const Eigen::Matrix3d a = KalmanFilter::continuous_a(kp);
  const Eigen::Vector3d b = KalmanFilter::continuous_b(kp);
  const DiscreteModel d = discretize_zoh(a, b, kp.period_s);
  Eigen::MatrixXd aug = Eigen::MatrixXd::Zero(4, 4);
  aug.topLeftCorner(3, 3) = a * kp.period_s;
  aug.topRightCorner(3, 1) = b * kp.period_s;
  const Eigen::MatrixXd e = taylor_exp(aug);
  EXPECT_LT((d.phi - e.topLeftCorner(3, 3)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((d.gamma - e.topRightCorner(3, 1)).cwiseAbs().maxCoeff(), 1e-15);
  // And the filter uses exactly these matrices, not a forward-Euler step.
  KalmanFilter kf(kp);
  EXPECT_LT((kf.phi() - d.phi).cwiseAbs().maxCoeff(), 1e-15);
  const Eigen::Matrix3d euler = Eigen::Matrix3d::Identity() + a * kp.period_s;
  EXPECT_GT((kf.phi() - euler).cwiseAbs().maxCoeff(), 1e-4);
}

TEST(Discretize, RejectsBadInput) {
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(2, 2), b = Eigen::MatrixXd::Zero(3, 1);
  EXPECT_THROW(discretize_zoh(a, b, 1e-3), std::invalid_argument);
  EXPECT_THROW(discretize_zoh(a, Eigen::MatrixXd::Zero(2, 1), 0.0), std::invalid_argument);
  a(0, 0) = kNan;
  EXPECT_THROW(discretize_zoh(a, Eigen::MatrixXd::Zero(2, 1), 1e-3), std::invalid_argument);
}

TEST(ReferenceModel, MatchesAnalyticStepResponse) {
  // G(s) = wn^2 / (s^2 + 2 zeta wn s + wn^2), over-damped: poles p1, p2 < 0 and
  // y(t) = 1 + (p2 e^{p1 t} - p1 e^{p2 t}) / (p1 - p2). A ZOH-exact model hits
  // it at every sample of a step.
  const SystemParams& sp = test::shipped_params();
  ReferenceModel model(sp.reference_model_params());
  const double wn = sp.reference_model.natural_frequency_rad_s;
  const double zeta = sp.reference_model.damping_ratio;
  const double root = wn * std::sqrt(zeta * zeta - 1.0);
  const double p1 = -zeta * wn + root, p2 = -zeta * wn - root;
  EXPECT_NEAR(p1, -31.8, 0.1);  // the paper-digest's handy numbers
  EXPECT_NEAR(p2, -314.6, 0.5);
  const double period = sp.timing.control_period_s;
  for (int k = 1; k <= 300; ++k) {
    const ReferenceSample s = model.step(0.2);
    const double t = k * period;
    const double y = 1.0 + (p2 * std::exp(p1 * t) - p1 * std::exp(p2 * t)) / (p1 - p2);
    const double dy = p1 * p2 * (std::exp(p1 * t) - std::exp(p2 * t)) / (p1 - p2);
    ASSERT_NEAR(s.velocity_mps, 0.2 * y, 1e-12) << "k " << k;
    ASSERT_NEAR(s.accel_mps2, 0.2 * dy, 1e-9) << "k " << k;
  }
}

TEST(ReferenceModel, HoldsLastCommandOnNaN) {
  ReferenceModel a(test::shipped_params().reference_model_params());
  ReferenceModel b(test::shipped_params().reference_model_params());
  for (int k = 0; k < 50; ++k) {
    const double ra = a.step(0.2).velocity_mps;
    const double rb = b.step(k == 10 || k == 11 ? kNan : 0.2).velocity_mps;
    EXPECT_EQ(ra, rb);
  }
  EXPECT_EQ(b.rejected_inputs(), 2u);
}

TEST(VelocityPi, ProportionalIntegralAndSaturation) {
  VelocityPiParams p{10000.0, 0.01, 1e-3, 675.0};
  VelocityPi pi(p);
  VelocityPiOutput out = pi.step({0.01, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(out.force_n, 100.0);  // Kp e, the integral starts at zero
  out = pi.step({0.01, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(out.force_n, 100.0 + 0.01 * 1e-3 * 0.01);
  out = pi.step({0.5, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(out.force_n, 675.0);
  EXPECT_TRUE(out.saturated);
  out = pi.step({-0.5, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(out.force_n, -675.0);
  out = pi.step({0.0, 0.0, 50.0});  // the compensator's force is added inside the limit
  EXPECT_NEAR(out.force_n, 50.0, 1e-6);
}

TEST(VelocityPi, ConditionalIntegrationStopsWindUp) {
  VelocityPiParams p{100.0, 5000.0, 1e-3, 50.0};
  VelocityPi pi(p);
  for (int k = 0; k < 1000; ++k) pi.step({1.0, 0.0, 0.0});  // saturated for a second
  EXPECT_LT(pi.integral_n(), 50.0);
  // Without the guard the integral would be 5000 N and take a second to unwind:
  // with it, a reversed error leaves saturation at once.
  const VelocityPiOutput out = pi.step({0.0, 0.4, 0.0});
  EXPECT_LT(out.force_n, 0.0);
}

TEST(VelocityPi, RejectsNonFiniteInputAndHolds) {
  VelocityPi pi(VelocityPiParams{10000.0, 0.01, 1e-3, 675.0});
  const double held = pi.step({0.01, 0.0, 0.0}).force_n;
  EXPECT_EQ(pi.step({kNan, 0.0, 0.0}).force_n, held);
  EXPECT_EQ(pi.step({0.0, std::numeric_limits<double>::infinity(), 0.0}).force_n, held);
  EXPECT_EQ(pi.step({0.0, 0.0, kNan}).force_n, held);
  EXPECT_EQ(pi.counters().rejected_inputs, 3u);
  EXPECT_THROW(VelocityPi(VelocityPiParams{10000.0, 0.01, 1e-3, -1.0}), std::invalid_argument);
}

TEST(CurrentController, DecouplingAndVoltageLimit) {
  const CurrentControllerParams p = test::shipped_params().current_controller_params();
  CurrentController cc(p);
  // At rest with zero error, only the back-EMF feed-forward is left: zero here.
  CurrentControllerOutput out = cc.step({0.0, 0.0, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(out.u_q_v, 0.0);
  // Moving at 1 m/s with the current on target: u_q = w_s psi_pm, u_d = -w_s L_q i_q.
  cc.reset();
  const double i_q = 100.0 / p.motor_constant_n_per_a;
  out = cc.step({100.0, 0.0, i_q, 1.0});
  const double w_s = 3.14159265358979323846 / p.pole_pitch_m;
  EXPECT_NEAR(out.u_q_v, w_s * p.permanent_magnet_flux_wb, 1e-9);
  EXPECT_NEAR(out.u_d_v, -w_s * p.armature_q_inductance_h * i_q, 1e-9);
  // A large error saturates the voltage vector on the circle, and the request is current-limited.
  cc.reset();
  out = cc.step({5000.0, 0.0, 0.0, 0.0});
  EXPECT_TRUE(out.voltage_limited);
  EXPECT_TRUE(out.current_limited);
  EXPECT_DOUBLE_EQ(out.i_q_ref_a, p.current_limit_a);
  EXPECT_NEAR(std::hypot(out.u_d_v, out.u_q_v), p.voltage_limit_v, 1e-9);
  EXPECT_EQ(cc.counters().voltage_limited, 1u);
}

TEST(CurrentController, RejectsNonFiniteInput) {
  CurrentController cc(test::shipped_params().current_controller_params());
  const CurrentControllerOutput good = cc.step({100.0, 0.0, 0.0, 0.0});
  const CurrentControllerOutput held = cc.step({100.0, kNan, 0.0, 0.0});
  EXPECT_EQ(held.u_q_v, good.u_q_v);
  EXPECT_EQ(cc.counters().rejected_inputs, 1u);
}

TEST(EncoderVelocity, BackwardDifferenceAndRejection) {
  EncoderVelocity ev(1e-3);
  ev.reset(0.5);
  EXPECT_NEAR(ev.step(0.500002), 0.002, 1e-12);
  EXPECT_NEAR(ev.step(0.500003), 0.001, 1e-12);
  EXPECT_NEAR(ev.step(kNan), 0.001, 1e-12);
  EXPECT_EQ(ev.rejected_inputs(), 1u);
  EXPECT_THROW(EncoderVelocity(0.0), std::invalid_argument);
}

}  // namespace
}  // namespace pmlsm
