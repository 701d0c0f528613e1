// Topic names, the type each one carries and the QoS profile (configs/dds/profiles.xml) each one
// uses: the one place where a topic and its type meet. Participant::make_writer/make_reader take
// the type from the topic, and the catalog (catalog.hpp) is built from for_each_topic below.
// Names follow the ROS 2 convention ("rt/" prefix) so ROS 2 and Foxglove tools list them under
// /pmlsm/...
#pragma once

// The generated type support (fastddsgen, build/idl), declared only: a topic names its type
// without pulling the generated headers into every file that includes this one.
namespace pmlsm_msgs::msg {
class AgentAnnouncePubSubType;
class CompensatorOutputPubSubType;
class CurrentFeedbackPubSubType;
class DriveControlPubSubType;
class DriveStatePubSubType;
class EstimatedStatePubSubType;
class EvaluationRequestPubSubType;
class EvaluationResultPubSubType;
class ForceCommandPubSubType;
class LaunchRequestPubSubType;
class MotorFeedbackPubSubType;
class NetworkWeightsPubSubType;
class NodeExitPubSubType;
class NodeOutputPubSubType;
class NodeStatusPubSubType;
class ParameterEventPubSubType;
class ParameterRequestPubSubType;
class PlantTruthPubSubType;
class TrainerProgressPubSubType;
class TrainingSetupPubSubType;
class VelocityReferencePubSubType;
class VelocitySetpointPubSubType;
class VoltageCommandPubSubType;
class WorkerStatusPubSubType;
}  // namespace pmlsm_msgs::msg

