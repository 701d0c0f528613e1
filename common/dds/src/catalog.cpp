#include "pmlsm/dds/catalog.hpp"

#include <fastdds/dds/topic/TopicDataType.hpp>

#include <memory>
#include <stdexcept>
#include <utility>

#include "AgentAnnouncePubSubTypes.h"
#include "CompensatorOutputPubSubTypes.h"
#include "CurrentFeedbackPubSubTypes.h"
#include "DriveControlPubSubTypes.h"
#include "DriveStatePubSubTypes.h"
#include "EstimatedStatePubSubTypes.h"
#include "EvaluationRequestPubSubTypes.h"
#include "EvaluationResultPubSubTypes.h"
#include "ForceCommandPubSubTypes.h"
#include "LaunchRequestPubSubTypes.h"
#include "MotorFeedbackPubSubTypes.h"
#include "NetworkWeightsPubSubTypes.h"
#include "NodeExitPubSubTypes.h"
#include "NodeOutputPubSubTypes.h"
#include "NodeStatusPubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "TrainerProgressPubSubTypes.h"
#include "TrainingSetupPubSubTypes.h"
#include "VelocityReferencePubSubTypes.h"
#include "VelocitySetpointPubSubTypes.h"
#include "VoltageCommandPubSubTypes.h"
#include "WorkerStatusPubSubTypes.h"

namespace pmlsm::dds {
namespace {

struct EmbeddedSchema {
  const char* short_name;
  const char* idl;
};

constexpr EmbeddedSchema kSchemas[] = {
#include "idl_schemas.inc"
};

std::string schema_of(const std::string& short_name) {
  for (const auto& schema : kSchemas) {
    if (short_name == schema.short_name) return schema.idl;
  }
  throw std::logic_error("no embedded IDL for type " + short_name);
}

template <typename PubSubType>
CatalogEntry entry(const TopicSpec& spec, const std::string& short_name) {
  const PubSubType type;  // for its registered name and size bound, as the typed nodes use them
  return CatalogEntry{spec, type.getName(), schema_of(short_name), type.m_typeSize};
}

std::vector<CatalogEntry> make_catalog() {
  namespace msg = pmlsm_msgs::msg;
  return {
      entry<msg::MotorFeedbackPubSubType>(topics::kMotorFeedback, "MotorFeedback"),
      entry<msg::ForceCommandPubSubType>(topics::kForceCommand, "ForceCommand"),
      entry<msg::CurrentFeedbackPubSubType>(topics::kCurrentFeedback, "CurrentFeedback"),
      entry<msg::VoltageCommandPubSubType>(topics::kVoltageCommand, "VoltageCommand"),
      entry<msg::PlantTruthPubSubType>(topics::kPlantTruth, "PlantTruth"),
      entry<msg::VelocityReferencePubSubType>(topics::kVelocityReference, "VelocityReference"),
      entry<msg::EstimatedStatePubSubType>(topics::kEstimatedState, "EstimatedState"),
      entry<msg::DriveControlPubSubType>(topics::kDriveControl, "DriveControl"),
      entry<msg::DriveStatePubSubType>(topics::kDriveState, "DriveState"),
      entry<msg::CompensatorOutputPubSubType>(topics::kCompensatorOutput, "CompensatorOutput"),
      entry<msg::NodeStatusPubSubType>(topics::kNodeStatus, "NodeStatus"),
      entry<msg::NetworkWeightsPubSubType>(topics::kNetworkWeights, "NetworkWeights"),
      entry<msg::TrainerProgressPubSubType>(topics::kTrainerProgress, "TrainerProgress"),
      entry<msg::TrainingSetupPubSubType>(topics::kTrainingSetup, "TrainingSetup"),
      entry<msg::EvaluationRequestPubSubType>(topics::kEvaluationRequest, "EvaluationRequest"),
      entry<msg::EvaluationResultPubSubType>(topics::kEvaluationResult, "EvaluationResult"),
      entry<msg::WorkerStatusPubSubType>(topics::kWorkerStatus, "WorkerStatus"),
      entry<msg::VelocitySetpointPubSubType>(topics::kVelocitySetpoint, "VelocitySetpoint"),
      entry<msg::AgentAnnouncePubSubType>(topics::kAgentAnnounce, "AgentAnnounce"),
      entry<msg::LaunchRequestPubSubType>(topics::kLaunchRequest, "LaunchRequest"),
      entry<msg::NodeOutputPubSubType>(topics::kNodeOutput, "NodeOutput"),
      entry<msg::NodeExitPubSubType>(topics::kNodeExit, "NodeExit"),
  };
}

}  // namespace

const std::vector<CatalogEntry>& catalog() {
  static const std::vector<CatalogEntry> entries = make_catalog();  // immutable after first use
  return entries;
}

std::string display_name(std::string_view dds_topic_name) {
  if (dds_topic_name.substr(0, 3) == "rt/") return "/" + std::string(dds_topic_name.substr(3));
  return std::string(dds_topic_name);
}

const CatalogEntry* find_topic(std::string_view name) {
  std::string dds_name(name);
  if (name.substr(0, 3) != "rt/") {
    dds_name = "rt/" + std::string(name.substr(0, 1) == "/" ? name.substr(1) : name);
  }
  for (const auto& e : catalog()) {
    if (dds_name == e.spec.name) return &e;
  }
  return nullptr;
}

const CatalogEntry* find_type(std::string_view type_name) {
  for (const auto& e : catalog()) {
    if (type_name == e.type_name) return &e;
  }
  return nullptr;
}

std::string known_topics_list() {
  std::string out;
  for (const auto& e : catalog()) out += "  " + display_name(e.spec.name) + "  (" + e.type_name + ")\n";
  return out;
}

}  // namespace pmlsm::dds
