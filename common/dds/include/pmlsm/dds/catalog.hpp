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
  std::uint32_t max_serialized_size = 0;  // bound of one sample's CDR, encapsulation included [bytes]
};

/// All project topics, in a fixed order (control topics first).
const std::vector<CatalogEntry>& catalog();

/// The entry for a topic given as "rt/pmlsm/x", "/pmlsm/x" (ROS 2 style) or "pmlsm/x"; nullptr
/// when it is not a project topic.
const CatalogEntry* find_topic(std::string_view name);

/// The entry whose type is `type_name`; nullptr when there is none.
const CatalogEntry* find_type(std::string_view type_name);

/// "rt/pmlsm/x" -> "/pmlsm/x", the name ROS 2 and Foxglove users see.
std::string display_name(std::string_view dds_topic_name);

/// The known topic names (display form), one per line, for "unknown topic" errors.
std::string known_topics_list();

}  // namespace pmlsm::dds
