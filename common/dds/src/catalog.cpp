#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/dds/ros2_names.hpp"

#include <fastdds/dds/topic/TopicDataType.hpp>

#include <memory>
#include <type_traits>
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

/// "pmlsm_msgs::msg::MotorFeedback" -> "MotorFeedback": the IDL file's (and its schema's) name.
std::string short_name_of(const std::string& type_name) { return type_name.substr(type_name.rfind(':') + 1); }

std::vector<CatalogEntry> make_catalog() {
  std::vector<CatalogEntry> entries;
  for_each_topic([&entries](const auto& topic) {
    const typename std::decay_t<decltype(topic)>::Type type;  // its registered name and size bound, as nodes use them
    entries.push_back(CatalogEntry{topic, type.getName(), ros2_type_name(type.getName()),
                                   schema_of(short_name_of(type.getName())), type.m_typeSize});
  });
  return entries;
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
