#include "pmlsm/ethercat/coe_drive.hpp"

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/util/validate.hpp"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace pmlsm::ethercat {

namespace {

canopen::Entry entry(std::uint16_t index, std::uint8_t subindex, const char* name, canopen::DataType type,
                     std::int64_t value) {
  canopen::Entry e;
  e.index = index;
  e.subindex = subindex;
  e.name = name;
  e.type = type;
  e.access = canopen::Access::kConst;
  e.value = value;
  return e;
}

canopen::PdoMap map_of(const canopen::ObjectDictionary& dictionary, std::uint16_t index) {
  const canopen::Result<canopen::PdoMap> map = canopen::read_pdo_map(dictionary, index);
  if (!map) {
    throw std::invalid_argument("PDO mapping " + format_hex(index, 4) + ": " + canopen::to_string(map.error) + " (" +
                                map.detail + ")");
  }
  return map.value;
}

}  // namespace

void add_coe_sync_manager_objects(canopen::ObjectDictionary& d) {
  using T = canopen::DataType;
  d.add(entry(kObjectSyncManagerTypes, 0, "sync manager types: count", T::kU8, 4));
  d.add(entry(kObjectSyncManagerTypes, 1, "SM0: mailbox out", T::kU8, 1));
  d.add(entry(kObjectSyncManagerTypes, 2, "SM1: mailbox in", T::kU8, 2));
  d.add(entry(kObjectSyncManagerTypes, 3, "SM2: outputs", T::kU8, 3));
  d.add(entry(kObjectSyncManagerTypes, 4, "SM3: inputs", T::kU8, 4));
  d.add(entry(kObjectRxPdoAssign, 0, "SM2 PDO assignment: count", T::kU8, 1));
  d.add(entry(kObjectRxPdoAssign, 1, "SM2 PDO assignment: RxPDO 1", T::kU16, kRxPdoMapping));
  d.add(entry(kObjectTxPdoAssign, 0, "SM3 PDO assignment: count", T::kU8, 1));
  d.add(entry(kObjectTxPdoAssign, 1, "SM3 PDO assignment: TxPDO 1", T::kU16, kTxPdoMapping));
}

CoeProcessImage::CoeProcessImage(canopen::ObjectDictionary& dictionary, std::uint16_t outputs_at,
                                 std::uint16_t inputs_at)
    : dictionary_(dictionary),
      rx_(map_of(dictionary, kRxPdoMapping)),
      tx_(map_of(dictionary, kTxPdoMapping)),
      outputs_at_(outputs_at),
      inputs_at_(inputs_at) {}

// The PDO codec works on CAN frames: the same bytes, an id it does not check.
void CoeProcessImage::take_outputs(Esc& esc) {
  canopen::CanFrame outputs{};
  outputs.id = 0x200;
  outputs.dlc = rx_.byte_length();
  for (std::uint8_t i = 0; i < outputs.dlc; ++i)
    outputs.data[i] = esc.byte_at(static_cast<std::uint16_t>(outputs_at_ + i));
  if (!canopen::unpack_pdo(rx_, dictionary_, outputs)) ++refused_outputs_;
}

void CoeProcessImage::give_inputs(Esc& esc) {
  const canopen::Result<canopen::CanFrame> inputs = canopen::pack_pdo(tx_, dictionary_, 0x180);
  if (inputs) esc.write_memory(inputs_at_, inputs.value.data.data(), inputs.value.dlc);
}

std::vector<std::uint16_t> VirtualCia402Slave::virtual_sii(std::uint16_t output_bytes, std::uint16_t input_bytes) {
  SiiInfo info;
  info.vendor_id = kVendorId;
  info.product_code = kProductCode;
  info.revision = 1;
  info.mailbox_receive_offset = kMailboxReceiveAt;
  info.mailbox_receive_size = kMailboxBytes;
  info.mailbox_send_offset = kMailboxSendAt;
  info.mailbox_send_size = kMailboxBytes;
  info.mailbox_protocols = 0x0004;  // CoE
  info.group = "Drive";
  info.order = "pmlsm-virtual-drive";
  info.name = "PMLSM virtual drive";
  info.sync_managers = {{kMailboxReceiveAt, kMailboxBytes, kSmControlMailboxWrite, 1, 1},
                        {kMailboxSendAt, kMailboxBytes, kSmControlMailboxRead, 1, 2},
                        {kOutputsAt, output_bytes, kSmControlOutputs, 1, 3},
                        {kInputsAt, input_bytes, kSmControlInputs, 1, 4}};
  return build_sii(info);
}

