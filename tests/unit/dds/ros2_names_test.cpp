// ROS 2's names for our messages (pmlsm/dds/ros2_names.hpp): every topic's type is registered
// under the name ROS 2 gives the message of that package and name, checked here against the rule
// (ros2/design, "Topic and Service name mapping to DDS") and against the IDL schema itself.
#include "pmlsm/dds/ros2_names.hpp"

#include <gtest/gtest.h>

#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "pmlsm/dds/catalog.hpp"

namespace pmlsm::dds {
namespace {

std::vector<std::string> split(const std::string& name, const std::string& separator) {
  std::vector<std::string> parts;
  std::size_t from = 0;
  for (std::size_t at; (at = name.find(separator, from)) != std::string::npos; from = at + separator.size()) {
    parts.push_back(name.substr(from, at - from));
  }
  parts.push_back(name.substr(from));
  return parts;
}

// The struct a schema defines last: the message itself (Stamp.idl comes first, flattened).
std::string last_struct_of(const std::string& idl) {
  const auto at = idl.rfind("struct ");
  if (at == std::string::npos) return "";
  std::istringstream words(idl.substr(at + 7));
  std::string name;
  words >> name;
  return name;
}

TEST(Ros2Names, EveryTopicsTypeIsRegisteredUnderRos2sNameForItsPackageAndMessage) {
  for (const CatalogEntry& entry : catalog()) {
    SCOPED_TRACE(entry.spec.name);
    // <package>::msg::dds_::<Type>_ where the IDL says <package>::msg::<Type>.
    const std::vector<std::string> idl = split(entry.type_name, "::");
    const std::vector<std::string> wire = split(entry.wire_type_name, "::");
    ASSERT_EQ(idl.size(), 3u) << entry.type_name;
    ASSERT_EQ(wire.size(), 4u) << entry.wire_type_name;
    EXPECT_EQ(wire[0], "pmlsm_msgs");
    EXPECT_EQ(wire[0], idl[0]);
    EXPECT_EQ(wire[1], "msg");
    EXPECT_EQ(wire[2], "dds_");
    EXPECT_EQ(wire[3], idl[2] + "_");
    // The message name is the struct the schema defines.
    EXPECT_EQ(idl[2], last_struct_of(entry.schema_idl));
    EXPECT_EQ(ros2_interface_path(entry.type_name), "pmlsm_msgs/msg/" + idl[2]);
  }
}

TEST(Ros2Names, NoTwoTypesShareAWireName) {
  std::set<std::string> wire_names;
  std::set<std::string> types;
  for (const CatalogEntry& entry : catalog()) types.insert(entry.type_name);
  for (const std::string& type : types) {
    EXPECT_TRUE(wire_names.insert(ros2_type_name(type)).second) << type;
  }
}

TEST(Ros2Names, NamesOutsideRos2sRulesAreRefusedWithTheRule) {
  struct Case {
    const char* name;
    const char* rule;
  };
  for (const Case& c : {Case{"pmlsm_msgs::MotorFeedback", "expected <package>::msg::<Type>"},
                        Case{"a::b::msg::MotorFeedback", "expected <package>::msg::<Type>"},
                        Case{"pmlsm_msgs::srv::MotorFeedback", "expected the module 'msg'"},
                        Case{"Pmlsm_msgs::msg::MotorFeedback", "must start with a lower case letter"},
                        Case{"pmlsm_msgs_::msg::MotorFeedback", "not end with '_'"},
                        Case{"pmlsm__msgs::msg::MotorFeedback", "double '_'"},
                        Case{"pmlsm-msgs::msg::MotorFeedback", "lower case letters, digits and '_' only"},
                        Case{"pmlsm_msgs::msg::motorFeedback", "must start with a capital letter"},
                        Case{"pmlsm_msgs::msg::Motor_Feedback", "letters and digits only"},
                        Case{"pmlsm_msgs::msg::", "must start with a capital letter"}}) {
    SCOPED_TRACE(c.name);
    try {
      ros2_type_name(c.name);
      ADD_FAILURE() << "accepted";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string("'") + c.name + "'"), std::string::npos) << what;
      EXPECT_NE(what.find(c.rule), std::string::npos) << what;
    }
  }
}

}  // namespace
}  // namespace pmlsm::dds
