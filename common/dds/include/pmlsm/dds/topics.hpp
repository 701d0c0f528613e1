// Topic names and the QoS profile (configs/dds/profiles.xml) each one uses.
// Names follow the ROS 2 convention ("rt/" prefix) so ROS 2 and Foxglove
// tools list them under /pmlsm/...
#pragma once

namespace pmlsm::dds {

struct TopicSpec {
  const char* name;
  const char* qos_profile;
};

/// Reader profile of observers (evaluator, recorder) on every topic: deep
/// history, so a reader that falls behind a fast lockstep run loses nothing.
inline constexpr const char* kObserverProfile = "pmlsm_observe";

namespace topics {
inline constexpr TopicSpec kMotorFeedback{"rt/pmlsm/motor_feedback", "pmlsm_control"};
inline constexpr TopicSpec kForceCommand{"rt/pmlsm/force_command", "pmlsm_control"};
inline constexpr TopicSpec kCurrentFeedback{"rt/pmlsm/current_feedback", "pmlsm_control"};
inline constexpr TopicSpec kVoltageCommand{"rt/pmlsm/voltage_command", "pmlsm_control"};
inline constexpr TopicSpec kPlantTruth{"rt/pmlsm/plant_truth", "pmlsm_observe"};
inline constexpr TopicSpec kVelocityReference{"rt/pmlsm/velocity_reference", "pmlsm_observe"};
inline constexpr TopicSpec kEstimatedState{"rt/pmlsm/estimated_state", "pmlsm_observe"};
// Setpoints from outside the loop for a controller running an external scenario.
inline constexpr TopicSpec kVelocitySetpoint{"rt/pmlsm/velocity_setpoint", "pmlsm_command"};
inline constexpr TopicSpec kCompensatorOutput{"rt/pmlsm/compensator_output", "pmlsm_control"};
// The drive's power state machine: requests in, its state out (latest kept for late joiners).
inline constexpr TopicSpec kDriveControl{"rt/pmlsm/drive_control", "pmlsm_command"};
inline constexpr TopicSpec kDriveState{"rt/pmlsm/drive_state", "pmlsm_latched"};
inline constexpr TopicSpec kNodeStatus{"rt/pmlsm/node_status", "pmlsm_observe"};
inline constexpr TopicSpec kNetworkWeights{"rt/pmlsm/network_weights", "pmlsm_latched"};
inline constexpr TopicSpec kTrainerProgress{"rt/pmlsm/trainer_progress", "pmlsm_observe"};
// Distributed weight search: de_trainer <-> de_worker.
inline constexpr TopicSpec kTrainingSetup{"rt/pmlsm/training/setup", "pmlsm_latched"};
inline constexpr TopicSpec kEvaluationRequest{"rt/pmlsm/training/request", "pmlsm_observe"};
inline constexpr TopicSpec kEvaluationResult{"rt/pmlsm/training/result", "pmlsm_observe"};
inline constexpr TopicSpec kWorkerStatus{"rt/pmlsm/training/worker_status", "pmlsm_control"};
// Launch agents (`pmlsm agent`) and the launcher that commands them.
inline constexpr TopicSpec kAgentAnnounce{"rt/pmlsm/launch/agent", "pmlsm_latched"};
inline constexpr TopicSpec kLaunchRequest{"rt/pmlsm/launch/request", "pmlsm_command"};
inline constexpr TopicSpec kNodeOutput{"rt/pmlsm/launch/output", "pmlsm_observe"};
inline constexpr TopicSpec kNodeExit{"rt/pmlsm/launch/exit", "pmlsm_observe"};
}  // namespace topics

}  // namespace pmlsm::dds
