// NMT node control commands, heartbeat coding, the slave's NMT state machine and the heartbeat
// consumer.
#include <gtest/gtest.h>

#include <stdexcept>

#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/nmt.hpp"

namespace {

using namespace pmlsm::canopen;

TEST(NmtCommandTest, CommandBytesAreTheStandards) {
  EXPECT_EQ(static_cast<int>(NmtCommand::kStart), 0x01);
  EXPECT_EQ(static_cast<int>(NmtCommand::kStop), 0x02);
  EXPECT_EQ(static_cast<int>(NmtCommand::kEnterPreOperational), 0x80);
  EXPECT_EQ(static_cast<int>(NmtCommand::kResetNode), 0x81);
  EXPECT_EQ(static_cast<int>(NmtCommand::kResetCommunication), 0x82);
}

TEST(NmtCommandTest, EncodeToOneNodeAndToAll) {
  const CanFrame f = encode_nmt(NmtCommand::kStart, NodeId(3));
  EXPECT_EQ(f.id, 0x000u);
  EXPECT_EQ(f.dlc, 2);
  EXPECT_EQ(f.data[0], 0x01);
  EXPECT_EQ(f.data[1], 3);
  EXPECT_FALSE(f.rtr);
  EXPECT_FALSE(f.extended);
  const CanFrame all = encode_nmt_all(NmtCommand::kResetCommunication);
  EXPECT_EQ(all.data[0], 0x82);
  EXPECT_EQ(all.data[1], 0);
}

TEST(NmtCommandTest, DecodeRoundTripForEveryCommand) {
  for (NmtCommand c : {NmtCommand::kStart, NmtCommand::kStop, NmtCommand::kEnterPreOperational, NmtCommand::kResetNode,
                       NmtCommand::kResetCommunication}) {
    const auto r = decode_nmt(encode_nmt(c, NodeId(42)));
    ASSERT_TRUE(r.ok()) << r.detail;
    EXPECT_EQ(r.value.command, c);
    EXPECT_EQ(r.value.node_id, 42);
    EXPECT_TRUE(r.value.addresses(NodeId(42)));
    EXPECT_FALSE(r.value.addresses(NodeId(41)));
  }
  const auto all = decode_nmt(encode_nmt_all(NmtCommand::kStop));
  ASSERT_TRUE(all.ok());
  EXPECT_TRUE(all.value.addresses(NodeId(1)));
  EXPECT_TRUE(all.value.addresses(NodeId(127)));
  EXPECT_STREQ(to_string(NmtCommand::kEnterPreOperational), "enter pre-operational");
}

TEST(NmtCommandTest, MalformedFramesGiveErrors) {
  CanFrame f = encode_nmt(NmtCommand::kStart, NodeId(3));
  f.dlc = 1;
  EXPECT_EQ(decode_nmt(f).error, Error::kWrongDlc);
  EXPECT_STREQ(decode_nmt(f).detail, "NMT: DLC must be 2");
  f.dlc = 3;
  EXPECT_EQ(decode_nmt(f).error, Error::kWrongDlc);
  f = encode_nmt(NmtCommand::kStart, NodeId(3));
  f.data[0] = 0x03;
  EXPECT_EQ(decode_nmt(f).error, Error::kUnknownCommand);
  f.data[0] = 0x01;
  f.data[1] = 128;
  EXPECT_EQ(decode_nmt(f).error, Error::kInvalidNodeId);
  f = encode_nmt(NmtCommand::kStart, NodeId(3));
  f.id = 0x001;
  EXPECT_EQ(decode_nmt(f).error, Error::kWrongCobId);
  f = encode_nmt(NmtCommand::kStart, NodeId(3));
  f.rtr = true;
  EXPECT_EQ(decode_nmt(f).error, Error::kRemoteFrame);
  f.rtr = false;
  f.extended = true;
  EXPECT_EQ(decode_nmt(f).error, Error::kExtendedFrame);
  f.extended = false;
  f.dlc = 9;
  EXPECT_EQ(decode_nmt(f).error, Error::kWrongDlc);
}

TEST(HeartbeatTest, StateBytesAreTheStandards) {
  const NodeId n(7);
  EXPECT_EQ(encode_boot_up(n).data[0], 0x00);
  EXPECT_EQ(encode_heartbeat(n, NmtState::kStopped).data[0], 0x04);
  EXPECT_EQ(encode_heartbeat(n, NmtState::kOperational).data[0], 0x05);
  EXPECT_EQ(encode_heartbeat(n, NmtState::kPreOperational).data[0], 0x7F);
  const CanFrame f = encode_heartbeat(n, NmtState::kOperational);
  EXPECT_EQ(f.id, 0x707u);
  EXPECT_EQ(f.dlc, 1);
}

TEST(HeartbeatTest, DecodeRoundTripAndErrors) {
  for (NmtState s : {NmtState::kInitialising, NmtState::kStopped, NmtState::kOperational, NmtState::kPreOperational}) {
    const auto r = decode_heartbeat(encode_heartbeat(NodeId(99), s));
    ASSERT_TRUE(r.ok()) << r.detail;
    EXPECT_EQ(r.value.node_id, 99);
    EXPECT_EQ(r.value.state, s);
    EXPECT_EQ(r.value.boot_up(), s == NmtState::kInitialising);
  }
  CanFrame f = encode_heartbeat(NodeId(1), NmtState::kOperational);
  f.data[0] = 0x85;  // toggle bit ignored
  ASSERT_TRUE(decode_heartbeat(f).ok());
  EXPECT_EQ(decode_heartbeat(f).value.state, NmtState::kOperational);
  f.data[0] = 0x01;
  EXPECT_EQ(decode_heartbeat(f).error, Error::kInvalidValue);
  f.data[0] = 0x05;
  f.dlc = 0;
  EXPECT_EQ(decode_heartbeat(f).error, Error::kWrongDlc);
  f.dlc = 2;
  EXPECT_EQ(decode_heartbeat(f).error, Error::kWrongDlc);
  f.dlc = 1;
  f.id = 0x700;
  EXPECT_EQ(decode_heartbeat(f).error, Error::kWrongCobId);
  f.id = 0x601;
  EXPECT_EQ(decode_heartbeat(f).error, Error::kWrongCobId);
  f.id = 0x701;
  f.rtr = true;  // node guarding request
  EXPECT_EQ(decode_heartbeat(f).error, Error::kRemoteFrame);
}

TEST(NmtSlaveTest, BootsIntoPreOperationalWithTheBootUpMessage) {
  NmtSlave slave(NodeId(4));
  EXPECT_EQ(slave.state(), NmtState::kInitialising);
  EXPECT_FALSE(slave.sdo_allowed());
  EXPECT_FALSE(slave.pdo_allowed());
  const auto boot = slave.boot();
  ASSERT_TRUE(boot.has_value());
  EXPECT_EQ(boot->id, 0x704u);
  EXPECT_EQ(boot->dlc, 1);
  EXPECT_EQ(boot->data[0], 0x00);
  EXPECT_EQ(slave.state(), NmtState::kPreOperational);
  EXPECT_TRUE(slave.sdo_allowed());
  EXPECT_FALSE(slave.pdo_allowed());
  EXPECT_FALSE(slave.boot().has_value());  // once per start
}

TEST(NmtSlaveTest, CommandsInInitialisingAreIgnored) {
  NmtSlave slave(NodeId(4));
  const NmtTransition t = slave.apply({NmtCommand::kStart, 4});
  EXPECT_FALSE(t.accepted);
  EXPECT_EQ(slave.state(), NmtState::kInitialising);
}

TEST(NmtSlaveTest, TransitionTable) {
  struct Row {
    NmtState from;
    NmtCommand command;
    NmtState to;
  };
  const Row rows[] = {
      {NmtState::kPreOperational, NmtCommand::kStart, NmtState::kOperational},
      {NmtState::kPreOperational, NmtCommand::kStop, NmtState::kStopped},
      {NmtState::kPreOperational, NmtCommand::kEnterPreOperational, NmtState::kPreOperational},
      {NmtState::kOperational, NmtCommand::kStop, NmtState::kStopped},
      {NmtState::kOperational, NmtCommand::kEnterPreOperational, NmtState::kPreOperational},
      {NmtState::kOperational, NmtCommand::kStart, NmtState::kOperational},
      {NmtState::kStopped, NmtCommand::kStart, NmtState::kOperational},
      {NmtState::kStopped, NmtCommand::kEnterPreOperational, NmtState::kPreOperational},
      {NmtState::kStopped, NmtCommand::kStop, NmtState::kStopped},
  };
  for (const Row& row : rows) {
    NmtSlave slave(NodeId(4));
    slave.boot();
    if (row.from == NmtState::kOperational) slave.apply({NmtCommand::kStart, 0});
    if (row.from == NmtState::kStopped) slave.apply({NmtCommand::kStop, 0});
    ASSERT_EQ(slave.state(), row.from);
    const NmtTransition t = slave.apply({row.command, 4});
    EXPECT_TRUE(t.accepted) << to_string(row.from) << " " << to_string(row.command);
    EXPECT_EQ(t.from, row.from);
    EXPECT_EQ(t.to, row.to) << to_string(row.from) << " " << to_string(row.command);
    EXPECT_EQ(slave.state(), row.to);
    EXPECT_EQ(t.reset, NmtReset::kNone);
  }
}

TEST(NmtSlaveTest, SdoAndPdoPermissionsPerState) {
  EXPECT_FALSE(sdo_allowed(NmtState::kInitialising));
  EXPECT_TRUE(sdo_allowed(NmtState::kPreOperational));
  EXPECT_TRUE(sdo_allowed(NmtState::kOperational));
  EXPECT_FALSE(sdo_allowed(NmtState::kStopped));
  EXPECT_FALSE(pdo_allowed(NmtState::kInitialising));
  EXPECT_FALSE(pdo_allowed(NmtState::kPreOperational));
  EXPECT_TRUE(pdo_allowed(NmtState::kOperational));
  EXPECT_FALSE(pdo_allowed(NmtState::kStopped));
  EXPECT_TRUE(sync_emcy_allowed(NmtState::kOperational));
  EXPECT_FALSE(sync_emcy_allowed(NmtState::kStopped));
}

TEST(NmtSlaveTest, ResetsGoBackToInitialisingAndBootAgain) {
  for (NmtCommand reset : {NmtCommand::kResetNode, NmtCommand::kResetCommunication}) {
    NmtSlave slave(NodeId(4));
    slave.boot();
    slave.apply({NmtCommand::kStart, 4});
    const NmtTransition t = slave.apply({reset, 0});
    EXPECT_TRUE(t.accepted);
    EXPECT_EQ(t.to, NmtState::kInitialising);
    EXPECT_EQ(t.reset, reset == NmtCommand::kResetNode ? NmtReset::kNode : NmtReset::kCommunication);
    EXPECT_EQ(slave.pending_reset(), t.reset);
    EXPECT_FALSE(slave.sdo_allowed());
    const auto boot = slave.boot();
    ASSERT_TRUE(boot.has_value());
    EXPECT_EQ(boot->data[0], 0x00);
    EXPECT_EQ(slave.state(), NmtState::kPreOperational);
    EXPECT_EQ(slave.pending_reset(), NmtReset::kNone);
  }
}

TEST(NmtSlaveTest, OtherNodesCommandsAndMalformedFramesChangeNothing) {
  NmtSlave slave(NodeId(4));
  slave.boot();
  const NmtTransition t = slave.apply({NmtCommand::kStart, 5});
  EXPECT_FALSE(t.accepted);
  EXPECT_STREQ(t.reason, "not addressed to this node");
  EXPECT_EQ(slave.state(), NmtState::kPreOperational);

  CanFrame bad = encode_nmt(NmtCommand::kStart, NodeId(4));
  bad.dlc = 1;
  const auto r = slave.on_frame(bad);
  EXPECT_EQ(r.error, Error::kWrongDlc);
  EXPECT_EQ(slave.state(), NmtState::kPreOperational);

  const auto ok = slave.on_frame(encode_nmt_all(NmtCommand::kStart));
  ASSERT_TRUE(ok.ok());
  EXPECT_TRUE(ok.value.accepted);
  EXPECT_EQ(slave.state(), NmtState::kOperational);
}

TEST(NmtSlaveTest, HeartbeatEveryPeriodInEveryStateButInitialising) {
  NmtSlave slave(NodeId(4));
  EXPECT_FALSE(slave.poll_heartbeat(100, 0).has_value());
  slave.boot();
  EXPECT_FALSE(slave.poll_heartbeat(100, 1000).has_value());  // starts the period
  EXPECT_FALSE(slave.poll_heartbeat(100, 1099).has_value());
  auto hb = slave.poll_heartbeat(100, 1100);
  ASSERT_TRUE(hb.has_value());
  EXPECT_EQ(hb->id, 0x704u);
  EXPECT_EQ(hb->data[0], 0x7F);
  slave.apply({NmtCommand::kStop, 4});
  hb = slave.poll_heartbeat(100, 1200);
  ASSERT_TRUE(hb.has_value());
  EXPECT_EQ(hb->data[0], 0x04);
  EXPECT_FALSE(slave.poll_heartbeat(0, 5000).has_value());  // 0x1017 = 0: no heartbeat
}

TEST(HeartbeatConsumerTest, TimesOutOnceAndRecovers) {
  HeartbeatConsumer consumer(NodeId(9), 150);
  EXPECT_EQ(consumer.poll(10000), HeartbeatEvent::kNone);  // never heard: not timed out
  EXPECT_EQ(consumer.on_frame(encode_boot_up(NodeId(9)), 0), HeartbeatEvent::kBootUp);
  EXPECT_EQ(consumer.on_frame(encode_heartbeat(NodeId(8), NmtState::kOperational), 10), HeartbeatEvent::kNone);
  EXPECT_EQ(consumer.on_frame(encode_heartbeat(NodeId(9), NmtState::kPreOperational), 100),
            HeartbeatEvent::kStateChanged);
  EXPECT_EQ(consumer.on_frame(encode_heartbeat(NodeId(9), NmtState::kPreOperational), 200), HeartbeatEvent::kReceived);
  EXPECT_EQ(consumer.poll(350), HeartbeatEvent::kNone);
  EXPECT_EQ(consumer.poll(351), HeartbeatEvent::kTimedOut);
  EXPECT_TRUE(consumer.timed_out());
  EXPECT_EQ(consumer.poll(400), HeartbeatEvent::kNone);  // once
  EXPECT_EQ(consumer.on_frame(encode_heartbeat(NodeId(9), NmtState::kOperational), 500), HeartbeatEvent::kRecovered);
  EXPECT_FALSE(consumer.timed_out());
  ASSERT_TRUE(consumer.state().has_value());
  EXPECT_EQ(*consumer.state(), NmtState::kOperational);
  EXPECT_THROW(HeartbeatConsumer(NodeId(9), 0), std::invalid_argument);
}

TEST(HeartbeatConsumerTest, EntryCoding) {
  EXPECT_EQ(consumer_heartbeat_entry(5, 200), 0x000500C8u);
  const auto r = decode_consumer_heartbeat_entry(0x000500C8u);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.value.node_id, 5);
  EXPECT_EQ(r.value.time_ms, 200);
  EXPECT_EQ(decode_consumer_heartbeat_entry(0x010500C8u).error, Error::kInvalidValue);
  EXPECT_EQ(decode_consumer_heartbeat_entry(0x008000C8u).error, Error::kInvalidNodeId);
}

}  // namespace
