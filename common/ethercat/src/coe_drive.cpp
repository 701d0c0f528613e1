#include "pmlsm/ethercat/coe_drive.hpp"

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/util/validate.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>

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

namespace {

// Static names: the dictionary keeps the pointer.
constexpr std::array<const char*, kMaxAssignedPdos + 1> kRxAssignNames{
    "SM2 PDO assignment: count", "SM2 PDO assignment: RxPDO 1", "SM2 PDO assignment: RxPDO 2",
    "SM2 PDO assignment: RxPDO 3", "SM2 PDO assignment: RxPDO 4"};
constexpr std::array<const char*, kMaxAssignedPdos + 1> kTxAssignNames{
    "SM3 PDO assignment: count", "SM3 PDO assignment: TxPDO 1", "SM3 PDO assignment: TxPDO 2",
    "SM3 PDO assignment: TxPDO 3", "SM3 PDO assignment: TxPDO 4"};

constexpr std::array<const char*, 6> kOutputSyncNames{"SM2 sync parameters: highest sub-index",
                                                      "SM2 sync mode",
                                                      "SM2 cycle time",
                                                      "SM2 sync modes supported",
                                                      "SM2 minimum cycle time",
                                                      "SM2 SM event missed"};
constexpr std::array<const char*, 6> kInputSyncNames{"SM3 sync parameters: highest sub-index",
                                                     "SM3 sync mode",
                                                     "SM3 cycle time",
                                                     "SM3 sync modes supported",
                                                     "SM3 minimum cycle time",
                                                     "SM3 SM event missed"};

std::uint16_t first_pdo_of(std::uint16_t assign) {
  return assign == kObjectRxPdoAssign ? kRxPdoMapping : kTxPdoMapping;
}

// ETG.1000.6: an assigned PDO changes only while the count is 0, and is one of its direction's.
std::uint32_t check_assigned_pdo(const canopen::ObjectDictionary& d, const canopen::Entry& e,
                                 std::int64_t value) noexcept {
  if (d.get_or(e.index, 0, 0) != 0) return canopen::kAbortDeviceState;
  const std::uint16_t first = first_pdo_of(e.index);
  if (value != 0 && (value < first || value >= first + kMaxAssignedPdos)) return canopen::kAbortValueRange;
  return canopen::kAbortNone;
}

// 0x1C32:01 takes SM-synchronous or DC SYNC0; 0x1C33:01 also SM2-latched inputs (TwinCAT's 0x22).
std::uint32_t check_sync_mode(const canopen::ObjectDictionary& /*d*/, const canopen::Entry& e,
                              std::int64_t value) noexcept {
  if (value == kSyncModeSm || value == kSyncModeDcSync0) return canopen::kAbortNone;
  if (e.index == kObjectInputSyncParameters && value == kSyncModeSm2Inputs) return canopen::kAbortNone;
  return canopen::kAbortValueRange;
}

// A count: each PDO it counts is assigned and mapped with entries.
std::uint32_t check_assigned_count(const canopen::ObjectDictionary& d, const canopen::Entry& e,
                                   std::int64_t value) noexcept {
  for (std::int64_t sub = 1; sub <= value; ++sub) {
    const auto pdo = static_cast<std::uint16_t>(d.get_or(e.index, static_cast<std::uint8_t>(sub), 0));
    if (pdo == 0) return canopen::kAbortValueRange;
    const canopen::Result<canopen::PdoMap> map = canopen::read_pdo_map(d, pdo);
    if (!map || map.value.empty()) return canopen::kAbortValueRange;
  }
  return canopen::kAbortNone;
}

// The mapping objects a drive offers beyond CANopen's one or two: every PDO 0x1C12 / 0x1C13 may
// assign (kMaxAssignedPdos a direction), empty until a master maps them, with the first's checks
// (CiA 301's procedure). A cyclic synchronous velocity or position mapping with its offsets and
// the lockstep contract needs two RxPDOs and three TxPDOs of 64 bits.
void add_missing_pdo_mappings(canopen::ObjectDictionary& d) {
  static const char* const kCountNames[2][kMaxAssignedPdos] = {
      {"RxPDO 1 mapping: number of entries", "RxPDO 2 mapping: number of entries", "RxPDO 3 mapping: number of entries",
       "RxPDO 4 mapping: number of entries"},
      {"TxPDO 1 mapping: number of entries", "TxPDO 2 mapping: number of entries", "TxPDO 3 mapping: number of entries",
       "TxPDO 4 mapping: number of entries"}};
  for (const std::uint16_t first : {kRxPdoMapping, kTxPdoMapping}) {
    const int direction = first == kRxPdoMapping ? 0 : 1;
    for (std::uint8_t i = 1; i < kMaxAssignedPdos; ++i) {
      const auto pdo = static_cast<std::uint16_t>(first + i);
      if (d.find(pdo, 0) != nullptr) continue;
      for (std::uint8_t sub = 0; sub <= canopen::kPdoMaxEntries; ++sub) {
        const canopen::Entry* from = d.find(first, sub);
        if (from == nullptr) continue;
        canopen::Entry copy = *from;
        copy.index = pdo;
        copy.value = 0;
        if (sub == 0) copy.name = kCountNames[direction][i];
        d.add(copy);
      }
    }
  }
}

}  // namespace

