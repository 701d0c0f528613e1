// Node ids and the predefined connection set; see cob_id.hpp.
#include "pmlsm/canopen/cob_id.hpp"

#include <stdexcept>
#include <string>

namespace pmlsm::canopen {

NodeId::NodeId(int value) : value_(0) {
  if (!is_valid_node_id(value)) {
    throw std::invalid_argument("node id: must be in [1, 127], got " + std::to_string(value));
  }
  value_ = static_cast<std::uint8_t>(value);
}

std::optional<NodeId> NodeId::from(int value) noexcept {
  if (!is_valid_node_id(value)) return std::nullopt;
  return NodeId(Unchecked{}, static_cast<std::uint8_t>(value));
}

const char* to_string(FunctionCode code) noexcept {
  switch (code) {
    case FunctionCode::kNmt: return "NMT";
    case FunctionCode::kSync: return "SYNC";
    case FunctionCode::kEmcy: return "EMCY";
    case FunctionCode::kTime: return "TIME";
    case FunctionCode::kTpdo1: return "TPDO1";
    case FunctionCode::kRpdo1: return "RPDO1";
    case FunctionCode::kTpdo2: return "TPDO2";
    case FunctionCode::kRpdo2: return "RPDO2";
    case FunctionCode::kTpdo3: return "TPDO3";
    case FunctionCode::kRpdo3: return "RPDO3";
    case FunctionCode::kTpdo4: return "TPDO4";
    case FunctionCode::kRpdo4: return "RPDO4";
    case FunctionCode::kSdoTx: return "SDO tx";
    case FunctionCode::kSdoRx: return "SDO rx";
    case FunctionCode::kHeartbeat: return "heartbeat";
    case FunctionCode::kUnknown: return "unknown";
  }
  return "unknown";
}

CobIdInfo classify(std::uint32_t id) noexcept {
  if (id > 0x7FFU) return {};
  if (id == kCobIdNmt) return {FunctionCode::kNmt, 0};
  if (id == kCobIdSync) return {FunctionCode::kSync, 0};
  if (id == kCobIdTime) return {FunctionCode::kTime, 0};
  const auto node = static_cast<std::uint8_t>(id & 0x7FU);
  if (node == 0) return {};
  // Function code (bits 10-7) -> per-node object; codes 0 (NMT) and 2 (TIME) have no node part.
  constexpr FunctionCode kPerNode[16] = {
      FunctionCode::kUnknown, FunctionCode::kEmcy,    FunctionCode::kUnknown,   FunctionCode::kTpdo1,
      FunctionCode::kRpdo1,   FunctionCode::kTpdo2,   FunctionCode::kRpdo2,     FunctionCode::kTpdo3,
      FunctionCode::kRpdo3,   FunctionCode::kTpdo4,   FunctionCode::kRpdo4,     FunctionCode::kSdoTx,
      FunctionCode::kSdoRx,   FunctionCode::kUnknown, FunctionCode::kHeartbeat, FunctionCode::kUnknown,
  };
  const FunctionCode function = kPerNode[(id >> 7) & 0xFU];
  if (function == FunctionCode::kUnknown) return {};
  return {function, node};
}

std::uint32_t cob_id(FunctionCode function, NodeId node) noexcept {
  switch (function) {
    case FunctionCode::kNmt: return kCobIdNmt;
    case FunctionCode::kSync: return kCobIdSync;
    case FunctionCode::kTime: return kCobIdTime;
    case FunctionCode::kEmcy: return emcy_cob_id(node);
    case FunctionCode::kTpdo1: return tpdo_cob_id(1, node);
    case FunctionCode::kRpdo1: return rpdo_cob_id(1, node);
    case FunctionCode::kTpdo2: return tpdo_cob_id(2, node);
    case FunctionCode::kRpdo2: return rpdo_cob_id(2, node);
    case FunctionCode::kTpdo3: return tpdo_cob_id(3, node);
    case FunctionCode::kRpdo3: return rpdo_cob_id(3, node);
    case FunctionCode::kTpdo4: return tpdo_cob_id(4, node);
    case FunctionCode::kRpdo4: return rpdo_cob_id(4, node);
    case FunctionCode::kSdoTx: return sdo_tx_cob_id(node);
    case FunctionCode::kSdoRx: return sdo_rx_cob_id(node);
    case FunctionCode::kHeartbeat: return heartbeat_cob_id(node);
    case FunctionCode::kUnknown: break;
  }
  return 0xFFFFFFFFU;
}

}  // namespace pmlsm::canopen
