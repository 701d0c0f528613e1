// NMT node control, heartbeat, the slave's NMT state machine and the heartbeat consumer; see
// nmt.hpp.
#include "pmlsm/canopen/nmt.hpp"

#include <stdexcept>
#include <string>

#include "frame_checks.hpp"
#include "pmlsm/canopen/bytes.hpp"

namespace pmlsm::canopen {
namespace {

bool is_nmt_command(std::uint8_t byte) noexcept {
  switch (static_cast<NmtCommand>(byte)) {
    case NmtCommand::kStart:
    case NmtCommand::kStop:
    case NmtCommand::kEnterPreOperational:
    case NmtCommand::kResetNode:
    case NmtCommand::kResetCommunication: return true;
  }
  return false;
}

bool is_nmt_state(std::uint8_t byte) noexcept {
  switch (static_cast<NmtState>(byte)) {
    case NmtState::kInitialising:
    case NmtState::kStopped:
    case NmtState::kOperational:
    case NmtState::kPreOperational: return true;
  }
  return false;
}

CanFrame nmt_frame(NmtCommand command, std::uint8_t node_id) noexcept {
  CanFrame frame = make_frame(kCobIdNmt, 2);
  frame.data[0] = static_cast<std::uint8_t>(command);
  frame.data[1] = node_id;
  return frame;
}

}  // namespace

const char* to_string(NmtCommand command) noexcept {
  switch (command) {
    case NmtCommand::kStart: return "start";
    case NmtCommand::kStop: return "stop";
    case NmtCommand::kEnterPreOperational: return "enter pre-operational";
    case NmtCommand::kResetNode: return "reset node";
    case NmtCommand::kResetCommunication: return "reset communication";
  }
  return "unknown";
}

const char* to_string(NmtState state) noexcept {
  switch (state) {
    case NmtState::kInitialising: return "initialising";
    case NmtState::kStopped: return "stopped";
    case NmtState::kOperational: return "operational";
    case NmtState::kPreOperational: return "pre-operational";
  }
  return "unknown";
}

const char* to_string(HeartbeatEvent event) noexcept {
  switch (event) {
    case HeartbeatEvent::kNone: return "none";
    case HeartbeatEvent::kReceived: return "received";
    case HeartbeatEvent::kBootUp: return "boot-up";
    case HeartbeatEvent::kStateChanged: return "state changed";
    case HeartbeatEvent::kTimedOut: return "timed out";
    case HeartbeatEvent::kRecovered: return "recovered";
  }
  return "unknown";
}

CanFrame encode_nmt(NmtCommand command, NodeId node) noexcept { return nmt_frame(command, node.value()); }

CanFrame encode_nmt_all(NmtCommand command) noexcept { return nmt_frame(command, kNmtAllNodes); }

Result<NmtCommandMessage> decode_nmt(const CanFrame& frame) noexcept {
  using R = Result<NmtCommandMessage>;
  if (const Status s = detail::check_standard_data_frame(frame); !s) return detail::as_result<NmtCommandMessage>(s);
  if (frame.id != kCobIdNmt) return fail_with<NmtCommandMessage>(Error::kWrongCobId, "NMT: COB-ID must be 0x000");
  if (frame.dlc != 2) return fail_with<NmtCommandMessage>(Error::kWrongDlc, "NMT: DLC must be 2");
  if (!is_nmt_command(frame.data[0])) {
    return fail_with<NmtCommandMessage>(Error::kUnknownCommand,
                                        "NMT: command byte must be 0x01, 0x02, 0x80, 0x81 or 0x82");
  }
  if (frame.data[1] > kMaxNodeId) {
    return fail_with<NmtCommandMessage>(Error::kInvalidNodeId, "NMT: node id byte must be 0 (all) or 1..127");
  }
  R result;
  result.value.command = static_cast<NmtCommand>(frame.data[0]);
  result.value.node_id = frame.data[1];
  return result;
}

CanFrame encode_heartbeat(NodeId node, NmtState state) noexcept {
  CanFrame frame = make_frame(heartbeat_cob_id(node), 1);
  frame.data[0] = static_cast<std::uint8_t>(state);
  return frame;
}

CanFrame encode_boot_up(NodeId node) noexcept { return encode_heartbeat(node, NmtState::kInitialising); }

Result<HeartbeatMessage> decode_heartbeat(const CanFrame& frame) noexcept {
  if (const Status s = detail::check_standard_data_frame(frame); !s) return detail::as_result<HeartbeatMessage>(s);
  const CobIdInfo info = classify(frame.id);
  if (info.function != FunctionCode::kHeartbeat) {
    return fail_with<HeartbeatMessage>(Error::kWrongCobId, "heartbeat: COB-ID must be 0x701..0x77F");
  }
  if (frame.dlc != 1) return fail_with<HeartbeatMessage>(Error::kWrongDlc, "heartbeat: DLC must be 1");
  const auto state = static_cast<std::uint8_t>(frame.data[0] & 0x7FU);
  if (!is_nmt_state(state)) {
    return fail_with<HeartbeatMessage>(Error::kInvalidValue, "heartbeat: state byte must be 0x00, 0x04, 0x05 or 0x7F");
  }
  Result<HeartbeatMessage> result;
  result.value.node_id = info.node_id;
  result.value.state = static_cast<NmtState>(state);
  return result;
}

// ---- NmtSlave ----------------------------------------------------------------------------------

std::optional<CanFrame> NmtSlave::boot() noexcept {
  if (state_ != NmtState::kInitialising) return std::nullopt;
  state_ = NmtState::kPreOperational;
  pending_reset_ = NmtReset::kNone;
  heartbeat_started_ = false;
  return encode_boot_up(node_);
}

NmtTransition NmtSlave::apply(const NmtCommandMessage& message) noexcept {
  NmtTransition t;
  t.from = state_;
  t.to = state_;
  if (!message.addresses(node_)) {
    t.reason = "not addressed to this node";
    return t;
  }
  if (state_ == NmtState::kInitialising) {
    t.reason = "initialising: NMT commands are not processed before the boot-up message";
    return t;
  }
  t.accepted = true;
  switch (message.command) {
    case NmtCommand::kStart: state_ = NmtState::kOperational; break;
    case NmtCommand::kStop: state_ = NmtState::kStopped; break;
    case NmtCommand::kEnterPreOperational: state_ = NmtState::kPreOperational; break;
    case NmtCommand::kResetNode:
      state_ = NmtState::kInitialising;
      pending_reset_ = NmtReset::kNode;
      break;
    case NmtCommand::kResetCommunication:
      state_ = NmtState::kInitialising;
      // A reset node still pending includes the communication reset.
      if (pending_reset_ != NmtReset::kNode) pending_reset_ = NmtReset::kCommunication;
      break;
    default:
      t.accepted = false;
      t.reason = "unknown NMT command";
      return t;
  }
  t.to = state_;
  t.reset = (state_ == NmtState::kInitialising) ? pending_reset_ : NmtReset::kNone;
  t.reason = (t.to == t.from) ? "already in the requested state" : "transition taken";
  return t;
}

Result<NmtTransition> NmtSlave::on_frame(const CanFrame& frame) noexcept {
  const Result<NmtCommandMessage> message = decode_nmt(frame);
  if (!message) return detail::as_result<NmtTransition>(message);
  return success(apply(message.value));
}

std::optional<CanFrame> NmtSlave::poll_heartbeat(std::uint16_t period_ms, std::uint64_t now_ms) noexcept {
  if (state_ == NmtState::kInitialising || period_ms == 0) return std::nullopt;
  if (!heartbeat_started_) {
    heartbeat_started_ = true;
    last_heartbeat_ms_ = now_ms;
    return std::nullopt;
  }
  if (now_ms < last_heartbeat_ms_ + period_ms) return std::nullopt;
  // Keep the schedule on the period grid; after a long gap start again from now.
  last_heartbeat_ms_ += period_ms;
  if (now_ms >= last_heartbeat_ms_ + period_ms) last_heartbeat_ms_ = now_ms;
  return encode_heartbeat(node_, state_);
}

// ---- consumer ----------------------------------------------------------------------------------

Result<ConsumerHeartbeat> decode_consumer_heartbeat_entry(std::uint32_t entry) noexcept {
  if ((entry >> 24) != 0) {
    return fail_with<ConsumerHeartbeat>(Error::kInvalidValue, "consumer heartbeat: bits 24-31 are reserved (0)");
  }
  const auto node = static_cast<std::uint8_t>((entry >> 16) & 0xFFU);
  if (node > kMaxNodeId) {
    return fail_with<ConsumerHeartbeat>(Error::kInvalidNodeId, "consumer heartbeat: node id must be 0..127");
  }
  return success(ConsumerHeartbeat{node, static_cast<std::uint16_t>(entry & 0xFFFFU)});
}

HeartbeatConsumer::HeartbeatConsumer(NodeId producer, std::uint16_t timeout_ms)
    : producer_(producer), timeout_ms_(timeout_ms) {
  if (timeout_ms == 0) {
    throw std::invalid_argument("heartbeat consumer time_ms: must be >= 1, got 0");
  }
}

HeartbeatEvent HeartbeatConsumer::on_frame(const CanFrame& frame, std::uint64_t now_ms) noexcept {
  if (frame.id != heartbeat_cob_id(producer_)) return HeartbeatEvent::kNone;
  const Result<HeartbeatMessage> message = decode_heartbeat(frame);
  if (!message) return HeartbeatEvent::kNone;
  const std::optional<NmtState> previous = state_;
  const bool was_timed_out = timed_out_;
  state_ = message.value.state;
  last_ms_ = now_ms;
  timed_out_ = false;
  if (message.value.boot_up()) return HeartbeatEvent::kBootUp;
  if (was_timed_out) return HeartbeatEvent::kRecovered;
  if (previous && *previous != message.value.state) return HeartbeatEvent::kStateChanged;
  return HeartbeatEvent::kReceived;
}

HeartbeatEvent HeartbeatConsumer::poll(std::uint64_t now_ms) noexcept {
  if (!state_ || timed_out_) return HeartbeatEvent::kNone;
  if (now_ms > last_ms_ + timeout_ms_) {
    timed_out_ = true;
    return HeartbeatEvent::kTimedOut;
  }
  return HeartbeatEvent::kNone;
}

}  // namespace pmlsm::canopen
