// Node ids and the COB-IDs (CAN identifiers) of CiA 301's predefined connection set:
//
//   NMT            0x000            SYNC            0x080           TIME           0x100
//   EMCY           0x080 + node     TPDO1..4        0x180/0x280/0x380/0x480 + node
//   RPDO1..4       0x200/0x300/0x400/0x500 + node
//   SDO tx         0x580 + node     (server -> client: the node's responses)
//   SDO rx         0x600 + node     (client -> server: requests to the node)
//   NMT error ctrl 0x700 + node     (heartbeat, boot-up)
//
// The 4-bit function code is id >> 7; the node id (1..127) is id & 0x7F.
#pragma once

#include <cstdint>
#include <optional>

namespace pmlsm::canopen {

inline constexpr std::uint8_t kMinNodeId = 1;
inline constexpr std::uint8_t kMaxNodeId = 127;

constexpr bool is_valid_node_id(int node_id) noexcept { return node_id >= kMinNodeId && node_id <= kMaxNodeId; }

/// A node id known to be in 1..127. Validated once (from the config) so that the encoders need
/// not check it again.
class NodeId {
 public:
  /// @throws std::invalid_argument "node id: must be in [1, 127], got 0".
  explicit NodeId(int value);

  /// nullopt outside 1..127.
  static std::optional<NodeId> from(int value) noexcept;

  constexpr std::uint8_t value() const noexcept { return value_; }

  friend constexpr bool operator==(NodeId a, NodeId b) noexcept { return a.value_ == b.value_; }
  friend constexpr bool operator!=(NodeId a, NodeId b) noexcept { return a.value_ != b.value_; }

 private:
  struct Unchecked {};
  constexpr NodeId(Unchecked, std::uint8_t value) noexcept : value_(value) {}
  std::uint8_t value_;
};

// ---- the predefined connection set ---------------------------------------------------------

inline constexpr std::uint32_t kCobIdNmt = 0x000;
inline constexpr std::uint32_t kCobIdSync = 0x080;
inline constexpr std::uint32_t kCobIdTime = 0x100;
inline constexpr std::uint32_t kCobIdEmcyBase = 0x080;
inline constexpr std::uint32_t kCobIdTpdo1Base = 0x180;
inline constexpr std::uint32_t kCobIdRpdo1Base = 0x200;
inline constexpr std::uint32_t kCobIdTpdo2Base = 0x280;
inline constexpr std::uint32_t kCobIdRpdo2Base = 0x300;
inline constexpr std::uint32_t kCobIdTpdo3Base = 0x380;
inline constexpr std::uint32_t kCobIdRpdo3Base = 0x400;
inline constexpr std::uint32_t kCobIdTpdo4Base = 0x480;
inline constexpr std::uint32_t kCobIdRpdo4Base = 0x500;
inline constexpr std::uint32_t kCobIdSdoTxBase = 0x580;
inline constexpr std::uint32_t kCobIdSdoRxBase = 0x600;
inline constexpr std::uint32_t kCobIdHeartbeatBase = 0x700;

constexpr std::uint32_t emcy_cob_id(NodeId node) noexcept { return kCobIdEmcyBase + node.value(); }
/// TPDO n (1..4) of a node: 0x180 + 0x100 * (n - 1) + node. n outside 1..4 gives 0 (NMT's id,
/// never a PDO's), which the PDO encoders refuse.
constexpr std::uint32_t tpdo_cob_id(int n, NodeId node) noexcept {
  return (n >= 1 && n <= 4) ? kCobIdTpdo1Base + 0x100U * static_cast<std::uint32_t>(n - 1) + node.value() : 0U;
}
/// RPDO n (1..4) of a node: 0x200 + 0x100 * (n - 1) + node; 0 for n outside 1..4.
constexpr std::uint32_t rpdo_cob_id(int n, NodeId node) noexcept {
  return (n >= 1 && n <= 4) ? kCobIdRpdo1Base + 0x100U * static_cast<std::uint32_t>(n - 1) + node.value() : 0U;
}
/// The node's SDO responses (server -> client).
constexpr std::uint32_t sdo_tx_cob_id(NodeId node) noexcept { return kCobIdSdoTxBase + node.value(); }
/// Requests to the node's SDO server (client -> server).
constexpr std::uint32_t sdo_rx_cob_id(NodeId node) noexcept { return kCobIdSdoRxBase + node.value(); }
constexpr std::uint32_t heartbeat_cob_id(NodeId node) noexcept { return kCobIdHeartbeatBase + node.value(); }

enum class FunctionCode : std::uint8_t {
  kNmt,   // 0x000
  kSync,  // 0x080
  kEmcy,  // 0x081..0x0FF
  kTime,  // 0x100
  kTpdo1,
  kRpdo1,
  kTpdo2,
  kRpdo2,
  kTpdo3,
  kRpdo3,
  kTpdo4,
  kRpdo4,
  kSdoTx,      // 0x581..0x5FF
  kSdoRx,      // 0x601..0x67F
  kHeartbeat,  // 0x701..0x77F (NMT error control: heartbeat, boot-up)
  kUnknown,    // not in the predefined connection set (e.g. 0x180, 0x7E5, > 0x7FF)
};

/// "NMT", "SYNC", "EMCY", "TIME", "TPDO1", "RPDO1", ..., "SDO tx", "SDO rx", "heartbeat",
/// "unknown".
const char* to_string(FunctionCode code) noexcept;

struct CobIdInfo {
  FunctionCode function = FunctionCode::kUnknown;
  /// 1..127 for the per-node objects, 0 for NMT, SYNC, TIME and unknown ids.
  std::uint8_t node_id = 0;
};

/// Which object of the predefined connection set an 11-bit id is, and for which node.
/// Per-node function codes with node part 0 (0x180, 0x580, 0x700, ...) and ids over 0x7FF are
/// kUnknown; 0x080 is SYNC, 0x081..0x0FF EMCY.
CobIdInfo classify(std::uint32_t id) noexcept;

/// The id of `function` for `node` (NMT, SYNC and TIME ignore the node); 0xFFFFFFFF for
/// kUnknown.
std::uint32_t cob_id(FunctionCode function, NodeId node) noexcept;

}  // namespace pmlsm::canopen
