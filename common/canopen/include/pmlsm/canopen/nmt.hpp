// NMT (network management, CiA 301): the master's node control commands, the node states and
// their heartbeat coding, a slave's NMT state machine, and the heartbeat producer/consumer.
//
// Node control (COB-ID 0x000, DLC 2): byte 0 the command, byte 1 the node id (0 = all nodes).
//   start remote node 0x01, stop remote node 0x02, enter pre-operational 0x80,
//   reset node 0x81, reset communication 0x82.
// Heartbeat / boot-up (COB-ID 0x700 + node, DLC 1): byte 0 the state:
//   boot-up 0x00 (sent once, on leaving initialisation), stopped 0x04, operational 0x05,
//   pre-operational 0x7F.
//
// The slave's states (CiA 301 NMT slave state diagram):
//   initialising --(boot-up message, automatic)--> pre-operational
//   pre-operational / stopped --start--> operational
//   pre-operational / operational --stop--> stopped
//   operational / stopped --enter pre-operational--> pre-operational
//   any but initialising --reset node / reset communication--> initialising (the application
//     resets its parameters, then boot() sends the boot-up message again)
// What each state allows:
//   state            SDO  PDO  SYNC/EMCY  heartbeat  NMT commands
//   initialising     no   no   no         no         no (not on the bus yet)
//   pre-operational  yes  no   yes        yes        yes
//   operational      yes  yes  yes        yes        yes
//   stopped          no   no   no         yes        yes
#pragma once

#include <cstdint>
#include <optional>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/result.hpp"

namespace pmlsm::canopen {

// ---- node control commands -----------------------------------------------------------------

enum class NmtCommand : std::uint8_t {
  kStart = 0x01,
  kStop = 0x02,
  kEnterPreOperational = 0x80,
  kResetNode = 0x81,
  kResetCommunication = 0x82,
};

/// "start", "stop", "enter pre-operational", "reset node", "reset communication" ("unknown").
const char* to_string(NmtCommand command) noexcept;

/// Node id byte 0: the command addresses every node.
inline constexpr std::uint8_t kNmtAllNodes = 0;

struct NmtCommandMessage {
  NmtCommand command = NmtCommand::kEnterPreOperational;
  /// 0 = all nodes, else 1..127.
  std::uint8_t node_id = kNmtAllNodes;

  constexpr bool addresses(NodeId node) const noexcept { return node_id == kNmtAllNodes || node_id == node.value(); }
};

/// The command to one node.
CanFrame encode_nmt(NmtCommand command, NodeId node) noexcept;
/// The command to every node (node id byte 0).
CanFrame encode_nmt_all(NmtCommand command) noexcept;
/// Errors: id not 0x000 (kWrongCobId), RTR / extended frame, DLC not 2 (kWrongDlc), command byte
/// not one of the five (kUnknownCommand), node byte over 127 (kInvalidNodeId).
Result<NmtCommandMessage> decode_nmt(const CanFrame& frame) noexcept;

// ---- states and heartbeat ------------------------------------------------------------------

/// The values are the heartbeat's state byte (initialising: the boot-up message's 0x00).
enum class NmtState : std::uint8_t {
  kInitialising = 0x00,
  kStopped = 0x04,
  kOperational = 0x05,
  kPreOperational = 0x7F,
};

/// "initialising", "stopped", "operational", "pre-operational" ("unknown").
const char* to_string(NmtState state) noexcept;

constexpr bool sdo_allowed(NmtState state) noexcept {
  return state == NmtState::kPreOperational || state == NmtState::kOperational;
}
constexpr bool pdo_allowed(NmtState state) noexcept { return state == NmtState::kOperational; }
/// SYNC consumption and EMCY production.
constexpr bool sync_emcy_allowed(NmtState state) noexcept { return sdo_allowed(state); }

struct HeartbeatMessage {
  std::uint8_t node_id = 0;  // 1..127
  NmtState state = NmtState::kInitialising;
  /// state == kInitialising: the boot-up message.
  constexpr bool boot_up() const noexcept { return state == NmtState::kInitialising; }
};

/// Heartbeat of `node` in `state` (kInitialising gives the boot-up message).
CanFrame encode_heartbeat(NodeId node, NmtState state) noexcept;
/// The boot-up message: encode_heartbeat(node, kInitialising).
CanFrame encode_boot_up(NodeId node) noexcept;
/// Errors: id not 0x701..0x77F (kWrongCobId), RTR / extended frame (node guarding's RTR is not
/// supported), DLC not 1, state byte not 0x00/0x04/0x05/0x7F (kInvalidValue). Bit 7 (node
/// guarding's toggle bit, reserved in a heartbeat) is ignored.
Result<HeartbeatMessage> decode_heartbeat(const CanFrame& frame) noexcept;

// ---- the slave's NMT state machine -----------------------------------------------------------

/// What a reset command asks the application to do before boot() (CiA 301): reset node resets
/// the application (0x2000-0x9FFF) and communication (0x1000-0x1FFF) objects to their power-on
/// values, reset communication only the latter.
enum class NmtReset : std::uint8_t { kNone, kNode, kCommunication };

struct NmtTransition {
  /// The command was for this node (its id or all nodes) and the state machine took it.
  bool accepted = false;
  NmtState from = NmtState::kInitialising;
  NmtState to = NmtState::kInitialising;  // == from when nothing changed
  NmtReset reset = NmtReset::kNone;
  const char* reason = "";  // static text, never null
};

class NmtSlave {
 public:
  explicit NmtSlave(NodeId node) noexcept : node_(node) {}