std::int64_t interpolation_period_ns(const canopen::ObjectDictionary& d) {
  const std::optional<std::int64_t> value = d.get(canopen::kObjectInterpolationTimePeriod, 1);
  const std::optional<std::int64_t> index = d.get(canopen::kObjectInterpolationTimePeriod, 2);
  if (!value || !index || *index < -9 || *index > 0) return 1'000'000;
  std::int64_t ns = *value;
  for (std::int64_t i = -9; i < *index; ++i) ns *= 10;
  return ns;
}

void add_coe_sync_manager_objects(canopen::ObjectDictionary& d) {
  using T = canopen::DataType;
  add_missing_pdo_mappings(d);
  const auto period_ns = static_cast<std::uint32_t>(interpolation_period_ns(d));
  for (const auto& [index, names] : {std::pair{kObjectOutputSyncParameters, &kOutputSyncNames},
                                     std::pair{kObjectInputSyncParameters, &kInputSyncNames}}) {
    d.add(entry(index, 0, (*names)[0], T::kU8, kSyncParameterSmMissed));
    canopen::Entry mode = entry(index, kSyncParameterMode, (*names)[1], T::kU16, kSyncModeSm);
    mode.access = canopen::Access::kRw;
    mode.check = check_sync_mode;
    d.add(mode);
    canopen::Entry cycle = entry(index, kSyncParameterCycleTime, (*names)[2], T::kU32, 0);
    cycle.access = canopen::Access::kRw;
    d.add(cycle);
    d.add(entry(index, kSyncParameterModes, (*names)[3], T::kU16, 0x0006));
    d.add(entry(index, kSyncParameterMinCycle, (*names)[4], T::kU32, period_ns));
    canopen::Entry missed = entry(index, kSyncParameterSmMissed, (*names)[5], T::kU16, 0);
    missed.access = canopen::Access::kRo;
    d.add(missed);
  }
  d.add(entry(kObjectSyncManagerTypes, 0, "sync manager types: count", T::kU8, 4));
  d.add(entry(kObjectSyncManagerTypes, 1, "SM0: mailbox out", T::kU8, 1));
  d.add(entry(kObjectSyncManagerTypes, 2, "SM1: mailbox in", T::kU8, 2));
  d.add(entry(kObjectSyncManagerTypes, 3, "SM2: outputs", T::kU8, 3));
  d.add(entry(kObjectSyncManagerTypes, 4, "SM3: inputs", T::kU8, 4));
  for (const auto& [assign, names] :
       {std::pair{kObjectRxPdoAssign, &kRxAssignNames}, std::pair{kObjectTxPdoAssign, &kTxAssignNames}}) {
    const std::uint16_t first = first_pdo_of(assign);
    std::array<std::uint16_t, kMaxAssignedPdos> pdos{};
    std::uint8_t count = 0;
    for (std::uint8_t i = 0; i < kMaxAssignedPdos; ++i) {
      const auto pdo = static_cast<std::uint16_t>(first + i);
      const canopen::Result<canopen::PdoMap> map = canopen::read_pdo_map(d, pdo);
      if (!map || map.value.empty()) continue;
      // Assigned by default as the CANopen description sends it: a PDO mapped but not valid there
      // (a load sensor's TPDO3) is offered, for a master to assign.
      const auto communication = static_cast<std::uint16_t>(pdo - canopen::kPdoMappingOffset);
      const std::optional<std::int64_t> cob = d.get(communication, 1);
      const bool sent = !cob || (static_cast<std::uint32_t>(*cob) & canopen::kPdoCobIdInvalid) == 0;
      if (sent) pdos[count++] = pdo;
      // The PDO's COB-ID (a CANopen thing) not valid, so a master may map it anew.
      if (cob) {
        d.set(communication, 1,
              static_cast<std::int64_t>(static_cast<std::uint32_t>(*cob) | canopen::kPdoCobIdInvalid));
      }
    }
    canopen::Entry e = entry(assign, 0, (*names)[0], T::kU8, count);
    e.access = canopen::Access::kRw;
    e.min = 0;
    e.max = kMaxAssignedPdos;
    e.check = check_assigned_count;
    d.add(e);
    for (std::uint8_t i = 0; i < kMaxAssignedPdos; ++i) {
      canopen::Entry pdo = entry(assign, static_cast<std::uint8_t>(i + 1), (*names)[i + 1], T::kU16, pdos[i]);
      pdo.access = canopen::Access::kRw;
      pdo.check = check_assigned_pdo;
      d.add(pdo);
    }
  }
}

