// A slave's SII image as a master reads it or a drive's dump holds it (parse_sii): refused with a
// named error or parsed; a parsed image built again (build_sii) reads back the same identity,
// mailbox, name, order code, group and sync managers.
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "fuzz_support.hpp"
#include "pmlsm/ethercat/sii.hpp"

namespace pmlsm::fuzz::ethercat_sii {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::ethercat;
  std::vector<std::uint16_t> words;
  for (std::size_t i = 0; i + 1 < size && words.size() < kSiiMaxWords; i += 2) {
    words.push_back(static_cast<std::uint16_t>(data[i] | (data[i + 1] << 8)));
  }
  SiiInfo info;
  try {
    info = parse_sii(words);
  } catch (const std::invalid_argument&) {
    return 0;
  }
  const SiiInfo back = parse_sii(build_sii(info));
  const bool same = back.vendor_id == info.vendor_id && back.product_code == info.product_code &&
                    back.revision == info.revision && back.serial == info.serial &&
                    back.mailbox_receive_offset == info.mailbox_receive_offset &&
                    back.mailbox_send_size == info.mailbox_send_size && back.name == info.name &&
                    back.order == info.order && back.group == info.group && back.sync_managers == info.sync_managers;
  if (!same) std::abort();
  return 0;
}

}  // namespace pmlsm::fuzz::ethercat_sii