canopen::ObjectDictionary VirtualCia402Slave::make_dictionary(const std::vector<std::uint16_t>& sii) {
  canopen::Cia402DictionaryConfig config;
  if (sii.size() >= sii::kMinWords) {
    config.vendor_id = static_cast<std::uint32_t>(sii[sii::kVendorId] | (sii[sii::kVendorId + 1] << 16));
    config.product_code = static_cast<std::uint32_t>(sii[sii::kProductCode] | (sii[sii::kProductCode + 1] << 16));
  } else {
    config.vendor_id = kVendorId;
    config.product_code = kProductCode;
  }
  canopen::ObjectDictionary dictionary = canopen::make_cia402_dictionary(canopen::NodeId(1), config);
  add_coe_sync_manager_objects(dictionary);
  return dictionary;
}

EscParams VirtualCia402Slave::esc_params(std::vector<std::uint16_t> sii, const CoeProcessImage& process) {
  EscParams params;
  params.sii = sii.empty() ? virtual_sii(process.output_bytes(), process.input_bytes()) : std::move(sii);
  params.output_bytes = process.output_bytes();
  params.input_bytes = process.input_bytes();
  return params;
}

VirtualCia402Slave::VirtualCia402Slave(std::vector<std::uint16_t> sii)
    : dictionary_(make_dictionary(sii)),
      process_(dictionary_, kOutputsAt, kInputsAt),
      esc_(esc_params(std::move(sii), process_)),
      coe_(dictionary_, canopen::NodeId(1)) {
  esc_.set_mailbox_handler(&coe_);
}

VirtualEthercatDrive::VirtualEthercatDrive(const canopen::Cia402ApplicationParams& params, drive::Drive& drive, Log log,
                                           std::vector<std::uint16_t> sii)
    : slave_(std::move(sii)), application_(params, slave_.dictionary(), drive, *this), log_(std::move(log)) {}

void VirtualEthercatDrive::check_watchdog(std::int64_t now_ns) {
  Esc& esc = slave_.esc();
  const bool op = esc.al_state() == AlState::kOp;
  if (op && !in_op_) outputs_ns_ = now_ns;  // the watch starts at the entry into OP
  in_op_ = op;
  const std::int64_t watchdog_ns = esc.process_data_watchdog_ns();
  if (!op || watchdog_ns == 0 || now_ns - outputs_ns_ <= watchdog_ns) return;
  esc.process_data_watchdog_expired();
  in_op_ = false;
  if (application_.enabled()) {
    char why[96];
    std::snprintf(why, sizeof why, "no process data for %.1f ms (SM watchdog %.1f ms)",
                  static_cast<double>(now_ns - outputs_ns_) * 1e-6, static_cast<double>(watchdog_ns) * 1e-6);
    application_.raise_fault(canopen::kEmcySyncLost, why, now_ns);
  }
  log(true, "process-data watchdog expired: OP -> SAFEOP (AL status code 0x001B)", now_ns);
}

void VirtualEthercatDrive::after_frame(std::int64_t now_ns) {
  check_watchdog(now_ns);
  Esc& esc = slave_.esc();
  const AlState state = esc.al_state();
  const std::uint64_t written = esc.outputs_written();
  const std::uint64_t cycles = written - outputs_seen_;
  outputs_seen_ = written;
  if (cycles > 0) outputs_ns_ = now_ns;
  if (state != AlState::kOp) {
    cycles_outside_op_ += cycles;
    if (state == AlState::kSafeOp) slave_.process().give_inputs(esc);
    return;
  }
  // Called between frames, so one cycle at most; should the owner fall behind, each cycle missed is
  // still a period (the master's cycles are the drive's clock), with the outputs SM2 holds now.
  for (std::uint64_t i = 0; i < cycles; ++i) {
    slave_.process().take_outputs(esc);
    application_.apply_controlword(now_ns);
    application_.step_period(now_ns);
  }
  slave_.process().give_inputs(esc);
}

}  // namespace pmlsm::ethercat
