// The UDP-multicast virtual CAN bus's datagram decoder (python-can's msgpack format,
// pycan_wire::decode). A datagram that decodes gives a valid frame, which encodes and decodes
// back to the same frame.
#include <cstdlib>

#include "fuzz_support.hpp"
#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/can/pycan_wire.hpp"

namespace pmlsm::fuzz::can_pycan_wire {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::can;
  CanFrame frame{};
  if (pycan_wire::decode(data, size, frame).status != pycan_wire::DecodeStatus::ok) return 0;
  if (!is_valid_frame(frame)) std::abort();
  std::uint8_t datagram[pycan_wire::kMaxEncodedSize];
  const std::size_t bytes = pycan_wire::encode(frame, 0.0, datagram, sizeof datagram);
  if (bytes == 0) std::abort();
  CanFrame back{};
  if (pycan_wire::decode(datagram, bytes, back).status != pycan_wire::DecodeStatus::ok) std::abort();
  bool same = back.id == frame.id && back.dlc == frame.dlc && back.rtr == frame.rtr && back.extended == frame.extended;
  for (std::size_t i = 0; i < frame.dlc && !frame.rtr; ++i) same = same && back.data[i] == frame.data[i];
  if (!same) std::abort();
  return 0;
}

}  // namespace pmlsm::fuzz::can_pycan_wire
