// The CoE side of a CiA 402 slave on EtherCAT: the sync manager objects a master reads to map the
// process data (0x1C00: each sync manager's type; 0x1C12 / 0x1C13: the RxPDO 0x1600 assigned to
// SM2, the outputs, and the TxPDO 0x1A00 to SM3, the inputs), added to the CiA 402 dictionary
// of common/canopen; and the process image between the sync managers' memory and the
// dictionary's mapped objects, through canopen's PDO mapping (the same bytes a CANopen PDO
// carries).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "pmlsm/canopen/cia402_application.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/drive/drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/mailbox.hpp"

namespace pmlsm::ethercat {

inline constexpr std::uint16_t kObjectSyncManagerTypes = 0x1C00;
inline constexpr std::uint16_t kObjectRxPdoAssign = 0x1C12;  ///< SM2, outputs
inline constexpr std::uint16_t kObjectTxPdoAssign = 0x1C13;  ///< SM3, inputs
inline constexpr std::uint16_t kRxPdoMapping = 0x1600;       ///< the first RxPDO; 0x1600-0x1603 looked at
inline constexpr std::uint16_t kTxPdoMapping = 0x1A00;       ///< the first TxPDO; 0x1A00-0x1A03 looked at
inline constexpr std::uint8_t kMaxAssignedPdos = 4;
/// ETG.1020's sync manager parameters: how the outputs (SM2) and the inputs (SM3) are synchronised.
inline constexpr std::uint16_t kObjectOutputSyncParameters = 0x1C32;
inline constexpr std::uint16_t kObjectInputSyncParameters = 0x1C33;
inline constexpr std::uint8_t kSyncParameterMode = 1;         ///< u16 rw: the sync mode
inline constexpr std::uint8_t kSyncParameterCycleTime = 2;    ///< u32 rw: the master's cycle [ns]
inline constexpr std::uint8_t kSyncParameterModes = 4;        ///< u16 const: the modes supported
inline constexpr std::uint8_t kSyncParameterMinCycle = 5;     ///< u32 const: the shortest cycle [ns]
inline constexpr std::uint8_t kSyncParameterSmMissed = 0x0B;  ///< u16 ro: cycles without the outputs in time
/// Sync modes (0x1C32:01, 0x1C33:01): synchronous to the SM2 event, to the DC's SYNC0, and (inputs
/// only) latched at the SM2 event as TwinCAT writes it.
inline constexpr std::uint16_t kSyncModeSm = 0x0001;
inline constexpr std::uint16_t kSyncModeDcSync0 = 0x0002;
inline constexpr std::uint16_t kSyncModeSm2Inputs = 0x0022;

/// Adds 0x1C00 (4 sync managers: mailbox out, mailbox in, outputs, inputs) and 0x1C12 / 0x1C13:
/// every RxPDO (0x1600-0x1603) and TxPDO (0x1A00-0x1A03) whose mapping the dictionary has with
/// entries, in order. The CiA 402 dictionary alone gives 0x1600 and 0x1A00; a CANopen device's
/// (configs/canopen) its RPDO1 and TPDO1 + TPDO2, the same objects on EtherCAT; the mapping
/// objects of the rest of 0x1600-0x1603 / 0x1A00-0x1A03 are added empty, with the first's checks,
/// for a master to map (a velocity or position mapping needs more than 64 bits). A master may
/// assign others in PREOP (ETG.1000.6): sub-indices 1-4 change only while the count (sub-index 0)
/// is 0 and name a PDO of their direction; a count needs each PDO it counts mapped. The PDOs'
/// COB-IDs (0x1400.., 0x1800..), which EtherCAT does not use, are marked not valid so their
/// mappings can be written (CiA 301 changes a mapping only of a PDO not valid).
/// And 0x1C32 / 0x1C33 (ETG.1020), sub-indices 1, 2, 4, 5 and 0x0B: the sync mode a master chooses
/// (SM-synchronous, 1, as the slave starts; DC SYNC0, 2), the cycle it writes, the modes supported
/// (0x0006: SM-synchronous and DC SYNC0) and the shortest cycle (the dictionary's interpolation
/// period 0x60C2, the one period the drive steps; 1 ms without it); 0x1C32:0B counts the SYNC0
/// pulses that found no new outputs.
/// @throws std::invalid_argument from the dictionary (full, or an object already there).
void add_coe_sync_manager_objects(canopen::ObjectDictionary& dictionary);

/// The dictionary's period (0x60C2: value x 10^index s) in ns; 1 ms without the object.
std::int64_t interpolation_period_ns(const canopen::ObjectDictionary& dictionary);

/// The slave application's side of the process data, between frames.
class CoeProcessImage {
 public:
  /// The PDOs 0x1C12 and 0x1C13 assign, in order, each map after the one before; SM2's memory
  /// at `outputs_at`, SM3's at `inputs_at`.
  /// @throws std::invalid_argument when an assignment or a map is not valid against the dictionary.
  CoeProcessImage(canopen::ObjectDictionary& dictionary, std::uint16_t outputs_at, std::uint16_t inputs_at);
  std::uint16_t output_bytes() const { return bytes_of(rx_); }
  std::uint16_t input_bytes() const { return bytes_of(tx_); }
  /// Whether the outputs carry object `index` (the lockstep contract's command tick).
  bool outputs_map(std::uint16_t index) const;
  /// The assignment and mappings read again (a master wrote them in PREOP; at PREOP -> SAFEOP).
  /// @throws std::invalid_argument as the constructor; the image is then unchanged.
  void rebuild();
  /// The outputs the master wrote into SM2 into the dictionary's mapped objects. Never throws;
  /// outputs the dictionary refuses (out of range) are counted and not written.
  void take_outputs(Esc& esc);
  /// The mapped TxPDO objects into SM3 for the master's next read. Never throws.
  void give_inputs(Esc& esc);
  /// Both, in that order.
  void exchange(Esc& esc) {
    take_outputs(esc);
    give_inputs(esc);
  }
  std::uint64_t refused_outputs() const { return refused_outputs_; }

