// Every topic of the system with its message type and that type's schema, for the tools that
// handle topics without knowing their C++ types: the recorder and player, `pmlsm topic`, the
// Foxglove bridge. The schema is the flattened IDL ('omgidl' in MCAP and Foxglove): Stamp.idl
// followed by the message's own file, '#include' lines removed, generated from idl/ at build time.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "pmlsm/dds/topics.hpp"

namespace pmlsm::dds {

struct CatalogEntry {
  TopicSpec spec;                         // DDS topic name ("rt/pmlsm/...") and its QoS profile
  std::string type_name;                  // IDL type name, e.g. "pmlsm_msgs::msg::MotorFeedback"
  std::string wire_type_name;             // registered DDS type name: ROS 2's (ros2_names.hpp)
  std::string schema_idl;                 // flattened IDL text defining type_name
  std::string ros2_definition;            // the same type as ROS 2's .msg text with its dependencies
  std::uint32_t max_serialized_size = 0;  // bound of one sample's CDR, encapsulation included [bytes]
};

/// All project topics, in a fixed order (control topics first).
const std::vector<CatalogEntry>& catalog();

/// The entry for a topic given as "rt/pmlsm/x", "/pmlsm/x" (ROS 2 style) or "pmlsm/x"; nullptr
/// when it is not a project topic.
const CatalogEntry* find_topic(std::string_view name);

/// The entry whose type is `type_name`; nullptr when there is none.
const CatalogEntry* find_type(std::string_view type_name);

/// How a recording describes its messages (MCAP's well-known profiles): omgidl, the flattened IDL
/// (schema encoding "omgidl", Foxglove's), or ros2, ROS 2's .msg definitions (schema encoding
/// "ros2msg", named "pmlsm_msgs/msg/X": rosbag2's). The messages are the same CDR bytes in both.
enum class RecordingProfile { kOmgIdl, kRos2 };

/// "omgidl" or "ros2". @throws std::invalid_argument naming both.
RecordingProfile recording_profile_from_string(const std::string& text);

struct RecordedSchema {
  std::string name;
  std::string encoding;
  std::string data;
};

/// The schema record a recording of `profile` writes for a topic's type.
RecordedSchema recorded_schema(const CatalogEntry& entry, RecordingProfile profile);

/// The project topic a recorded channel carries, when its schema is one of ours for that topic's
/// type in either profile (the same name and encoding; a ros2msg definition also the same text);
/// else nullptr and `why` says what does not match. A player decodes and publishes only these.
const CatalogEntry* recorded_entry(const std::string& topic, const RecordedSchema& schema, std::string& why);

/// "rt/pmlsm/x" -> "/pmlsm/x", the name ROS 2 and Foxglove users see.
std::string display_name(std::string_view dds_topic_name);

/// The known topic names (display form), one per line, for "unknown topic" errors.
std::string known_topics_list();

}  // namespace pmlsm::dds
