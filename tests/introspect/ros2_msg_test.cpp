// ROS 2 .msg files from IDL (pmlsm/introspect/ros2_msg.hpp): the mapping of every IDL form our
// messages use, constants from <Name>_Constants modules, a definition with its dependencies as
// rosbag2 stores it, and the IDL a .msg cannot express refused with what and where.

#include "pmlsm/introspect/ros2_msg.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace pmlsm::introspect {
namespace {

const std::string kIdl = R"(
module pkg_msgs { module msg {
  struct Inner { double x; };
  module Outer_Constants {
    const uint8 MODE_A = 1;
    const uint32 LIMIT = 2 * 8;
  };
  @final
  struct Outer {
    Inner inner;
    boolean ok;
    octet raw;
    int16 i16; uint16 u16; int32 i32; uint32 u32; int64 i64; uint64 u64;
    float f32; double f64;
    string text; string<16> bounded;
    sequence<double> values; sequence<double, 4> some_values; double fixed[3];
    sequence<string<8>, 2> names; sequence<Inner, 5> inners;
  };
}; };
)";

TEST(Ros2Msg, EveryIdlFormBecomesItsRos2FieldAndTheConstantsOpenTheFile) {
  const std::vector<Ros2MessageFile> files = ros2_message_files(kIdl, "pkg_msgs");
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[0].name, "Inner");
  EXPECT_EQ(files[0].text, "float64 x\n");
  EXPECT_EQ(files[1].name, "Outer");
  EXPECT_EQ(files[1].text,
            "uint8 MODE_A=1\n"
            "uint32 LIMIT=16\n"
            "\n"
            "Inner inner\n"
            "bool ok\n"
            "uint8 raw\n"
            "int16 i16\nuint16 u16\nint32 i32\nuint32 u32\nint64 i64\nuint64 u64\n"
            "float32 f32\nfloat64 f64\n"
            "string text\nstring<=16 bounded\n"
            "float64[] values\nfloat64[<=4] some_values\nfloat64[3] fixed\n"
            "string<=8[<=2] names\nInner[<=5] inners\n");
}

TEST(Ros2Msg, ADefinitionCarriesEachMessageItUsesOnceAfterASeparator) {
  const std::string separator = std::string(80, '=') + "\n";
  EXPECT_EQ(ros2_message_definition(kIdl, "pkg_msgs", "Inner"), "float64 x\n");
  const std::string outer = ros2_message_definition(kIdl, "pkg_msgs", "Outer");
  const std::string tail = separator + "MSG: pkg_msgs/Inner\nfloat64 x\n";
  ASSERT_GE(outer.size(), tail.size());
  EXPECT_EQ(outer.substr(outer.size() - tail.size()), tail) << outer;
  EXPECT_EQ(outer.find("MSG: "), outer.rfind("MSG: ")) << "Inner twice: " << outer;
}

TEST(Ros2Msg, WhatAMsgCannotSayIsRefusedNamingItAndWhy) {
  struct Case {
    const char* what;
    std::string idl;
    const char* expected;
  };
  const std::string open = "module pkg_msgs { module msg { ";
  const std::string close = " }; };";
  const std::vector<Case> cases = {
      {"an enum", open + "enum Mode { A, B }; struct M { Mode mode; };" + close, "field 'pkg_msgs::msg::M::mode'"},
      {"a list of lists", open + "typedef sequence<double, 2> Pair; struct M { sequence<Pair, 3> pairs; };" + close,
       "a list of lists"},
      {"a field name in camel case", open + "struct M { double positionM; };" + close, "lower case letters"},
      {"a field name with a double '_'", open + "struct M { double a__b; };" + close, "single '_'"},
      {"a constant in lower case",
       open + "module M_Constants { const uint8 low = 1; }; struct M { double x; };" + close, "upper case"},
      {"a constant of no message", open + "module N_Constants { const uint8 A = 1; }; struct M { double x; };" + close,
       "not in a module <Message>_Constants"},
      {"a struct outside <package>::msg", "module other { struct M { double x; }; };",
       "'other::M' is not a message of pkg_msgs::msg"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    try {
      ros2_message_files(c.idl, "pkg_msgs");
      ADD_FAILURE() << "accepted";
    } catch (const SchemaError& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(ros2_message_definition(kIdl, "pkg_msgs", "Missing"), SchemaError);
}

}  // namespace
}  // namespace pmlsm::introspect