 private:
  static std::vector<canopen::PdoMap> assigned(const canopen::ObjectDictionary& dictionary, std::uint16_t assign);
  static std::uint16_t bytes_of(const std::vector<canopen::PdoMap>& maps);

  canopen::ObjectDictionary& dictionary_;
  std::vector<canopen::PdoMap> rx_;
  std::vector<canopen::PdoMap> tx_;
  std::uint16_t outputs_at_;
  std::uint16_t inputs_at_;
  std::uint64_t refused_outputs_ = 0;
};

/// A virtual CiA 402 slave on EtherCAT: its ESC, the CiA 402 dictionary of common/canopen with the
/// sync manager objects, SDO over CoE on it, and its process image. At PREOP -> SAFEOP it takes the
/// mapping the master left (the image rebuilt, SM2 and SM3 checked against its lengths); one the
/// dictionary refuses is AL status code 0x001D (invalid output configuration). `pmlsm ethercat
/// serve` runs one; tests and the fuzz target build one the same way.
class VirtualCia402Slave {
 public:
  static constexpr std::uint16_t kMailboxReceiveAt = 0x1000;
  static constexpr std::uint16_t kMailboxSendAt = 0x1080;
  static constexpr std::uint16_t kMailboxBytes = 128;
  static constexpr std::uint16_t kOutputsAt = 0x1100;  ///< SM2
  static constexpr std::uint16_t kInputsAt = 0x1180;   ///< SM3
  static constexpr std::uint32_t kVendorId = 0;        ///< none of ETG's list
  static constexpr std::uint32_t kProductCode = 0x00005001;

