// The simulated servo drive: the plant with the drive's own current loop
// (31.25 us) closed around it, taking a force command every control tick, as
// a real drive in cyclic-synchronous-torque mode does, and reporting what its
// encoder and current sensors read. Both the in-process loop and the
// plant_sim node run it, so their traces are the same.
#pragma once

#include "pmlsm/control/current_controller.hpp"
#include "pmlsm/drive/drive.hpp"
#include "pmlsm/plant/encoder_velocity.hpp"
#include "pmlsm/plant/load_sensor.hpp"
#include "pmlsm/plant/plant.hpp"
#include "pmlsm/sim/system_params.hpp"

namespace pmlsm {

/// What the drive reports at a control tick.
struct DriveFeedback {
  double encoder_position_m = 0;
  double velocity_mps = 0;  ///< encoder difference over the last tick
  double i_d_a = 0;
  double i_q_a = 0;
  /// The load's sensor (SystemParams::load_sensor; NaN in what it does not measure).
  LoadSensorReading load;
};

class SimulatedDrive {
 public:
  /// @throws std::invalid_argument from the plant or current controller parameters.
  SimulatedDrive(const SystemParams& params, const PlantInitialCondition& initial);

  /// The readings at the present tick. Call once per tick: the encoder
  /// velocity is the difference to the previous call's position.
  DriveFeedback sample();

  /// Holds the force request for one control period: the current loop runs
  /// every current-loop period and the plant integrates between them. The
  /// back-EMF feed-forward uses the velocity of the last sample(), as the
  /// drive's own encoder gives it.
  void apply_force(double force_request_n);

  /// The `voltage` command level: the controller runs the current loop and
  /// sends a voltage for each current-loop period of the tick. measurement()
  /// is what the current sensors and encoder read now; apply_voltage() holds
  /// one voltage for one current-loop period. A tick is
  /// current_steps_per_tick() of these.
  const PlantMeasurement& measurement() const { return last_measurement_; }
  void apply_voltage(double u_d_v, double u_q_v);
  int current_steps_per_tick() const { return current_steps_per_tick_; }
  /// The velocity of the last sample(), which the current loop's back-EMF term uses.
  double tick_velocity_mps() const { return last_velocity_mps_; }

  const Plant& plant() const { return plant_; }
  const CurrentController& current_controller() const { return current_; }
  double last_u_d_v() const { return last_u_d_v_; }
  double last_u_q_v() const { return last_u_q_v_; }

 private:
  Plant plant_;
  CurrentController current_;
  EncoderVelocity encoder_velocity_;
  LoadSensor load_sensor_;
  int current_steps_per_tick_;
  double current_period_s_;
  PlantMeasurement last_measurement_;
  double last_velocity_mps_ = 0;
  double last_u_d_v_ = 0;
  double last_u_q_v_ = 0;
};

/// SimulatedDrive behind the drive seam: the simulated drive's own CiA 402 power state machine
/// (force only in operation enabled; quick stop and fault reaction end in zero force at once:
/// the simulation has no stopping ramp of its own). The voltage command level goes around it
/// to simulated() (simulation only: a real drive runs its own current loop). A plant whose
/// state diverges (PlantDivergence) faults the drive: zero force, latched for good.
class SimulatedDriveBackend final : public drive::Drive {
 public:
  /// @throws std::invalid_argument from the plant, current controller or state machine.
  SimulatedDriveBackend(const SystemParams& params, const PlantInitialCondition& initial,
                        const drive::PowerStateParams& power = {});

  drive::Measurement sample() override;
  void apply(double force_n) override;
  drive::TransitionResult request(drive::DriveCommand command) override { return power_.request(command); }
  void fault(std::uint16_t error_code) override { power_.fault(error_code); }
  drive::PowerState power_state() const override { return power_.state(); }
  std::uint16_t error_code() const override { return power_.error_code(); }
  std::uint64_t fault_count() const override { return power_.fault_count(); }
  bool simulated() const override { return true; }
  const char* fault_detail() const override { return fault_detail_; }

  SimulatedDrive& simulated_drive() { return drive_; }
  const SimulatedDrive& simulated_drive() const { return drive_; }

 private:
  SimulatedDrive drive_;
  /// A diverged plant faults the drive (kErrorPlantDiverged), again after every fault reset.
  void check_plant();

  drive::PowerStateMachine power_;
  double motor_constant_n_per_a_;
  std::uint64_t ticks_ = 0;  ///< sample() calls: the tick a divergence is reported at
  char fault_detail_[160] = "";
};

}  // namespace pmlsm
