// A virtual EtherCAT slave (Esc on a VirtualSegment, CoE answered from a CiA 402 dictionary) fed
// frames as a master on the wire may send them: any datagram at any register, SII commands, AL
// requests, mailbox messages, and logical addresses through whatever FMMUs and sync managers
// earlier datagrams of the same input set up, on a clock that runs on frame by frame (its
// distributed clock and SYNC0). The slave never reads or writes past its memory or the frame, and
// its AL state stays one of the standard's.
#include <array>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "fuzz_support.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"

namespace pmlsm::fuzz::ethercat_slave {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::ethercat;
  VirtualCia402Slave slave;  // fresh each input: what one wrote does not carry over
  // A quarter of a millisecond a frame on the slave's clock: what SYNC0 set up fires between frames.
  std::int64_t now_ns = 0;
  VirtualSegment segment({&slave.esc()}, [&now_ns] { return now_ns += 250'000; });
  // The input as a series of frames: a 2-byte length, then that many bytes.
  std::array<std::uint8_t, kMaxEthernetFrameBytes> frame{};
  for (std::size_t at = 0; at + 2 <= size;) {
    const std::size_t length = std::min<std::size_t>(
        static_cast<std::size_t>(data[at] | (data[at + 1] << 8)) % (kMaxEthernetFrameBytes + 1), size - at - 2);
    std::memcpy(frame.data(), data + at + 2, length);
    segment.pass(frame.data(), length);
    slave.exchange();  // the application between frames
    at += 2 + length;
    const auto state = static_cast<std::uint8_t>(slave.esc().al_state());
    if (state != 1 && state != 2 && state != 4 && state != 8) std::abort();
  }
  return 0;
}

}  // namespace pmlsm::fuzz::ethercat_slave