  /// `sii`: the image to answer with (a drive's dump: its identity goes into 0x1018 too); empty:
  /// its own (virtual_sii()). @throws std::invalid_argument from the image or the dictionary.
  explicit VirtualCia402Slave(std::vector<std::uint16_t> sii = {});
  /// With a CiA 402 dictionary of the caller's (a CANopen device's, configs/canopen), the sync
  /// manager objects added. @throws std::invalid_argument as above.
  VirtualCia402Slave(canopen::ObjectDictionary dictionary, std::vector<std::uint16_t> sii);
  VirtualCia402Slave(const VirtualCia402Slave&) = delete;
  VirtualCia402Slave& operator=(const VirtualCia402Slave&) = delete;

  Esc& esc() { return esc_; }
  canopen::ObjectDictionary& dictionary() { return dictionary_; }
  const CoeProcessImage& process() const { return process_; }
  CoeProcessImage& process() { return process_; }
  const CoeSdoServer& coe() const { return coe_; }
  /// The application between frames: the process image (CoeProcessImage::exchange).
  void exchange() { process_.exchange(esc_); }
  /// The master chose DC SYNC0 (0x1C32:01 = 2): a period at each SYNC0 pulse, not at each SM2 event.
  bool dc_synchronous() const;
  /// A CoE emergency (the error code and the dictionary's error register 0x1001) into the send
  /// mailbox, for the master's next read of it. False when it could not be posted (no mailbox yet,
  /// or the queue full: counted by the ESC).
  bool post_emergency(std::uint16_t error_code);

  /// Its own SII: identity, the name "PMLSM virtual drive", a 128-byte CoE mailbox at 0x1000 and
  /// 0x1080, and its sync managers with the process data's lengths.
  static std::vector<std::uint16_t> virtual_sii(std::uint16_t output_bytes, std::uint16_t input_bytes);
  /// The CiA 402 dictionary with the identity and name `sii` gives (empty: virtual_sii()'s) and
  /// 0x6502 = `supported_drive_modes`.
  static canopen::ObjectDictionary make_dictionary(
      const std::vector<std::uint16_t>& sii, std::uint32_t supported_drive_modes = canopen::kSupportedModesTorque);

 private:
  static canopen::ObjectDictionary with_sync_manager_objects(canopen::ObjectDictionary dictionary);
  static EscParams esc_params(std::vector<std::uint16_t> sii, const CoeProcessImage& process);
  /// PREOP -> SAFEOP: the mapping the master left taken (0), or refused (0x001D).
  std::uint16_t take_mapping();
  /// SAFEOP -> OP in DC SYNC0 mode: SYNC0 running at the drive's period (else 0x0030), a cycle
  /// written to 0x1C32:02 that is that period (else 0x0035).
  std::uint16_t check_synchronisation() const;

  canopen::ObjectDictionary dictionary_;
  CoeProcessImage process_;
  Esc esc_;
  CoeSdoServer coe_;
};

/// A virtual CiA 402 drive on EtherCAT: VirtualCia402Slave's ESC, dictionary and CoE server with
/// the drive application of common/canopen (Cia402Application) over a drive backend, in cyclic
/// synchronous torque, synchronous to SM2 (as a drive runs without distributed clocks): in OP,
/// every process-data cycle whose outputs the master completed is one period, the controlword
/// applied (the power-state walk), the target torque applied for the period, the actual values
/// written back for the master's next read (so the master reads the period before, as on a real
/// ring). In SAFEOP the inputs are kept current and the outputs are not applied (ETG.1000.6:
/// outputs in a safe state). The process-data watchdog (the ESC's 0x0420, 100 ms unless the
/// master sets it): in OP, no outputs for longer than it since the last ones (or the entry into
/// OP) drops the slave to SAFEOP with AL status code 0x001B and faults an enabled drive with
/// 0x8700 (force off). The drive's faults go out as counted emergencies.
///
/// When the master chooses DC SYNC0 (0x1C32:01 = 2, SYNC0 running at the drive's period, checked
/// at SAFEOP -> OP), a period is stepped at each SYNC0 pulse instead (the ESC's SYNC0 interrupt, as
/// the slave's clock passes it), with the outputs SM2 holds then, whether new ones came or not; the
/// actual values are in SM3 for the master's next read. Pulses without new outputs count in
/// 0x1C32:0B. The command tick does not gate the pulses: the slave's clock, not the master's frames,
/// is the drive's time (realtime only).
class VirtualEthercatDrive : canopen::Cia402ApplicationEvents {
 public:
  /// A line for the owner's log (error false: a state change; true: a fault or a refusal).
  using Log = std::function<void(bool error, const std::string& line, std::int64_t now_ns)>;

