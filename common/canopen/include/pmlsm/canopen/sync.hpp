// SYNC (CiA 301): COB-ID 0x080, DLC 0, or DLC 1 carrying a counter 1..240 when the producer's
// synchronous counter overflow value (object 0x1019) is 2..240. The counter starts at 1 and
// wraps to 1 after the overflow value.
#pragma once

#include <cstdint>
#include <optional>

#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/result.hpp"

namespace pmlsm::canopen {

inline constexpr std::uint8_t kSyncCounterMin = 1;
inline constexpr std::uint8_t kSyncCounterMax = 240;

struct SyncMessage {
  /// nullopt: a SYNC without counter (DLC 0).
  std::optional<std::uint8_t> counter;
};

/// SYNC without counter (DLC 0).
CanFrame encode_sync() noexcept;
/// SYNC with counter (DLC 1). Error kInvalidValue for a counter outside 1..240.
Result<CanFrame> encode_sync(std::uint8_t counter) noexcept;
/// Errors: id not 0x080 (kWrongCobId), RTR / extended frame, DLC not 0 or 1, counter outside
/// 1..240 (kInvalidValue).
Result<SyncMessage> decode_sync(const CanFrame& frame) noexcept;

/// The SYNC producer's frames: no counter when overflow is 0 (0x1019 = 0), else 1, 2, ...,
/// overflow, 1, ...
class SyncProducer {
 public:
  /// @throws std::invalid_argument for an overflow of 1 or over 240 (CiA 301 allows 0 and
  ///         2..240): "sync counter overflow: must be 0 or in [2, 240], got 1".
  explicit SyncProducer(std::uint8_t counter_overflow = 0);

  CanFrame next() noexcept;
  /// Back to counter 1 (CiA 301: when the SYNC producer restarts).
  void reset() noexcept { counter_ = 0; }

 private:
  std::uint8_t overflow_;
  std::uint8_t counter_ = 0;  // the last counter sent, 0 before the first
};

}  // namespace pmlsm::canopen
