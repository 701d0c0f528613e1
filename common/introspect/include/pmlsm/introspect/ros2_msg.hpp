// ROS 2 interface definitions (.msg) made from our IDL, so a ROS 2 user installs the same
// messages the wire carries (the package built from idl/, `pmlsm ros2-package`) and a recording
// of the ros2msg profile carries definitions rosbag2 and Foxglove read.
//
// Mapping (rosidl's, read backwards): boolean bool, octet/uint8 uint8, char char, intN/uintN
// the same, float float32, double float64, string<N> string<=N, sequence<T, N> T[<=N],
// sequence<T> T[], T name[N] T[N], a struct of <package>::msg its name; the constants of module
// <package>::msg::<Name>_Constants (how rosidl writes a message's constants in IDL) open <Name>.msg.
// Field names must be ROS 2's (lower case, single '_'), constants upper case; enums, nested
// lists and types outside <package>::msg are refused, so what is generated means what the IDL does.
#pragma once

#include <string>
#include <vector>

#include "pmlsm/introspect/cdr_schema.hpp"

namespace pmlsm::introspect {

struct Ros2MessageFile {
  std::string name;  ///< "MotorFeedback": the file msg/MotorFeedback.msg
  std::string text;  ///< constants, a blank line when there are any, then one line per field
};

/// One file per struct of `idl` (in definition order), all of module <package>::msg.
/// @throws SchemaError naming the struct, field or constant that a .msg cannot express.
std::vector<Ros2MessageFile> ros2_message_files(const std::string& idl, const std::string& package);

/// The definition of message `name` as rosbag2 stores it (MCAP schema encoding "ros2msg"): its
/// .msg text, then for each message it uses a line of 80 '=', "MSG: <package>/<Name>" and that
/// message's text. @throws SchemaError as ros2_message_files, or when `name` is not in the IDL.
std::string ros2_message_definition(const std::string& idl, const std::string& package, const std::string& name);

}  // namespace pmlsm::introspect