std::vector<canopen::PdoMap> CoeProcessImage::assigned(const canopen::ObjectDictionary& dictionary,
                                                       std::uint16_t assign) {
  const auto count = static_cast<std::uint8_t>(dictionary.get_or(assign, 0, 0));
  std::vector<canopen::PdoMap> maps;
  for (std::uint8_t i = 1; i <= count; ++i) {
    const auto pdo = static_cast<std::uint16_t>(dictionary.get_or(assign, i, 0));
    maps.push_back(map_of(dictionary, pdo));
  }
  return maps;
}

std::uint16_t CoeProcessImage::bytes_of(const std::vector<canopen::PdoMap>& maps) {
  std::uint16_t bytes = 0;
  for (const canopen::PdoMap& m : maps) bytes = static_cast<std::uint16_t>(bytes + m.byte_length());
  return bytes;
}

CoeProcessImage::CoeProcessImage(canopen::ObjectDictionary& dictionary, std::uint16_t outputs_at,
                                 std::uint16_t inputs_at)
    : dictionary_(dictionary),
      rx_(assigned(dictionary, kObjectRxPdoAssign)),
      tx_(assigned(dictionary, kObjectTxPdoAssign)),
      outputs_at_(outputs_at),
      inputs_at_(inputs_at) {}

void CoeProcessImage::rebuild() {
  std::vector<canopen::PdoMap> rx = assigned(dictionary_, kObjectRxPdoAssign);
  std::vector<canopen::PdoMap> tx = assigned(dictionary_, kObjectTxPdoAssign);
  rx_ = std::move(rx);
  tx_ = std::move(tx);
}

bool CoeProcessImage::outputs_map(std::uint16_t index) const {
  return std::any_of(rx_.begin(), rx_.end(), [&](const canopen::PdoMap& m) {
    return std::any_of(m.begin(), m.end(), [&](const canopen::PdoMapEntry& e) { return e.index == index; });
  });
}

// The PDO codec works on CAN frames: the same bytes, an id it does not check. Each PDO follows
// the one before in the sync manager's memory.
void CoeProcessImage::take_outputs(Esc& esc) {
  auto at = outputs_at_;
  for (const canopen::PdoMap& map : rx_) {
    canopen::CanFrame outputs{};
    outputs.id = 0x200;
    outputs.dlc = map.byte_length();
    for (std::uint8_t i = 0; i < outputs.dlc; ++i) outputs.data[i] = esc.byte_at(static_cast<std::uint16_t>(at + i));
    if (!canopen::unpack_pdo(map, dictionary_, outputs)) ++refused_outputs_;
    at = static_cast<std::uint16_t>(at + outputs.dlc);
  }
}

