// COB-IDs of CiA 301's predefined connection set, node id validation and classify().
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "pmlsm/canopen/cob_id.hpp"

namespace {

using namespace pmlsm::canopen;

TEST(NodeIdTest, AcceptsOneTo127Only) {
  EXPECT_EQ(NodeId(1).value(), 1);
  EXPECT_EQ(NodeId(127).value(), 127);
  EXPECT_FALSE(NodeId::from(0).has_value());
  EXPECT_FALSE(NodeId::from(128).has_value());
  EXPECT_FALSE(NodeId::from(-1).has_value());
  ASSERT_TRUE(NodeId::from(5).has_value());
  EXPECT_EQ(NodeId::from(5)->value(), 5);
  try {
    NodeId bad(0);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "node id: must be in [1, 127], got 0");
  }
  EXPECT_THROW(NodeId(128), std::invalid_argument);
}

TEST(CobIdTest, PredefinedConnectionSetTable) {
  const NodeId n(5);
  EXPECT_EQ(kCobIdNmt, 0x000u);
  EXPECT_EQ(kCobIdSync, 0x080u);
  EXPECT_EQ(emcy_cob_id(n), 0x085u);
  EXPECT_EQ(tpdo_cob_id(1, n), 0x185u);
  EXPECT_EQ(tpdo_cob_id(2, n), 0x285u);
  EXPECT_EQ(tpdo_cob_id(3, n), 0x385u);
  EXPECT_EQ(tpdo_cob_id(4, n), 0x485u);
  EXPECT_EQ(rpdo_cob_id(1, n), 0x205u);
  EXPECT_EQ(rpdo_cob_id(2, n), 0x305u);
  EXPECT_EQ(rpdo_cob_id(3, n), 0x405u);
  EXPECT_EQ(rpdo_cob_id(4, n), 0x505u);
  EXPECT_EQ(sdo_tx_cob_id(n), 0x585u);
  EXPECT_EQ(sdo_rx_cob_id(n), 0x605u);
  EXPECT_EQ(heartbeat_cob_id(n), 0x705u);
  EXPECT_EQ(tpdo_cob_id(0, n), 0u);
  EXPECT_EQ(rpdo_cob_id(5, n), 0u);
  const NodeId last(127);
  EXPECT_EQ(emcy_cob_id(last), 0x0FFu);
  EXPECT_EQ(sdo_rx_cob_id(last), 0x67Fu);
  EXPECT_EQ(heartbeat_cob_id(last), 0x77Fu);
}

TEST(CobIdTest, ClassifyEveryFunctionForEveryNode) {
  const FunctionCode per_node[] = {FunctionCode::kEmcy,  FunctionCode::kTpdo1, FunctionCode::kRpdo1,
                                   FunctionCode::kTpdo2, FunctionCode::kRpdo2, FunctionCode::kTpdo3,
                                   FunctionCode::kRpdo3, FunctionCode::kTpdo4, FunctionCode::kRpdo4,
                                   FunctionCode::kSdoTx, FunctionCode::kSdoRx, FunctionCode::kHeartbeat};
  for (int id = 1; id <= 127; ++id) {
    const NodeId node(id);
    for (FunctionCode f : per_node) {
      const std::uint32_t cob = cob_id(f, node);
      const CobIdInfo info = classify(cob);
      EXPECT_EQ(info.function, f) << to_string(f) << " node " << id;
      EXPECT_EQ(info.node_id, id) << to_string(f);
    }
  }
}

TEST(CobIdTest, ClassifyBroadcastAndUnknownIds) {
  EXPECT_EQ(classify(0x000).function, FunctionCode::kNmt);
  EXPECT_EQ(classify(0x080).function, FunctionCode::kSync);
  EXPECT_EQ(classify(0x080).node_id, 0);
  EXPECT_EQ(classify(0x100).function, FunctionCode::kTime);
  EXPECT_EQ(classify(0x081).function, FunctionCode::kEmcy);
  // Per-node codes with node part 0, unused codes, LSS ids and ids over 11 bits.
  for (std::uint32_t id :
       {0x001u, 0x07Fu, 0x101u, 0x180u, 0x200u, 0x580u, 0x600u, 0x680u, 0x700u, 0x7E4u, 0x7E5u, 0x800u, 0x12345u}) {
    EXPECT_EQ(classify(id).function, FunctionCode::kUnknown) << std::hex << id;
    EXPECT_EQ(classify(id).node_id, 0) << std::hex << id;
  }
}

TEST(CobIdTest, Names) {
  EXPECT_STREQ(to_string(FunctionCode::kSdoRx), "SDO rx");
  EXPECT_STREQ(to_string(FunctionCode::kTpdo3), "TPDO3");
  EXPECT_STREQ(to_string(FunctionCode::kHeartbeat), "heartbeat");
  EXPECT_STREQ(to_string(static_cast<FunctionCode>(200)), "unknown");
  EXPECT_EQ(cob_id(FunctionCode::kUnknown, NodeId(1)), 0xFFFFFFFFu);
  EXPECT_EQ(cob_id(FunctionCode::kSync, NodeId(9)), 0x080u);
}

}  // namespace
