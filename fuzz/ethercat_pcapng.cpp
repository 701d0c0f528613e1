// A capture file (pcapng, as `pmlsm ethercat pcap` reads Wireshark's or a drive vendor's): refused
// with a named error or read to its end, every frame in it parsed and its SDO messages described,
// without reading past the bytes given.
#include <stdexcept>
#include <vector>

#include "fuzz_support.hpp"
#include "pmlsm/ethercat/capture.hpp"

namespace pmlsm::fuzz::ethercat_pcapng {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::ethercat;
  try {
    PcapngReader reader(std::vector<std::uint8_t>(data, data + size), "fuzz.pcapng");
    const CaptureDecode d = decode_capture(reader);
    for (const CaptureDecode::Sdo& s : d.sdos) (void)describe(s.seen);
  } catch (const std::runtime_error&) {
    // a malformed file, named
  }
  return 0;
}

}  // namespace pmlsm::fuzz::ethercat_pcapng