void CoeProcessImage::give_inputs(Esc& esc) {
  auto at = inputs_at_;
  for (const canopen::PdoMap& map : tx_) {
    const canopen::Result<canopen::CanFrame> inputs = canopen::pack_pdo(map, dictionary_, 0x180);
    if (inputs) esc.write_memory(at, inputs.value.data.data(), inputs.value.dlc);
    at = static_cast<std::uint16_t>(at + map.byte_length());
  }
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
  info.mailbox_protocols = 0x0004;                      // CoE
  info.coe_details = 0x01 | kCoeDetailsCompleteAccess;  // SDO, and complete access
  info.group = "Drive";
  info.order = "pmlsm-virtual-drive";
  info.name = "PMLSM virtual drive";
  info.sync_managers = {{kMailboxReceiveAt, kMailboxBytes, kSmControlMailboxWrite, 1, 1},
                        {kMailboxSendAt, kMailboxBytes, kSmControlMailboxRead, 1, 2},
                        {kOutputsAt, output_bytes, kSmControlOutputs, 1, 3},
                        {kInputsAt, input_bytes, kSmControlInputs, 1, 4}};
  return build_sii(info);
}

canopen::ObjectDictionary VirtualCia402Slave::make_dictionary(const std::vector<std::uint16_t>& sii,
                                                              std::uint32_t supported_drive_modes) {
  // The identity and name the SII gives (a drive's dump: its own), else ours.
  const SiiInfo info = parse_sii(sii.size() >= sii::kMinWords ? sii : virtual_sii(0, 0));
  canopen::Cia402DictionaryConfig config;
  config.vendor_id = info.vendor_id;
  config.product_code = info.product_code;
  if (!info.name.empty()) config.device_name = info.name;
  config.supported_drive_modes = supported_drive_modes;
  return canopen::make_cia402_dictionary(canopen::NodeId(1), config);
}