  /// Leaves initialising: enters pre-operational and returns the boot-up message to send.
  /// nullopt when not initialising (the boot-up message is sent once per (re)start).
  std::optional<CanFrame> boot() noexcept;

  /// Applies a node control command. Commands for other nodes are not accepted (reason "not
  /// addressed to this node"); in initialising every command is ignored. A command whose
  /// target is the current state is accepted without change. Reset node / reset communication
  /// go to initialising with `reset` set; pending_reset() keeps it until boot().
  NmtTransition apply(const NmtCommandMessage& message) noexcept;

  /// decode_nmt + apply. A malformed frame changes nothing and gives the decode error.
  Result<NmtTransition> on_frame(const CanFrame& frame) noexcept;

  /// The heartbeat to send now, if one is due: every `period_ms` (object 0x1017; 0 = no
  /// heartbeat) after boot() or the previous one, in every state but initialising. The first
  /// call after boot() starts the period (the boot-up message is the first heartbeat).
  std::optional<CanFrame> poll_heartbeat(std::uint16_t period_ms, std::uint64_t now_ms) noexcept;

  NmtState state() const noexcept { return state_; }
  NodeId node() const noexcept { return node_; }
  NmtReset pending_reset() const noexcept { return pending_reset_; }
  bool sdo_allowed() const noexcept { return canopen::sdo_allowed(state_); }
  bool pdo_allowed() const noexcept { return canopen::pdo_allowed(state_); }

 private:
  NodeId node_;
  NmtState state_ = NmtState::kInitialising;
  NmtReset pending_reset_ = NmtReset::kNone;
  bool heartbeat_started_ = false;
  std::uint64_t last_heartbeat_ms_ = 0;
};

// ---- heartbeat consumer (a master watching a node) -------------------------------------------

/// Object 0x1016 sub-index n: bits 16-23 the producer's node id, bits 0-15 the consumer
/// heartbeat time in ms (0 = not watched), bits 24-31 reserved (0).
constexpr std::uint32_t consumer_heartbeat_entry(std::uint8_t node_id, std::uint16_t time_ms) noexcept {
  return (static_cast<std::uint32_t>(node_id) << 16) | time_ms;
}

struct ConsumerHeartbeat {
  std::uint8_t node_id = 0;
  std::uint16_t time_ms = 0;
};

/// Error (kInvalidValue) when the reserved bits 24-31 are set or the node id is over 127.
Result<ConsumerHeartbeat> decode_consumer_heartbeat_entry(std::uint32_t entry) noexcept;

enum class HeartbeatEvent : std::uint8_t {
  kNone,          // not this producer's frame, or nothing new
  kReceived,      // a heartbeat in time
  kBootUp,        // the producer (re)started: its boot-up message
  kStateChanged,  // a heartbeat with another state than the previous one
  kTimedOut,      // no heartbeat within the consumer time (reported once per loss)
  kRecovered,     // a heartbeat after a time-out
};

/// "none", "received", "boot-up", "state changed", "timed out", "recovered" ("unknown").
const char* to_string(HeartbeatEvent event) noexcept;

/// Watches one producer's heartbeat. The time-out (CiA 301: EMCY 0x8130) starts with the first
/// heartbeat or boot-up received: a node never seen is not timed out (a master that needs it
/// waits for the boot-up with its own deadline).
class HeartbeatConsumer {
 public:
  /// @throws std::invalid_argument when timeout_ms is 0 ("heartbeat consumer time_ms: must be
  ///         >= 1, got 0").
  HeartbeatConsumer(NodeId producer, std::uint16_t timeout_ms);

  /// A received frame: kNone unless it is the producer's valid heartbeat.
  HeartbeatEvent on_frame(const CanFrame& frame, std::uint64_t now_ms) noexcept;
  /// Periodic check: kTimedOut once when the last heartbeat is older than timeout_ms.
  HeartbeatEvent poll(std::uint64_t now_ms) noexcept;

  /// The last state heard (nullopt before the first heartbeat).
  std::optional<NmtState> state() const noexcept { return state_; }
  bool timed_out() const noexcept { return timed_out_; }
  NodeId producer() const noexcept { return producer_; }

 private:
  NodeId producer_;
  std::uint16_t timeout_ms_;
  std::optional<NmtState> state_;
  std::uint64_t last_ms_ = 0;
  bool timed_out_ = false;
};

}  // namespace pmlsm::canopen
