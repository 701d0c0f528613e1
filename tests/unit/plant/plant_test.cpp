// The nonlinear plant: physics checks against closed-form results, and the
// integrator's accuracy.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/plant/plant.hpp"
#include "test_support.hpp"

namespace pmlsm {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The plant with the drive's current loop closed around it at 31.25 us: what a
// force command sees.
struct Drive {
  explicit Drive(const SystemParams& p) : params(p), plant(p.plant), current(p.current_controller_params()) {}

  void run(double force_request_n, double duration_s) {
    const double dt = params.timing.current_loop_period_s;
    const int steps = static_cast<int>(std::lround(duration_s / dt));
    for (int i = 0; i < steps; ++i) step(force_request_n);
  }

  PlantMeasurement step(double force_request_n) {
    const CurrentControllerOutput u =
        current.step({force_request_n, last.i_d_a, last.i_q_a, plant.state().motor_velocity_mps});
    last = plant.step({u.u_d_v, u.u_q_v, 0.0}, params.timing.current_loop_period_s);
    return last;
  }

  SystemParams params;
  Plant plant;
  CurrentController current;
  PlantMeasurement last;
};

double mechanical_energy_j(const PlantState& s, const MechanicsParams& m) {
  const double stretch = s.load_position_m - s.motor_position_m;
  return 0.5 * m.motor_mass_kg * s.motor_velocity_mps * s.motor_velocity_mps +
         0.5 * m.load_mass_kg * s.load_velocity_mps * s.load_velocity_mps + 0.5 * m.spring_n_per_m * stretch * stretch;
}

TEST(Plant, FreeTwoMassOscillationIs10Point2Hz) {
  // With the current held at zero by the drive, the motor and load swing
  // freely: w = sqrt(k (1/m_M + 1/m_L)) = 64.1 rad/s, 10.2 Hz (paper-digest).
  Drive drive(test::ideal_params());
  drive.plant.reset({0.0, 0.0, 0.02, 0.0});
  const auto& m = drive.params.plant.mechanics;
  const double expected_hz = std::sqrt(m.spring_n_per_m * (1.0 / m.motor_mass_kg + 1.0 / m.load_mass_kg)) / (2 * kPi);
  EXPECT_NEAR(expected_hz, 10.2, 0.01);

  // Time the upward zero crossings of the spring stretch over 2 s, interpolated.
  const double dt = drive.params.timing.current_loop_period_s;
  std::vector<double> crossings;
  double prev = 0.02;
  for (int i = 1; i <= static_cast<int>(2.0 / dt); ++i) {
    drive.step(0.0);
    const double stretch = drive.plant.state().load_position_m - drive.plant.state().motor_position_m;
    if (prev < 0.0 && stretch >= 0.0) crossings.push_back((i - 1 + prev / (prev - stretch)) * dt);
    prev = stretch;
  }
  ASSERT_GE(crossings.size(), 15u);
  const double period = (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  EXPECT_NEAR(1.0 / period, expected_hz, 0.005 * expected_hz);
}

TEST(Plant, MechanicalEnergyChangesOnlyByTheThrustsWork) {
  // No damping, friction or ripple: E(t) - E(0) must equal the work of the
  // motor thrust (small: the drive holds the current near zero). Any error in
  // the mechanics' integration or signs shows up as a mismatch.
  Drive drive(test::ideal_params());
  drive.plant.reset({0.0, 0.1, 0.02, -0.3});
  const auto& m = drive.params.plant.mechanics;
  const double e0 = mechanical_energy_j(drive.plant.state(), m);
  const double dt = drive.params.timing.current_loop_period_s;
  double work = 0;
  PlantTruth before = drive.plant.truth();
  for (int i = 0; i < static_cast<int>(2.0 / dt); ++i) {
    drive.step(0.0);
    const PlantTruth after = drive.plant.truth();
    work += 0.5 * (before.thrust_n + after.thrust_n) * (after.state.motor_position_m - before.state.motor_position_m);
    before = after;
  }
  const double e1 = mechanical_energy_j(drive.plant.state(), m);
  EXPECT_NEAR(e1 - e0, work, 1e-6 * e0) << "E0 " << e0 << " E1 " << e1 << " W " << work;
  EXPECT_GT(e0, 2.5);
}

TEST(Plant, SteadyThrustIsMotorConstantTimesQCurrent) {
  // Vector control with i_d = 0: once the damper currents have decayed,
  // F_dx = (3p/2)(pi/tau) psi_pm i_q = K_m i_q (14).
  Drive drive(test::ideal_params());
  const double force_n = 300.0;
  drive.run(force_n, 0.03);
  const PlantTruth t = drive.plant.truth();
  const double km = drive.params.plant.electrical.motor_constant_n_per_a;
  EXPECT_NEAR(t.thrust_n, km * t.i_q_a, 1e-3 * force_n);
  EXPECT_NEAR(t.thrust_n, force_n, 0.005 * force_n);
  EXPECT_NEAR(t.i_d_a, 0.0, 1e-3);
  EXPECT_NEAR(t.i_dd_a, 0.0, 1e-3);
  EXPECT_GT(t.state.motor_velocity_mps, 0.1);  // it accelerated, so back-EMF was compensated
}

TEST(Plant, CurrentLoopStepResponse) {
  // i_q* step of 3.19 A (300 N): first-order-like response at the designed
  // 3000 rad/s bandwidth: 10-90 % rise about 0.73 ms, little overshoot.
  Drive drive(test::ideal_params());
  const double dt = drive.params.timing.current_loop_period_s;
  const double target_a = 300.0 / drive.params.plant.electrical.motor_constant_n_per_a;
  double t10 = -1, t90 = -1, peak = 0, at_3ms = 0;
  for (int i = 1; i <= static_cast<int>(0.005 / dt); ++i) {
    const double i_q = drive.step(300.0).i_q_a;
    const double t = i * dt;
    if (t10 < 0 && i_q >= 0.1 * target_a) t10 = t;
    if (t90 < 0 && i_q >= 0.9 * target_a) t90 = t;
    peak = std::max(peak, i_q);
    if (std::abs(t - 0.003) < 0.5 * dt) at_3ms = i_q;
  }
  ASSERT_GT(t10, 0);
  ASSERT_GT(t90, 0);
  EXPECT_GT(t90 - t10, 0.2e-3);
  EXPECT_LT(t90 - t10, 1.2e-3);
  EXPECT_LT(peak, 1.10 * target_a);
  EXPECT_NEAR(at_3ms, target_a, 0.02 * target_a);
}

TEST(Plant, InverterLimitsTheVoltageVector) {
  Plant plant(test::shipped_params().plant);
  plant.step({400.0, 400.0, 0.0}, 1e-4);
  EXPECT_EQ(plant.counters().voltage_limited, 1u);
  plant.step({10.0, 10.0, 0.0}, 1e-4);
  EXPECT_EQ(plant.counters().voltage_limited, 1u);
  EXPECT_NEAR(test::shipped_params().plant.inverter.voltage_limit_v(), 325.0 / std::sqrt(3.0), 1e-12);
}

TEST(Plant, NonFiniteInputIsRejectedAndCounted) {
  Plant plant(test::shipped_params().plant);
  plant.step({0.0, 20.0, 0.0}, 1e-3);
  const PlantState before = plant.state();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  plant.step({nan, 20.0, 0.0}, 1e-3);                                     // the last good input is held instead
  plant.step({0.0, 20.0, 0.0}, std::numeric_limits<double>::infinity());  // nothing moves
  EXPECT_EQ(plant.counters().rejected_inputs, 2u);
  const PlantState& after = plant.state();
  for (double v : {after.psi_d_wb, after.psi_q_wb, after.motor_velocity_mps, after.load_velocity_mps}) {
    EXPECT_TRUE(std::isfinite(v));
  }
  EXPECT_NE(after.motor_position_m, before.motor_position_m);
}

TEST(Plant, EncoderQuantisesToItsResolution) {
  Plant plant(test::shipped_params().plant);
  plant.reset({0.0123456789, 0.0, 0.0123456789, 0.0});
  EXPECT_DOUBLE_EQ(plant.measure().encoder_position_m, 0.012345);
  plant.reset({-0.0000015, 0.0, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(plant.measure().encoder_position_m, -0.000002);  // floor, as counts do
}

TEST(Plant, EncoderNoiseIsSeededAndReproducible) {
  PlantParams p = test::shipped_params().plant;
  p.encoder.position_noise_std_m = 5e-6;
  p.encoder.noise_seed = 42;
  Plant a(p), b(p);
  p.encoder.noise_seed = 43;
  Plant c(p);
  bool differs = false;
  for (int i = 0; i < 20; ++i) {
    const double xa = a.measure().encoder_position_m;
    EXPECT_EQ(xa, b.measure().encoder_position_m);
    differs |= xa != c.measure().encoder_position_m;
  }
  EXPECT_TRUE(differs);
}

// The read head on a compliant mount: e = x_e - x_m obeys e'' + 2 zeta w e' + w^2 e = -x_m'', so
// once its own ring has died out (zeta 0.05 at 100 Hz: 32 ms) it lags the motor by the
// quasi-static -x_m'' / w^2 (to (f / f_e)^2 = 1 %, the motor swinging at 10.2 Hz), and the encoder
// reads the head. A rigid mount reads the motor.
TEST(Plant, EncoderOnACompliantMountReadsTheHeadLaggingTheMotor) {
  SystemParams p = test::ideal_params();
  p.plant.encoder.mount_frequency_hz = 100.0;
  p.plant.encoder.mount_damping = 0.05;
  Drive drive(p);
  drive.plant.reset({0.0, 0.0, 0.02, 0.0});
  const double w = 2 * kPi * 100.0, dt = p.timing.current_loop_period_s;
  double worst_error_m = 0, largest_lag_m = 0;
  for (int i = 1; i <= static_cast<int>(1.0 / dt); ++i) {
    const PlantMeasurement m = drive.step(0.0);
    const PlantTruth t = drive.plant.truth();
    EXPECT_LE(std::abs(m.encoder_position_m - t.encoder_head_position_m), p.plant.encoder.resolution_m);
    if (i * dt < 0.3) continue;
    const double lag_m = -t.state.motor_position_m + t.encoder_head_position_m;
    const double quasi_static_m = -t.motor_accel_mps2 / (w * w);
    worst_error_m = std::max(worst_error_m, std::abs(lag_m - quasi_static_m));
    largest_lag_m = std::max(largest_lag_m, std::abs(quasi_static_m));
  }
  EXPECT_GT(largest_lag_m, 10e-6);
  EXPECT_LT(worst_error_m, 0.03 * largest_lag_m) << worst_error_m << " of " << largest_lag_m;

  Plant rigid(test::shipped_params().plant);
  rigid.reset({0.0123456789, 0.1, 0.0, 0.0});
  EXPECT_EQ(rigid.truth().encoder_head_position_m, rigid.state().motor_position_m);
  p.plant.encoder.mount_damping = 0.0;
  EXPECT_THROW(Plant{p.plant}, std::invalid_argument);  // a compliant mount needs its damping
}

TEST(Plant, FrictionIsExactSignAwayFromZeroAndSmoothThrough) {
  const PlantParams p = test::shipped_params().plant;
  Plant plant(p);
  const double fc = p.friction.coulomb_n, fv = p.friction.viscous_n_s_per_m;
  for (double v : {0.01, -0.2, 1.5}) {
    plant.reset({0.0, v, 0.0, v});
    EXPECT_DOUBLE_EQ(plant.truth().friction_n, -(std::copysign(fc, v) + fv * v)) << v;  // (11)
  }
  plant.reset({0.0, 0.0, 0.0, 0.0});
  EXPECT_EQ(plant.truth().friction_n, 0.0);
  plant.reset({0.0, 0.5 * p.friction.regularisation_velocity_mps, 0.0, 0.0});
  const double inside = plant.truth().friction_n;
  EXPECT_LT(inside, 0.0);
  EXPECT_GT(inside, -fc);
}

TEST(Plant, RippleFollowsEquation10) {
  const PlantParams p = test::shipped_params().plant;
  Plant plant(p);
  for (double x : {0.0031, 0.0177, 0.4}) {
    plant.reset({x, 0.0, x, 0.0});
    const auto& r = p.ripple;
    const double expected = r.scale_n * r.amplitude_1 * std::sin(r.spatial_freq_1_rad_per_m * x) *
                            (r.amplitude_1 + r.amplitude_2 * std::sin(r.spatial_freq_2_rad_per_m * x));
    EXPECT_NEAR(plant.truth().ripple_n, expected, 1e-12);
  }
}

TEST(Plant, InvalidParameterNamesItself) {
  PlantParams p = test::shipped_params().plant;
  p.mechanics.load_mass_kg = -4;
  try {
    Plant plant(p);
    FAIL() << "accepted a negative mass";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("mechanics.load_mass_kg"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("-4"), std::string::npos) << e.what();
  }
}

// Runs the full nonlinear plant (shipped friction and ripple) over 50 ms from a
// moving start, driven by a voltage that changes every 31.25 us, and returns
// the final state. The mover stays well above the friction's smoothed band
// (|v| < 0.2 mm/s), whose kink in the second derivative would blur the order.
PlantState run_reference_trajectory(Integrator integrator, double max_step_s) {
  PlantParams p = test::shipped_params().plant;
  p.integrator = integrator;
  p.max_step_s = max_step_s;
  Plant plant(p);
  plant.reset({0.0, 0.3, 0.005, 0.3});
  const double dt = 31.25e-6;
  for (int i = 0; i < 1600; ++i) {
    const double t = i * dt;
    plant.step({5.0 * std::sin(400 * t), 60.0 * std::sin(90 * t) + 20.0, 0.0}, dt);
  }
  return plant.state();
}

struct StateError {
  double velocity_mps;
  double flux_wb;
};

StateError difference(const PlantState& a, const PlantState& b) {
  return {std::max({std::abs(a.motor_velocity_mps - b.motor_velocity_mps),
                    std::abs(a.load_velocity_mps - b.load_velocity_mps)}),
          std::max({std::abs(a.psi_d_wb - b.psi_d_wb), std::abs(a.psi_q_wb - b.psi_q_wb),
                    std::abs(a.psi_dd_wb - b.psi_dd_wb), std::abs(a.psi_qq_wb - b.psi_qq_wb)})};
}

TEST(PlantIntegrator, ErrorAt10MicrosecondsAndConvergenceOrder) {
  // Reference: RK4 at 10 us / 64. The step the paper uses, 10 us (here 7.8 us:
  // four per 31.25 us current period), must be far more accurate than the
  // encoder (1 mm/s of velocity at 1 ms) and the order must be the method's.
  // The order is read off two larger steps, where the error is far above
  // rounding (RK4's error at 10 us is already near 1e-13).
  const PlantState reference = run_reference_trajectory(Integrator::kRk4, 1e-5 / 64);
  for (Integrator integrator : {Integrator::kRk4, Integrator::kHeun, Integrator::kAdamsBashforth2}) {
    const bool rk4 = integrator == Integrator::kRk4;
    const StateError at_10us = difference(run_reference_trajectory(integrator, 1e-5), reference);
    const double h = rk4 ? 31.25e-6 : 15.625e-6;  // whole fractions of the 31.25 us input period
    const StateError coarse = difference(run_reference_trajectory(integrator, h), reference);
    const StateError fine = difference(run_reference_trajectory(integrator, h / 2), reference);
    const double order = std::log2(coarse.velocity_mps / fine.velocity_mps);
    SCOPED_TRACE(to_string(integrator));
    EXPECT_LT(at_10us.velocity_mps, 1e-6);  // 1000x below the encoder's velocity resolution
    EXPECT_LT(at_10us.flux_wb, 1e-7);
    EXPECT_NEAR(order, rk4 ? 4.0 : 2.0, 0.3) << "errors " << coarse.velocity_mps << " " << fine.velocity_mps;
    std::printf("[ integrator ] %s: velocity error at 10 us %.3g m/s, flux error %.3g Wb, order %.2f\n",
                to_string(integrator), at_10us.velocity_mps, at_10us.flux_wb, order);
  }
}

}  // namespace
}  // namespace pmlsm