canopen::ObjectDictionary VirtualCia402Slave::with_sync_manager_objects(canopen::ObjectDictionary dictionary) {
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
    : VirtualCia402Slave(make_dictionary(sii), sii) {}

VirtualCia402Slave::VirtualCia402Slave(canopen::ObjectDictionary dictionary, std::vector<std::uint16_t> sii)
    : dictionary_(with_sync_manager_objects(std::move(dictionary))),
      process_(dictionary_, kOutputsAt, kInputsAt),
      esc_(esc_params(std::move(sii), process_)),
      coe_(dictionary_, canopen::NodeId(1)) {
  esc_.set_mailbox_handler(&coe_);
  esc_.set_before_safeop([this] { return take_mapping(); });
  esc_.set_before_op([this] { return check_synchronisation(); });
}

bool VirtualCia402Slave::dc_synchronous() const {
  return dictionary_.get_or(kObjectOutputSyncParameters, kSyncParameterMode, kSyncModeSm) == kSyncModeDcSync0;
}

std::uint16_t VirtualCia402Slave::check_synchronisation() const {
  if (!dc_synchronous()) return 0;
  const std::int64_t period_ns = interpolation_period_ns(dictionary_);
  const std::int64_t written = dictionary_.get_or(kObjectOutputSyncParameters, kSyncParameterCycleTime, 0);
  if (written != 0 && written != period_ns) return al_code::kInvalidSyncCycleTime;
  const Sync0State& sync0 = esc_.sync0();
  if (!sync0.active || sync0.cycle_ns != period_ns) return al_code::kInvalidDcSyncConfiguration;
  return 0;
}

bool VirtualCia402Slave::post_emergency(std::uint16_t error_code) {
  std::array<std::uint8_t, kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes> message{};
  const auto error_register = static_cast<std::uint8_t>(dictionary_.get_or(canopen::kObjectErrorRegister, 0, 0));
  const std::size_t size = coe_.write_emergency(message.data(), error_code, error_register);
  return esc_.post_mailbox(message.data(), size);
}

std::uint16_t VirtualCia402Slave::take_mapping() {
  try {
    process_.rebuild();
  } catch (const std::invalid_argument&) {
    return al_code::kInvalidOutputConfiguration;
  }
  esc_.set_process_data_bytes(process_.output_bytes(), process_.input_bytes());
  return 0;
}

VirtualEthercatDrive::VirtualEthercatDrive(const canopen::Cia402ApplicationParams& params, drive::Drive& drive, Log log,
                                           std::vector<std::uint16_t> sii)
    : slave_(VirtualCia402Slave::make_dictionary(
                 sii, params.own_loops ? canopen::kSupportedModesCyclicSynchronous : canopen::kSupportedModesTorque),
             sii),
      application_(params, slave_.dictionary(), drive, *this),
      log_(std::move(log)) {
  slave_.esc().set_sync0_handler([this](std::int64_t now_ns) { on_sync0(now_ns); });
}

VirtualEthercatDrive::VirtualEthercatDrive(const canopen::Cia402ApplicationParams& params, drive::Drive& drive,
                                           canopen::ObjectDictionary dictionary, Log log,
                                           std::vector<std::uint16_t> sii)
    : slave_(std::move(dictionary), std::move(sii)),
      application_(params, slave_.dictionary(), drive, *this),
      log_(std::move(log)) {
  slave_.esc().set_sync0_handler([this](std::int64_t now_ns) { on_sync0(now_ns); });
}

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

void VirtualEthercatDrive::on_sync0(std::int64_t now_ns) {
  Esc& esc = slave_.esc();
  const std::uint64_t written = esc.outputs_written();
  const bool new_outputs = written != outputs_at_pulse_;
  outputs_at_pulse_ = written;
  if (!slave_.dc_synchronous() || esc.al_state() != AlState::kOp) return;
  if (!new_outputs) {
    ++sm_missed_;
    slave_.dictionary().set(kObjectOutputSyncParameters, kSyncParameterSmMissed,
                            static_cast<std::int64_t>(std::min<std::uint64_t>(sm_missed_, 0xFFFF)));
  }
  slave_.process().take_outputs(esc);
  application_.apply_controlword(now_ns);
  application_.step_period(now_ns);
  slave_.process().give_inputs(esc);
}

void VirtualEthercatDrive::after_frame(std::int64_t now_ns) {
  check_watchdog(now_ns);
  Esc& esc = slave_.esc();
  if (slave_.dc_synchronous()) {
    // The periods are the pulses' (on_sync0); between frames only the watch and the objects.
    const std::uint64_t written = esc.outputs_written();
    if (written > outputs_seen_) outputs_ns_ = now_ns;
    outputs_seen_ = written;
    if (esc.al_state() == AlState::kOp) return;
    application_.update_objects();
    if (esc.al_state() == AlState::kSafeOp) slave_.process().give_inputs(esc);
    return;
  }
  const AlState state = esc.al_state();
  const std::uint64_t written = esc.outputs_written();
  const std::uint64_t cycles = written - outputs_seen_;
  outputs_seen_ = written;
  if (cycles > 0) outputs_ns_ = now_ns;
  if (state != AlState::kOp) {
    // Objects written by SDO show in the live ones (0x6060 in 0x6061) before any period.
    application_.update_objects();
    cycles_outside_op_ += cycles;
    if (state == AlState::kSafeOp) slave_.process().give_inputs(esc);
    return;
  }
  // Called between frames, so one cycle at most; should the owner fall behind, each cycle missed is
  // still a period (the master's cycles are the drive's clock), with the outputs SM2 holds now.
  for (std::uint64_t i = 0; i < cycles; ++i) {
    slave_.process().take_outputs(esc);
    application_.apply_controlword(now_ns);
    const auto command_tick = static_cast<std::uint64_t>(slave_.dictionary().get_or(canopen::kObjectCommandTick, 0, 0));
    // The lockstep contract when the outputs carry the command tick (the mapping the master chose).
    if (slave_.process().outputs_map(canopen::kObjectCommandTick) &&
        command_tick != (application_.periods() & 0xFFFFFFFFULL)) {
      ++unstepped_cycles_;  // a frame sent again, or a walk's cycle before the run: no period
      continue;
    }
    application_.step_period(now_ns);
  }
  slave_.process().give_inputs(esc);
}

}  // namespace pmlsm::ethercat
