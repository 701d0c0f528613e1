// Topics every identity is granted beside what the policy lists (configs/security/policy.yaml),
// as SROS2 grants every ROS 2 node.
#pragma once

namespace pmlsm::security {

/// ROS 2's graph announcement (common/dds's ros2_graph.hpp): each process publishes which nodes it
/// holds and which endpoints are theirs, and may read the others'. Node names and endpoint ids,
/// no data; protected as the governance says for every topic.
inline constexpr const char* kRos2GraphTopic = "ros_discovery_info";

}  // namespace pmlsm::security