namespace pmlsm::dds {

struct TopicSpec {
  const char* name;
  const char* qos_profile;
};

/// A topic with the type it carries (a fastddsgen PubSubType).
template <typename PubSubType>
struct Topic : TopicSpec {
  using Type = PubSubType;
  constexpr Topic(const char* topic_name, const char* profile) : TopicSpec{topic_name, profile} {}
};

/// Reader profile of observers (evaluator, recorder) on every topic: deep
/// history, so a reader that falls behind a fast lockstep run loses nothing.
inline constexpr const char* kObserverProfile = "pmlsm_observe";
/// Reader profile of realtime chain inputs that may cross processes or hosts (best effort: a
/// sample repaired late is a tick too late; see configs/dds/profiles.xml).
inline constexpr const char* kRealtimeInputProfile = "pmlsm_realtime_input";

namespace topics {
inline constexpr Topic<pmlsm_msgs::msg::MotorFeedbackPubSubType> kMotorFeedback{"rt/pmlsm/motor_feedback",
                                                                                "pmlsm_control"};
inline constexpr Topic<pmlsm_msgs::msg::ForceCommandPubSubType> kForceCommand{"rt/pmlsm/force_command",
                                                                              "pmlsm_control"};
inline constexpr Topic<pmlsm_msgs::msg::CurrentFeedbackPubSubType> kCurrentFeedback{"rt/pmlsm/current_feedback",
                                                                                    "pmlsm_control"};
inline constexpr Topic<pmlsm_msgs::msg::VoltageCommandPubSubType> kVoltageCommand{"rt/pmlsm/voltage_command",
                                                                                  "pmlsm_control"};
inline constexpr Topic<pmlsm_msgs::msg::PlantTruthPubSubType> kPlantTruth{"rt/pmlsm/plant_truth", "pmlsm_observe"};
inline constexpr Topic<pmlsm_msgs::msg::VelocityReferencePubSubType> kVelocityReference{"rt/pmlsm/velocity_reference",
                                                                                        "pmlsm_observe"};
inline constexpr Topic<pmlsm_msgs::msg::EstimatedStatePubSubType> kEstimatedState{"rt/pmlsm/estimated_state",
                                                                                  "pmlsm_observe"};
// Setpoints from outside the loop for a controller running an external scenario.
inline constexpr Topic<pmlsm_msgs::msg::VelocitySetpointPubSubType> kVelocitySetpoint{"rt/pmlsm/velocity_setpoint",
                                                                                      "pmlsm_command"};
inline constexpr Topic<pmlsm_msgs::msg::CompensatorOutputPubSubType> kCompensatorOutput{"rt/pmlsm/compensator_output",
                                                                                        "pmlsm_control"};
// The drive's power state machine: requests in, its state out (latest kept for late joiners).
inline constexpr Topic<pmlsm_msgs::msg::DriveControlPubSubType> kDriveControl{"rt/pmlsm/drive_control",
                                                                              "pmlsm_command"};
inline constexpr Topic<pmlsm_msgs::msg::DriveStatePubSubType> kDriveState{"rt/pmlsm/drive_state", "pmlsm_latched"};
inline constexpr Topic<pmlsm_msgs::msg::NodeStatusPubSubType> kNodeStatus{"rt/pmlsm/node_status", "pmlsm_observe"};
inline constexpr Topic<pmlsm_msgs::msg::NetworkWeightsPubSubType> kNetworkWeights{"rt/pmlsm/network_weights",
                                                                                  "pmlsm_latched"};
inline constexpr Topic<pmlsm_msgs::msg::TrainerProgressPubSubType> kTrainerProgress{"rt/pmlsm/trainer_progress",
                                                                                    "pmlsm_observe"};
// Distributed weight search: de_trainer <-> de_worker.
inline constexpr Topic<pmlsm_msgs::msg::TrainingSetupPubSubType> kTrainingSetup{"rt/pmlsm/training/setup",
                                                                                "pmlsm_latched"};
inline constexpr Topic<pmlsm_msgs::msg::EvaluationRequestPubSubType> kEvaluationRequest{"rt/pmlsm/training/request",
                                                                                        "pmlsm_observe"};
inline constexpr Topic<pmlsm_msgs::msg::EvaluationResultPubSubType> kEvaluationResult{"rt/pmlsm/training/result",
                                                                                      "pmlsm_observe"};
inline constexpr Topic<pmlsm_msgs::msg::WorkerStatusPubSubType> kWorkerStatus{"rt/pmlsm/training/worker_status",
                                                                              "pmlsm_control"};
// Launch agents (`pmlsm agent`) and the launcher that commands them.
inline constexpr Topic<pmlsm_msgs::msg::AgentAnnouncePubSubType> kAgentAnnounce{"rt/pmlsm/launch/agent",
                                                                                "pmlsm_latched"};
inline constexpr Topic<pmlsm_msgs::msg::LaunchRequestPubSubType> kLaunchRequest{"rt/pmlsm/launch/request",
                                                                                "pmlsm_command"};
inline constexpr Topic<pmlsm_msgs::msg::NodeOutputPubSubType> kNodeOutput{"rt/pmlsm/launch/output", "pmlsm_observe"};
inline constexpr Topic<pmlsm_msgs::msg::NodeExitPubSubType> kNodeExit{"rt/pmlsm/launch/exit", "pmlsm_observe"};
// Live parameters (`pmlsm param`): requests to a node, its answers and the record of its changes
// (kept for late joiners and recordings).
inline constexpr Topic<pmlsm_msgs::msg::ParameterRequestPubSubType> kParameterRequest{"rt/pmlsm/parameter_request",
                                                                                      "pmlsm_command"};
inline constexpr Topic<pmlsm_msgs::msg::ParameterEventPubSubType> kParameterEvent{"rt/pmlsm/parameter_event",
                                                                                  "pmlsm_observe"};
}  // namespace topics

/// Calls f(topic) for every topic above, in the catalog's order (control topics first).
template <typename F>
void for_each_topic(F&& f) {
  f(topics::kMotorFeedback);
  f(topics::kForceCommand);
  f(topics::kCurrentFeedback);
  f(topics::kVoltageCommand);
  f(topics::kPlantTruth);
  f(topics::kVelocityReference);
  f(topics::kEstimatedState);
  f(topics::kDriveControl);
  f(topics::kDriveState);
  f(topics::kCompensatorOutput);
  f(topics::kNodeStatus);
  f(topics::kNetworkWeights);
  f(topics::kTrainerProgress);
  f(topics::kTrainingSetup);
  f(topics::kEvaluationRequest);
  f(topics::kEvaluationResult);
  f(topics::kWorkerStatus);
  f(topics::kVelocitySetpoint);
  f(topics::kAgentAnnounce);
  f(topics::kLaunchRequest);
  f(topics::kNodeOutput);
  f(topics::kNodeExit);
  f(topics::kParameterRequest);
  f(topics::kParameterEvent);
}

}  // namespace pmlsm::dds
