// SYNC; see sync.hpp.
#include "pmlsm/canopen/sync.hpp"

#include <stdexcept>
#include <string>

#include "frame_checks.hpp"
#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/cob_id.hpp"

namespace pmlsm::canopen {

CanFrame encode_sync() noexcept { return make_frame(kCobIdSync, 0); }

Result<CanFrame> encode_sync(std::uint8_t counter) noexcept {
  if (counter < kSyncCounterMin || counter > kSyncCounterMax) {
    return fail_with<CanFrame>(Error::kInvalidValue, "SYNC: counter must be in 1..240");
  }
  CanFrame frame = make_frame(kCobIdSync, 1);
  frame.data[0] = counter;
  return success(frame);
}

Result<SyncMessage> decode_sync(const CanFrame& frame) noexcept {
  if (const Status s = detail::check_standard_data_frame(frame); !s) return detail::as_result<SyncMessage>(s);
  if (frame.id != kCobIdSync) return fail_with<SyncMessage>(Error::kWrongCobId, "SYNC: COB-ID must be 0x080");
  if (frame.dlc == 0) return success(SyncMessage{});
  if (frame.dlc != 1) return fail_with<SyncMessage>(Error::kWrongDlc, "SYNC: DLC must be 0 or 1");
  const std::uint8_t counter = frame.data[0];
  if (counter < kSyncCounterMin || counter > kSyncCounterMax) {
    return fail_with<SyncMessage>(Error::kInvalidValue, "SYNC: counter must be in 1..240");
  }
  return success(SyncMessage{counter});
}

SyncProducer::SyncProducer(std::uint8_t counter_overflow) : overflow_(counter_overflow) {
  if (counter_overflow == 1 || counter_overflow > kSyncCounterMax) {
    throw std::invalid_argument("sync counter overflow: must be 0 or in [2, 240], got " +
                                std::to_string(counter_overflow));
  }
}

CanFrame SyncProducer::next() noexcept {
  if (overflow_ == 0) return encode_sync();
  counter_ = (counter_ >= overflow_) ? 1 : static_cast<std::uint8_t>(counter_ + 1);
  CanFrame frame = make_frame(kCobIdSync, 1);
  frame.data[0] = counter_;
  return frame;
}

}  // namespace pmlsm::canopen
