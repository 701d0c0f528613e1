// A virtual slave for the EtherCAT tests that talk CoE: its mailboxes in its SII (receive at
// 0x1000, send at 0x1080, 128 bytes each, CoE only) and a CiA 402 dictionary answering over them.
#pragma once

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/ethercat/sii.hpp"

#include <cstdint>
#include <stdexcept>
#include <vector>

namespace pmlsm::ethercat::test {

inline EscParams coe_slave_params() {
  EscParams p;
  p.sii.assign(sii::kMinWords, 0);
  p.sii[sii::kMailboxReceiveOffset] = 0x1000;
  p.sii[sii::kMailboxReceiveSize] = 128;
  p.sii[sii::kMailboxSendOffset] = 0x1080;
  p.sii[sii::kMailboxSendSize] = 128;
  p.sii[sii::kMailboxProtocols] = 0x0004;
  p.sii[sii::kFirstCategory] = 0xFFFF;
  return p;
}

/// The slave, its dictionary and the CoE server answering from it, wired together.
struct CoeSlave {
  Esc esc{coe_slave_params()};
  canopen::ObjectDictionary dictionary = canopen::make_cia402_dictionary(canopen::NodeId(1));
  CoeSdoServer coe{dictionary, canopen::NodeId(1)};
  CoeSlave() { esc.set_mailbox_handler(&coe); }
  CoeSlave(const CoeSlave&) = delete;
  CoeSlave& operator=(const CoeSlave&) = delete;
};

/// The one slave on `master`'s link addressed (0x1001), its SII read and its mailbox set, in
/// PREOP: what a CoE exchange needs. @throws std::runtime_error when it does not reach PREOP.
inline SlaveInfo to_preop(Master& master) {
  master.assign_station_addresses(1);
  const SlaveInfo info = master.read_slave_info(0x1001);
  master.configure_mailbox(info);
  if (!master.request_state(0x1001, AlState::kPreOp).reached) throw std::runtime_error("the slave did not reach PREOP");
  return info;
}

/// The virtual drive's SII with both mailboxes `bytes` long (at least the 16 of an SDO message),
/// for transfers that need segments where a 128-byte mailbox would not.
inline std::vector<std::uint16_t> sii_with_mailboxes(std::uint16_t bytes) {
  SiiInfo info = parse_sii(VirtualCia402Slave::virtual_sii(8, 16));
  info.mailbox_receive_size = bytes;
  info.mailbox_send_size = bytes;
  info.sync_managers[0].length = bytes;
  info.sync_managers[1].length = bytes;
  return build_sii(info);
}

}  // namespace pmlsm::ethercat::test
