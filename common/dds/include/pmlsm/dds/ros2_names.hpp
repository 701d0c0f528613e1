// The names ROS 2 gives our messages on the wire, so `ros2 topic echo`, rosbag2 and PlotJuggler
// match our topics. ROS 2 (ros2/design, "Topic and Service name mapping to DDS"; rmw_fastrtps
// and rmw_cyclonedds alike) registers the message `<package>/msg/<Type>` under the DDS type name
// `<package>::msg::dds_::<Type>_` and publishes topic `/x` as `rt/x`. Our IDL declares each
// message as `<package>::msg::<Type>` (idl/), the name of the interface a ROS 2 user installs.
#pragma once

#include <string>
#include <string_view>

namespace pmlsm::dds {

/// The parts of an IDL type name "<package>::<kind>::<Type>".
struct InterfaceName {
  std::string package;  ///< "pmlsm_msgs": lower case, digits and single underscores (REP 144)
  std::string kind;     ///< "msg" (ROS 2's srv and action are not used here)
  std::string type;     ///< "MotorFeedback": upper camel case, letters and digits
};

/// Splits and checks an IDL type name against ROS 2's rules for package and message names.
/// @throws std::invalid_argument naming the name and the rule it breaks.
InterfaceName interface_name(std::string_view idl_type_name);

/// "pmlsm_msgs::msg::MotorFeedback" -> "pmlsm_msgs::msg::dds_::MotorFeedback_", the DDS type
/// name every writer and reader of ours registers. @throws as interface_name.
std::string ros2_type_name(std::string_view idl_type_name);

/// "pmlsm_msgs::msg::MotorFeedback" -> "pmlsm_msgs/msg/MotorFeedback", the name a ROS 2 tool
/// shows (`ros2 topic list -t`) and an MCAP file of the ros2msg profile uses for its schema.
std::string ros2_interface_path(std::string_view idl_type_name);

}  // namespace pmlsm::dds