  /// `drive` outlives it; `sii` as VirtualCia402Slave's; the dictionary offers the velocity and
  /// position modes when `params` has the drive's own loops. @throws std::invalid_argument from the
  /// image, the dictionary or the scaling.
  VirtualEthercatDrive(const canopen::Cia402ApplicationParams& params, drive::Drive& drive, Log log = {},
                       std::vector<std::uint16_t> sii = {});
  /// With the CiA 402 dictionary `dictionary` (VirtualCia402Slave's second form). When its
  /// outputs carry the command tick (0x2002, the lockstep contract of a CANopen device's
  /// dictionary), a cycle steps a period only when the command tick equals the periods stepped
  /// (0x2001): a frame the master sends again after a lost reply is not a second period.
  VirtualEthercatDrive(const canopen::Cia402ApplicationParams& params, drive::Drive& drive,
                       canopen::ObjectDictionary dictionary, Log log = {}, std::vector<std::uint16_t> sii = {});

  Esc& esc() { return slave_.esc(); }
  canopen::ObjectDictionary& dictionary() { return slave_.dictionary(); }
  const VirtualCia402Slave& slave() const { return slave_; }
  /// The slave, to post a message of the application's own (a warning's emergency).
  VirtualCia402Slave& slave() { return slave_; }

  /// Between frames (VirtualSegment::serve's between_frames): the watchdog, then the cycles the
  /// master completed since, as above. Never throws.
  void after_frame(std::int64_t now_ns);
  /// The process-data watchdog at `now_ns`, also when no frame comes (the owner calls it between
  /// its waits). Never throws.
  void check_watchdog(std::int64_t now_ns);

  std::uint64_t periods() const { return application_.periods(); }
  double applied_force_n() const { return application_.applied_force_n(); }
  /// Process-data cycles whose outputs came while not in OP (not applied).
  std::uint64_t cycles_outside_op() const { return cycles_outside_op_; }
  /// Lockstep: cycles in OP whose command tick was not the next period (a repeated frame).
  std::uint64_t unstepped_cycles() const { return unstepped_cycles_; }
  /// DC SYNC0 mode: pulses in OP that found no new outputs since the one before (0x1C32:0B).
  std::uint64_t sync0_without_outputs() const { return sm_missed_; }
  std::uint64_t emergencies() const { return emergencies_; }
  std::uint16_t last_emergency() const { return last_emergency_; }

 private:
  /// A SYNC0 pulse: a period in OP when the master chose DC SYNC0 mode.
  void on_sync0(std::int64_t now_ns);
  void log(bool error, const std::string& line, std::int64_t now_ns) override {
    if (log_) log_(error, line, now_ns);
  }
  void emergency(std::uint16_t code) override {
    ++emergencies_;
    last_emergency_ = code;
    slave_.post_emergency(code);
  }

  VirtualCia402Slave slave_;  // declared first: the application holds its dictionary
  canopen::Cia402Application application_;
  Log log_;
  std::uint64_t outputs_seen_ = 0;
  std::uint64_t sm_missed_ = 0;         ///< SYNC0 pulses in OP without new outputs (0x1C32:0B)
  std::uint64_t outputs_at_pulse_ = 0;  ///< the ESC's outputs completed at the last pulse
  std::int64_t outputs_ns_ = 0;         ///< when the last outputs came, or OP was entered if later
  bool in_op_ = false;
  std::uint64_t cycles_outside_op_ = 0;
  std::uint64_t unstepped_cycles_ = 0;
  std::uint64_t emergencies_ = 0;
  std::uint16_t last_emergency_ = 0;
};

}  // namespace pmlsm::ethercat
