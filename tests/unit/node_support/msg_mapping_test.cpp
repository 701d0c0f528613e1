// msg_mapping: every field between the messages and the domain structs. Each field gets its
// own value, so a swapped or forgotten pair fails; the TickRecord mappings are also checked to
// leave every other field of the record alone, and the per-tick ones not to allocate.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "DriveState.h"
#include "msg_mapping.hpp"
#include "allocation_counter.hpp"

namespace pmlsm {
namespace {

namespace msg = pmlsm_msgs::msg;
using node::from_msg;
using node::to_msg;

// Every field of a TickRecord, by name, to compare whole records.
std::vector<std::pair<std::string, double>> fields(const TickRecord& r) {
  return {{"tick", static_cast<double>(r.tick)},
          {"time_s", r.time_s},
          {"command_mps", r.command_mps},
          {"v_ref_mps", r.v_ref_mps},
          {"a_ref_mps2", r.a_ref_mps2},
          {"encoder_position_m", r.encoder_position_m},
          {"motor_velocity_measured_mps", r.motor_velocity_measured_mps},
          {"motor_position_m", r.motor_position_m},
          {"motor_velocity_mps", r.motor_velocity_mps},
          {"load_position_m", r.load_position_m},
          {"load_velocity_mps", r.load_velocity_mps},
          {"load_accel_mps2", r.load_accel_mps2},
          {"spring_force_n", r.spring_force_n},
          {"est_motor_velocity_mps", r.est_motor_velocity_mps},
          {"est_load_velocity_mps", r.est_load_velocity_mps},
          {"est_spring_force_n", r.est_spring_force_n},
          {"est_load_accel_mps2", r.est_load_accel_mps2},
          {"force_command_n", r.force_command_n},
          {"compensation_force_n", r.compensation_force_n},
          {"thrust_n", r.thrust_n},
          {"ripple_n", r.ripple_n},
          {"friction_n", r.friction_n},
          {"i_q_a", r.i_q_a},
          {"u_q_v", r.u_q_v},
          {"applied_force_n", r.applied_force_n},
          {"force_off", r.force_off ? 1.0 : 0.0}};
}

// A record whose every field holds its own value (-1000 - index), none of which a mapping
// below writes.
TickRecord sentinel_record() {
  TickRecord r;
  r.tick = 999;
  double v = -1000;
  for (double* f : {&r.time_s,
                    &r.command_mps,
                    &r.v_ref_mps,
                    &r.a_ref_mps2,
                    &r.encoder_position_m,
                    &r.motor_velocity_measured_mps,
                    &r.motor_position_m,
                    &r.motor_velocity_mps,
                    &r.load_position_m,
                    &r.load_velocity_mps,
                    &r.load_accel_mps2,
                    &r.spring_force_n,
                    &r.est_motor_velocity_mps,
                    &r.est_load_velocity_mps,
                    &r.est_spring_force_n,
                    &r.est_load_accel_mps2,
                    &r.force_command_n,
                    &r.compensation_force_n,
                    &r.thrust_n,
                    &r.ripple_n,
                    &r.friction_n,
                    &r.i_q_a,
                    &r.u_q_v,
                    &r.applied_force_n}) {
    *f = v;
    v -= 1;
  }
  return r;
}

void expect_same_record(const TickRecord& actual, const TickRecord& expected) {
  const auto a = fields(actual);
  const auto e = fields(expected);
  ASSERT_EQ(a.size(), e.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i].second, e[i].second) << a[i].first;
}

msg::Stamp some_stamp() {
  msg::Stamp s;
  s.tick(77);
  s.sim_time_ns(78);
  s.source_time_ns(79);
  s.run_id(0xabcdef);
  return s;
}

void expect_stamp_untouched(const msg::Stamp& s) {
  EXPECT_EQ(s.tick(), 77u);
  EXPECT_EQ(s.sim_time_ns(), 78);
  EXPECT_EQ(s.source_time_ns(), 79);
  EXPECT_EQ(s.run_id(), 0xabcdefu);
}

// ---- PlantTruth ---------------------------------------------------------------------------

PlantTruth distinct_truth() {
  PlantTruth t;
  t.state.psi_d_wb = 1.01;
  t.state.psi_q_wb = 1.02;
  t.state.psi_dd_wb = 1.03;
  t.state.psi_qq_wb = 1.04;
  t.state.motor_position_m = 1.05;
  t.state.motor_velocity_mps = 1.06;
  t.state.load_position_m = 1.07;
  t.state.load_velocity_mps = 1.08;
  t.i_d_a = 1.09;
  t.i_q_a = 1.10;
  t.i_dd_a = 1.11;
  t.i_qq_a = 1.12;
  t.thrust_n = 1.13;
  t.ripple_n = 1.14;
  t.friction_n = 1.15;
  t.spring_force_n = 1.16;
  t.motor_accel_mps2 = 1.17;
  t.load_accel_mps2 = 1.18;
  return t;
}

node::PlantAppliedInputs distinct_applied() { return {2.01, 2.02, 2.03}; }

TEST(MsgMapping, PlantTruthToMsgFieldByField) {
  msg::PlantTruth m;
  m.stamp(some_stamp());
  to_msg(distinct_truth(), distinct_applied(), m);
  EXPECT_EQ(m.motor_position_m(), 1.05);
  EXPECT_EQ(m.motor_velocity_mps(), 1.06);
  EXPECT_EQ(m.motor_acceleration_mps2(), 1.17);
  EXPECT_EQ(m.load_position_m(), 1.07);
  EXPECT_EQ(m.load_velocity_mps(), 1.08);
  EXPECT_EQ(m.load_acceleration_mps2(), 1.18);
  EXPECT_EQ(m.spring_force_n(), 1.16);
  EXPECT_EQ(m.thrust_force_n(), 1.13);
  EXPECT_EQ(m.ripple_force_n(), 1.14);
  EXPECT_EQ(m.friction_force_n(), 1.15);
  EXPECT_EQ(m.command_force_n(), 2.01);
  EXPECT_EQ(m.psi_d_wb(), 1.01);
  EXPECT_EQ(m.psi_q_wb(), 1.02);
  EXPECT_EQ(m.psi_damper_d_wb(), 1.03);
  EXPECT_EQ(m.psi_damper_q_wb(), 1.04);
  EXPECT_EQ(m.i_d_a(), 1.09);
  EXPECT_EQ(m.i_q_a(), 1.10);
  EXPECT_EQ(m.i_damper_d_a(), 1.11);
  EXPECT_EQ(m.i_damper_q_a(), 1.12);
  EXPECT_EQ(m.u_d_v(), 2.02);
  EXPECT_EQ(m.u_q_v(), 2.03);
  expect_stamp_untouched(m.stamp());
}

TEST(MsgMapping, PlantTruthRoundTrip) {
  msg::PlantTruth m;
  const PlantTruth t = distinct_truth();
  const node::PlantAppliedInputs a = distinct_applied();
  to_msg(t, a, m);
  PlantTruth back;
  node::PlantAppliedInputs back_applied;
  from_msg(m, back, back_applied);
  EXPECT_EQ(back.state.psi_d_wb, t.state.psi_d_wb);
  EXPECT_EQ(back.state.psi_q_wb, t.state.psi_q_wb);
  EXPECT_EQ(back.state.psi_dd_wb, t.state.psi_dd_wb);
  EXPECT_EQ(back.state.psi_qq_wb, t.state.psi_qq_wb);
  EXPECT_EQ(back.state.motor_position_m, t.state.motor_position_m);
  EXPECT_EQ(back.state.motor_velocity_mps, t.state.motor_velocity_mps);
  EXPECT_EQ(back.state.load_position_m, t.state.load_position_m);
  EXPECT_EQ(back.state.load_velocity_mps, t.state.load_velocity_mps);
  EXPECT_EQ(back.i_d_a, t.i_d_a);
  EXPECT_EQ(back.i_q_a, t.i_q_a);
  EXPECT_EQ(back.i_dd_a, t.i_dd_a);
  EXPECT_EQ(back.i_qq_a, t.i_qq_a);
  EXPECT_EQ(back.thrust_n, t.thrust_n);
  EXPECT_EQ(back.ripple_n, t.ripple_n);
  EXPECT_EQ(back.friction_n, t.friction_n);
  EXPECT_EQ(back.spring_force_n, t.spring_force_n);
  EXPECT_EQ(back.motor_accel_mps2, t.motor_accel_mps2);
  EXPECT_EQ(back.load_accel_mps2, t.load_accel_mps2);
  EXPECT_EQ(back_applied.command_force_n, a.command_force_n);
  EXPECT_EQ(back_applied.u_d_v, a.u_d_v);
  EXPECT_EQ(back_applied.u_q_v, a.u_q_v);
}

TEST(MsgMapping, PlantTruthIntoTickRecordAsTheInProcessLoopRecordsIt) {
  msg::PlantTruth m;
  to_msg(distinct_truth(), distinct_applied(), m);
  TickRecord r = sentinel_record();
  from_msg(m, r);
  // The in-process loop: record_truth() and the drive's last u_q.
  TickRecord expected = sentinel_record();
  record_truth(distinct_truth(), expected);
  expected.u_q_v = 2.03;
  expect_same_record(r, expected);
  // And by name, so record_truth itself is held to the pairing.
  EXPECT_EQ(r.motor_position_m, 1.05);
  EXPECT_EQ(r.motor_velocity_mps, 1.06);
  EXPECT_EQ(r.load_position_m, 1.07);
  EXPECT_EQ(r.load_velocity_mps, 1.08);
  EXPECT_EQ(r.load_accel_mps2, 1.18);
  EXPECT_EQ(r.spring_force_n, 1.16);
  EXPECT_EQ(r.thrust_n, 1.13);
  EXPECT_EQ(r.ripple_n, 1.14);
  EXPECT_EQ(r.friction_n, 1.15);
  EXPECT_EQ(r.i_q_a, 1.10);
  EXPECT_EQ(r.u_q_v, 2.03);
}

// ---- MotorFeedback ------------------------------------------------------------------------

msg::MotorFeedback distinct_feedback() {
  msg::MotorFeedback m;
  m.stamp(some_stamp());
  m.position_m(3.01);
  m.velocity_mps(3.02);
  m.i_d_a(3.03);
  m.i_q_a(3.04);
  m.thrust_force_n(3.05);
  m.applied_force_n(3.06);
  m.applied_command_tick(3007);
  m.status(msg::MotorFeedback_Constants::STATUS_SAFE_STATE | msg::MotorFeedback_Constants::STATUS_FAULT);
  m.power_state(msg::DriveState_Constants::POWER_FAULT_REACTION_ACTIVE);
  m.error_code(0x8130);
  return m;
}

TEST(MsgMapping, MotorFeedbackIntoTickRecord) {
  TickRecord r = sentinel_record();
  from_msg(distinct_feedback(), r);
  TickRecord expected = sentinel_record();
  expected.encoder_position_m = 3.01;
  expected.motor_velocity_measured_mps = 3.02;
  expected.applied_force_n = 3.06;  // in effect during the previous tick, as the drive says
  expected.force_off = true;        // safe state and fault bits set
  expect_same_record(r, expected);
}

TEST(MsgMapping, MotorFeedbackIntoKalmanInput) {
  KalmanInput in;
  from_msg(distinct_feedback(), in);
  EXPECT_EQ(in.motor_velocity_measured_mps, 3.02);
  EXPECT_EQ(in.thrust_previous_n, 3.06);  // u_{k-1}: what the drive applied, not the thrust estimate
  EXPECT_EQ(in.motor_position_m, 3.01);
}

TEST(MsgMapping, MotorFeedbackIntoDriveTickStatus) {
  node::DriveTickStatus s;
  from_msg(distinct_feedback(), s);
  EXPECT_EQ(s.status, 129u);
  EXPECT_EQ(s.power_state, 6u);
  EXPECT_EQ(s.error_code, 0x8130u);
}

// The drive's reading back out of MotorFeedback (`pmlsm commission` on a live drive): the
// measurement and the force the drive says it held, not the status.
TEST(MsgMapping, MotorFeedbackIntoTheDrivesMeasurement) {
  drive::Measurement m;
  from_msg(distinct_feedback(), m);
  EXPECT_EQ(m.position_m, 3.01);
  EXPECT_EQ(m.velocity_mps, 3.02);
  EXPECT_EQ(m.i_d_a, 3.03);
  EXPECT_EQ(m.i_q_a, 3.04);
  EXPECT_EQ(m.thrust_force_n, 3.05);
  EXPECT_EQ(m.applied_force_n, 3.06);
  EXPECT_TRUE(std::isnan(drive::Measurement{}.applied_force_n));  // a backend's reading: not said
}

// The load's sensor at the tick: NaN in the drive's reading is "not measured", on the wire the
// kind and a 0; back out of the message, the kind decides again.
TEST(MsgMapping, TheLoadsSensorOnTheWireAndBack) {
  const std::uint8_t kinds[3] = {msg::MotorFeedback_Constants::LOAD_SENSOR_NONE,
                                 msg::MotorFeedback_Constants::LOAD_SENSOR_ENCODER,
                                 msg::MotorFeedback_Constants::LOAD_SENSOR_ACCELEROMETER};
  for (int kind = 0; kind < 3; ++kind) {
    drive::TickReport report;
    if (kind == 1) report.measurement.load_position_m = 0.0123;
    if (kind == 2) report.measurement.load_acceleration_mps2 = -4.5;
    report.measurement.load_sensor_saturated = kind == 2;
    report.status = kind == 2 ? drive::status::kLoadSensorSaturated : 0;
    msg::MotorFeedback m;
    to_msg(report, m);
    EXPECT_EQ(m.load_sensor(), kinds[kind]);
    EXPECT_EQ(m.load_position_m(), kind == 1 ? 0.0123 : 0.0);
    EXPECT_EQ(m.load_acceleration_mps2(), kind == 2 ? -4.5 : 0.0);
    drive::Measurement back;
    from_msg(m, back);
    EXPECT_EQ(std::isnan(back.load_position_m), kind != 1);
    EXPECT_EQ(std::isnan(back.load_acceleration_mps2), kind != 2);
    if (kind == 1) {
      EXPECT_EQ(back.load_position_m, 0.0123);
    }
    if (kind == 2) {
      EXPECT_EQ(back.load_acceleration_mps2, -4.5);
    }
    EXPECT_EQ(back.load_sensor_saturated, kind == 2);
  }
}

TEST(MsgMapping, WhatTheLoadsSensorDidForAnEstimateOnTheWireAndBack) {
  namespace c = msg::EstimatedState_Constants;
  struct Case {
    bool used, failed;
    LoadSensorFault problem;
    std::uint8_t use, fault;
    LoadSensorUse record;
  };
  for (const Case& k :
       {Case{false, false, LoadSensorFault::kNone, c::LOAD_SENSOR_NOT_USED, c::LOAD_FAULT_NONE,
             LoadSensorUse::kNotUsed},
        Case{true, false, LoadSensorFault::kNone, c::LOAD_SENSOR_USED, c::LOAD_FAULT_NONE, LoadSensorUse::kUsed},
        Case{false, false, LoadSensorFault::kJumping, c::LOAD_SENSOR_REFUSED, c::LOAD_FAULT_JUMPING,
             LoadSensorUse::kRefused},
        Case{false, true, LoadSensorFault::kStuck, c::LOAD_SENSOR_FAILED, c::LOAD_FAULT_STUCK,
             LoadSensorUse::kFailed}}) {
    KalmanEstimate e;
    e.load_measurement_used = k.used;
    e.load_sensor_failed = k.failed;
    e.load_sensor_problem = k.problem;
    msg::EstimatedState m;
    to_msg(e, 7, m);
    EXPECT_EQ(m.load_sensor_use(), k.use);
    EXPECT_EQ(m.load_sensor_fault(), k.fault);
    KalmanEstimate back;
    from_msg(m, back);
    EXPECT_EQ(back.load_measurement_used, k.used);
    EXPECT_EQ(back.load_sensor_failed, k.failed);
    EXPECT_EQ(back.load_sensor_problem, k.problem);
    TickRecord rec;
    from_msg(m, rec);
    EXPECT_EQ(rec.load_sensor_use, k.record);
    EXPECT_EQ(rec.load_sensor_fault, k.problem);
  }
  // A value past the last from a newer sender: refused, no fault named.
  msg::EstimatedState newer;
  newer.load_sensor_use(9);
  newer.load_sensor_fault(9);
  TickRecord rec;
  from_msg(newer, rec);
  EXPECT_EQ(rec.load_sensor_use, LoadSensorUse::kRefused);
  EXPECT_EQ(rec.load_sensor_fault, LoadSensorFault::kNone);
}

// ---- VelocityReference, ForceCommand ------------------------------------------------------

VelocityControllerOutput distinct_control(bool saturated) {
  VelocityControllerOutput c;
  c.command_mps = 4.01;
  c.v_ref_mps = 4.02;
  c.a_ref_mps2 = 4.03;
  c.force_n = 4.04;
  c.velocity_error_mps = 4.05;
  c.saturated = saturated;
  c.x_ref_m = 4.06;
  return c;
}

TEST(MsgMapping, VelocityReferenceFromTheControllerOutput) {
  msg::VelocityReference m;
  m.stamp(some_stamp());
  to_msg(distinct_control(false), 7, m);
  EXPECT_EQ(m.velocity_command_mps(), 4.01);
  EXPECT_EQ(m.parameters_version(), 7U);
  EXPECT_EQ(m.v_ref_mps(), 4.02);
  EXPECT_EQ(m.a_ref_mps2(), 4.03);
  expect_stamp_untouched(m.stamp());

  TickRecord r = sentinel_record();
  from_msg(m, r);
  TickRecord expected = sentinel_record();
  expected.command_mps = 4.01;
  expected.v_ref_mps = 4.02;
  expected.a_ref_mps2 = 4.03;
  expect_same_record(r, expected);
}

TEST(MsgMapping, ForceCommandFromTheControllerOutput) {
  for (const bool saturated : {true, false}) {
    msg::ForceCommand m;
    m.stamp(some_stamp());
    m.saturated(!saturated);
    to_msg(distinct_control(saturated), 0.25, 5006, m);
    EXPECT_EQ(m.feedback_tick(), 5006u);
    EXPECT_EQ(m.force_n(), 4.04);
    EXPECT_EQ(m.pi_force_n(), 4.04 - 0.25);
    EXPECT_EQ(m.compensation_force_n(), 0.25);
    EXPECT_EQ(m.velocity_error_mps(), 4.05);
    EXPECT_EQ(m.saturated(), saturated);
    EXPECT_EQ(m.v_ref_mps(), 4.02);
    EXPECT_EQ(m.x_ref_m(), 4.06);
    expect_stamp_untouched(m.stamp());

    // The drive loop's setpoint: the force, and the references a drive closing its own loops follows.
    const drive::ForceCommandIn in = from_msg(m, 77, 88);
    EXPECT_EQ(in.run_id, m.stamp().run_id());
    EXPECT_EQ(in.feedback_tick, 5006u);
    EXPECT_EQ(in.force_n, 4.04);
    EXPECT_EQ(in.feedforward_force_n, 0.25);
    EXPECT_EQ(in.velocity_mps, 4.02);
    EXPECT_EQ(in.position_m, 4.06);
    EXPECT_EQ(in.writer_id, 77u);
    EXPECT_EQ(in.received_wall_ns, 88);

    TickRecord r = sentinel_record();
    from_msg(m, r);
    TickRecord expected = sentinel_record();
    expected.force_command_n = 4.04;
    expected.compensation_force_n = 0.25;
    expect_same_record(r, expected);
  }
}

// ---- EstimatedState -----------------------------------------------------------------------

KalmanEstimate distinct_estimate() {
  KalmanEstimate e;
  e.motor_velocity_mps = 6.01;
  e.load_velocity_mps = 6.02;
  e.spring_force_n = 6.03;
  e.load_accel_mps2 = 6.04;
  e.innovation_mps = 6.05;
  e.input_force_n = 6.06;
  e.covariance_diag = Eigen::Vector3d(6.07, 6.08, 6.09);
  e.measurement_used = true;
  e.accelerometer_bias_mps2 = 6.11;
  return e;
}

TEST(MsgMapping, EstimatedStateFromTheKalmanEstimate) {
  msg::EstimatedState m;
  m.stamp(some_stamp());
  to_msg(distinct_estimate(), 6010, m);
  EXPECT_EQ(m.feedback_tick(), 6010u);
  EXPECT_EQ(m.v_motor_mps(), 6.01);
  EXPECT_EQ(m.v_load_mps(), 6.02);
  EXPECT_EQ(m.spring_force_n(), 6.03);
  EXPECT_EQ(m.a_load_mps2(), 6.04);
  EXPECT_EQ(m.innovation_mps(), 6.05);
  EXPECT_EQ(m.input_force_n(), 6.06);
  EXPECT_EQ(m.covariance_diag()[0], 6.07);
  EXPECT_EQ(m.covariance_diag()[1], 6.08);
  EXPECT_EQ(m.covariance_diag()[2], 6.09);
  EXPECT_EQ(m.accelerometer_bias_mps2(), 6.11);
  expect_stamp_untouched(m.stamp());
}

TEST(MsgMapping, CompensatorOutputFromTheLawsStep) {
  namespace flags = msg::CompensatorOutput_Constants;
  CompensatorStep step;
  step.force_n = 7.01;
  step.u_n = 7.02;
  step.training_error_mps = 7.03;
  step.k_c_mps = 7.04;
  step.kc_guarded = true;
  msg::CompensatorOutput m;
  m.stamp(some_stamp());
  to_msg(step, flags::FLAG_ENABLED | flags::FLAG_ONLINE_LEARNING, 7010, 12, m);
  EXPECT_EQ(m.force_n(), 7.01);
  EXPECT_EQ(m.u_n(), 7.02);
  EXPECT_EQ(m.training_error_mps(), 7.03);
  EXPECT_EQ(m.k_c_mps(), 7.04);
  EXPECT_EQ(m.estimate_tick(), 7010u);
  EXPECT_EQ(m.weights_version(), 12u);
  EXPECT_EQ(m.flags(), flags::FLAG_ENABLED | flags::FLAG_ONLINE_LEARNING | flags::FLAG_KC_CLAMPED);
  // The step's own flags each map to theirs; the mode's are the caller's alone.
  step.kc_guarded = false;
  step.weights_updated = true;
  step.input_rejected = true;
  to_msg(step, 0, 7011, 12, m);
  EXPECT_EQ(m.flags(), flags::FLAG_WEIGHTS_UPDATED | flags::FLAG_INPUT_STALE);
  expect_stamp_untouched(m.stamp());
}

TEST(MsgMapping, EstimatedStateRoundTrip) {
  msg::EstimatedState m;
  const KalmanEstimate e = distinct_estimate();
  to_msg(e, 1, m);
  KalmanEstimate back;
  from_msg(m, back);
  EXPECT_EQ(back.motor_velocity_mps, e.motor_velocity_mps);
  EXPECT_EQ(back.load_velocity_mps, e.load_velocity_mps);
  EXPECT_EQ(back.spring_force_n, e.spring_force_n);
  EXPECT_EQ(back.load_accel_mps2, e.load_accel_mps2);
  EXPECT_EQ(back.innovation_mps, e.innovation_mps);
  EXPECT_EQ(back.input_force_n, e.input_force_n);
  EXPECT_EQ(back.covariance_diag, e.covariance_diag);
  EXPECT_EQ(back.accelerometer_bias_mps2, e.accelerometer_bias_mps2);
  EXPECT_FALSE(back.measurement_used);  // not on the wire: left as it was
}

TEST(MsgMapping, EstimatedStateIntoTickRecord) {
  msg::EstimatedState m;
  to_msg(distinct_estimate(), 1, m);
  TickRecord r = sentinel_record();
  from_msg(m, r);
  TickRecord expected = sentinel_record();
  expected.est_motor_velocity_mps = 6.01;
  expected.est_load_velocity_mps = 6.02;
  expected.est_spring_force_n = 6.03;
  expected.est_load_accel_mps2 = 6.04;
  expect_same_record(r, expected);
}

// ---- allocation-free ----------------------------------------------------------------------

TEST(MsgMapping, TheAllocationCounterCounts) {
  const std::size_t before = pmlsm::test::allocations();
  auto* v = new std::vector<double>(100);
  EXPECT_GE(pmlsm::test::allocations(), before + 2);  // the vector and its buffer
  delete v;
}

TEST(MsgMapping, PerTickMappingsDoNotAllocate) {
  // Everything made before the count starts.
  const PlantTruth truth = distinct_truth();
  const node::PlantAppliedInputs applied = distinct_applied();
  const VelocityControllerOutput control = distinct_control(true);
  const KalmanEstimate estimate = distinct_estimate();
  msg::PlantTruth truth_msg;
  msg::MotorFeedback feedback = distinct_feedback();
  msg::VelocityReference reference;
  msg::ForceCommand command;
  msg::EstimatedState estimate_msg;
  msg::CompensatorOutput compensator_msg;
  const CompensatorStep step;
  TickRecord record;
  KalmanInput input;
  node::DriveTickStatus status;
  PlantTruth truth_back;
  node::PlantAppliedInputs applied_back;
  KalmanEstimate estimate_back;

  const std::size_t before = pmlsm::test::allocations();
  to_msg(truth, applied, truth_msg);
  from_msg(truth_msg, truth_back, applied_back);
  from_msg(truth_msg, record);
  from_msg(feedback, record);
  from_msg(feedback, input);
  from_msg(feedback, status);
  to_msg(control, 0, reference);
  from_msg(reference, record);
  to_msg(control, 0.5, 3, command);
  from_msg(command, record);
  to_msg(estimate, 3, estimate_msg);
  from_msg(estimate_msg, estimate_back);
  from_msg(estimate_msg, record);
  to_msg(step, 0, 3, 0, compensator_msg);
  EXPECT_EQ(pmlsm::test::allocations(), before);
}

}  // namespace
}  // namespace pmlsm
