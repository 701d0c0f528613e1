// EtherCAT frames as a raw socket or a capture delivers them (parse_ethernet_frame). A frame that
// parses is built again datagram by datagram (FrameBuilder), and the rebuilt frame parses to the
// same datagrams: commands, indices, addresses, lengths, IRQs, data and working counters.
#include <cstdlib>
#include <cstring>

#include "fuzz_support.hpp"
#include "pmlsm/ethercat/frame.hpp"

namespace pmlsm::fuzz::ethercat_frames {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::ethercat;
  ParsedFrame parsed;
  if (parse_ethernet_frame(data, size, parsed) != FrameError::kNone) return 0;
  if (parsed.count == 0 || parsed.count > kMaxDatagramsPerFrame) std::abort();
  FrameBuilder rebuilt(parsed.source, parsed.destination);
  for (std::size_t i = 0; i < parsed.count; ++i) {
    const DatagramView& d = parsed.datagrams[i];
    if (!rebuilt.add(d.header.command, d.header.index, d.header.address, d.data, d.header.length, d.working_counter,
                     d.header.irq)) {
      std::abort();  // what fitted in a frame fits again
    }
  }
  ParsedFrame again;
  const Bytes bytes = rebuilt.ethernet();
  if (parse_ethernet_frame(bytes.data, bytes.size, again) != FrameError::kNone || again.count != parsed.count) {
    std::abort();
  }
  for (std::size_t i = 0; i < parsed.count; ++i) {
    const DatagramView& a = parsed.datagrams[i];
    const DatagramView& b = again.datagrams[i];
    const bool same = a.header.command == b.header.command && a.header.index == b.header.index &&
                      a.header.address == b.header.address && a.header.length == b.header.length &&
                      a.header.irq == b.header.irq && a.working_counter == b.working_counter &&
                      a.header.more == b.header.more && std::memcmp(a.data, b.data, a.header.length) == 0;
    if (!same) std::abort();
  }
  return 0;
}

}  // namespace pmlsm::fuzz::ethercat_frames
