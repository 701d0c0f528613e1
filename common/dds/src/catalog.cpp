#include "pmlsm/dds/catalog.hpp"
#include "pmlsm/dds/ros2_names.hpp"
#include "pmlsm/introspect/ros2_msg.hpp"

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
#include "ParameterEventPubSubTypes.h"
#include "ParameterRequestPubSubTypes.h"
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
    const std::string idl = schema_of(short_name_of(type.getName()));
    const InterfaceName name = interface_name(type.getName());
    entries.push_back(CatalogEntry{topic, type.getName(), ros2_type_name(type.getName()), idl,
                                   introspect::ros2_message_definition(idl, name.package, name.type), type.m_typeSize});
  });
  return entries;
}

}  // namespace

const std::vector<CatalogEntry>& catalog() {
  static const std::vector<CatalogEntry> kEntries = make_catalog();  // immutable after first use
  return kEntries;
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

RecordingProfile recording_profile_from_string(const std::string& text) {
  if (text == "omgidl") return RecordingProfile::kOmgIdl;
  if (text == "ros2") return RecordingProfile::kRos2;
  throw std::invalid_argument("unknown recording profile '" + text + "' (omgidl or ros2)");
}

RecordedSchema recorded_schema(const CatalogEntry& entry, RecordingProfile profile) {
  if (profile == RecordingProfile::kRos2) {
    return {ros2_interface_path(entry.type_name), "ros2msg", entry.ros2_definition};
  }
  return {entry.type_name, "omgidl", entry.schema_idl};
}

const CatalogEntry* recorded_entry(const std::string& topic, const RecordedSchema& schema, std::string& why) {
  const CatalogEntry* entry = find_topic(topic);
  if (entry == nullptr) {
    why = "not a project topic";
    return nullptr;
  }
  if (schema.encoding != "omgidl" && schema.encoding != "ros2msg") {
    why = "schema encoding '" + schema.encoding + "' (a recording of ours has omgidl or ros2msg)";
    return nullptr;
  }
  const RecordedSchema expected =
      recorded_schema(*entry, schema.encoding == "ros2msg" ? RecordingProfile::kRos2 : RecordingProfile::kOmgIdl);
  if (schema.name != expected.name) {
    why = "schema '" + schema.name + "', but the topic carries " + expected.name;
    return nullptr;
  }
  // An omgidl schema of an older build may differ in comments or added types and still decode
  // (the decoders read it); a ros2msg definition is ROS 2's contract and must be ours.
  if (schema.encoding == "ros2msg" && schema.data != expected.data) {
    why = "its ros2msg definition of " + schema.name + " differs from this build's";
    return nullptr;
  }
  return entry;
}

}  // namespace pmlsm::dds
