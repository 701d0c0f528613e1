// ROS 2's graph announcement (pmlsm/dds/ros2_graph.hpp) without DDS: node names as ROS 2 takes
// them, a Gid as rmw makes it from a GUID, and which endpoints each node announces.
#include "pmlsm/dds/ros2_graph.hpp"

#include <gtest/gtest.h>

namespace pmlsm::dds {
namespace {

using eprosima::fastrtps::rtps::GUID_t;

GUID_t guid(std::uint8_t prefix_byte, std::uint32_t entity) {
  GUID_t g;
  for (auto& b : g.guidPrefix.value) b = prefix_byte;
  g.entityId = entity;
  return g;
}

TEST(Ros2Graph, NodeNamesAreWhatRos2Takes) {
  EXPECT_EQ(ros2_node_name("plant_sim"), "plant_sim");
  EXPECT_EQ(ros2_node_name("pmlsm-topic.list"), "pmlsm_topic_list");
  EXPECT_EQ(ros2_node_name("2nd"), "_2nd");
  EXPECT_EQ(ros2_node_name(""), "");
}

TEST(Ros2Graph, AGidIsTheGuidsPrefixThenItsEntityId) {
  GUID_t g;
  for (std::size_t i = 0; i < 12; ++i) g.guidPrefix.value[i] = static_cast<eprosima::fastrtps::rtps::octet>(i + 1);
  g.entityId = 0x000001c1;  // the participant's entity id
  const auto gid = ros2_gid(g);
  for (std::size_t i = 0; i < 12; ++i) EXPECT_EQ(gid[i], i + 1) << i;
  EXPECT_EQ(gid[12], 0x00);
  EXPECT_EQ(gid[13], 0x00);
  EXPECT_EQ(gid[14], 0x01);
  EXPECT_EQ(gid[15], 0xc1);
}

TEST(Ros2Graph, EachNodeAnnouncesItsOwnEndpointsUntilRemoved) {
  Ros2Graph graph;
  const int plant = graph.add_node("plant_sim");
  const int controller = graph.add_node("controller");
  EXPECT_EQ(graph.add_node(""), -1);  // a participant without a node name: nothing announced
  graph.add_endpoint(plant, guid(1, 0x102), /*writer=*/true);
  graph.add_endpoint(plant, guid(1, 0x207), /*writer=*/false);
  graph.add_endpoint(controller, guid(1, 0x302), /*writer=*/true);
  graph.add_endpoint(-1, guid(1, 0x402), /*writer=*/true);  // ignored
  ASSERT_EQ(graph.nodes().size(), 2U);
  EXPECT_EQ(graph.nodes()[0].name, "plant_sim");
  EXPECT_EQ(graph.nodes()[0].writers, std::vector<GUID_t>{guid(1, 0x102)});
  EXPECT_EQ(graph.nodes()[0].readers, std::vector<GUID_t>{guid(1, 0x207)});
  EXPECT_EQ(graph.nodes()[1].writers, std::vector<GUID_t>{guid(1, 0x302)});

  graph.remove_endpoint(guid(1, 0x207));
  EXPECT_TRUE(graph.nodes()[0].readers.empty());
  graph.remove_node(plant);
  EXPECT_FALSE(graph.nodes()[0].live);
  EXPECT_TRUE(graph.nodes()[0].writers.empty());
  graph.add_endpoint(plant, guid(1, 0x502), /*writer=*/true);  // a removed node takes no more
  EXPECT_TRUE(graph.nodes()[0].writers.empty());
  EXPECT_TRUE(graph.nodes()[1].live);
}

}  // namespace
}  // namespace pmlsm::dds
