// An EtherCAT master in user space, over any Link: one datagram there and back at a time, its
// working counter checked; on top of that the bus scan (how many slaves answer, station addresses
// by position), the SII read through each slave's EEPROM interface (its identity and mailbox
// layout), sync manager set-up and the AL state walk, each refusal read and named.
//
// exchange() never throws (a cycle may call it); the set-up steps throw std::runtime_error naming
// the slave, the register and what came back, since nothing can go on after them.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/frame.hpp"
#include "pmlsm/ethercat/link.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/ethercat/pcapng.hpp"
#include "pmlsm/ethercat/sii.hpp"

namespace pmlsm::ethercat {

/// The longest value sdo_upload() takes (ETG.1000.6 allows 2^32 - 1; drives' texts are short).
inline constexpr std::uint32_t kMaxUploadBytes = 65536;

struct MasterParams {
  std::int64_t reply_timeout_ns = 20'000'000;  ///< how long a datagram may take there and back
  int retries = 2;                             ///< sent again this many times when no reply came
  std::uint16_t first_station_address = 0x1001;
  std::int64_t state_timeout_ns = 2'000'000'000;  ///< how long a slave may take to reach an AL state
  /// @throws std::invalid_argument naming the value.
  void validate() const;
};

struct Reply {
  bool answered = false;
  std::uint16_t working_counter = 0;
};

/// A slave as its SII describes it: identity, mailbox layout, name, sync managers.
struct SlaveInfo : SiiInfo {
  std::uint16_t station_address = 0;
};

/// An SDO transfer's outcome: done (the value read, its size), or aborted by the slave.
struct SdoResult {
  bool done = false;
  std::uint32_t value = 0;  ///< upload: the value (its first 4 little-endian bytes as a number)
  std::uint8_t size = 0;    ///< upload, expedited: 1..4 bytes (0: not indicated or not expedited)
  std::uint32_t abort_code = 0;
  std::vector<std::uint8_t> bytes;  ///< upload: every byte read (4 when the size was not indicated)
  bool expedited = true;            ///< upload: in the initiate response (else normal or segmented)
  /// "0x00020192", "\"AKD EtherCAT Drive (CoE)\" (24 bytes)" for a text, "01 02 ... (300 bytes)"
  /// for other long data, or "aborted: 0x06020000 object does not exist ..."
  std::string describe() const;
};

/// A slave's process data as mapped: its bytes, where they sit in the slave and in the logical
/// image.
struct ProcessDataLayout {
  std::uint16_t output_bytes = 0;  ///< SM2: the master writes
  std::uint16_t input_bytes = 0;   ///< SM3: the master reads
  std::uint32_t outputs_logical = 0;
  std::uint32_t inputs_logical = 0;  ///< outputs_logical + output_bytes
  /// The objects in the outputs and in the inputs, in the order they are packed (each assigned
  /// PDO's entries after the one before's).
  std::vector<canopen::PdoMapEntry> outputs;
  std::vector<canopen::PdoMapEntry> inputs;
  /// Where object `index` (sub-index `subindex`) sits in the outputs (or inputs): its first byte
  /// from the start of them, or -1 when it is not mapped.
  int output_offset(std::uint16_t index, std::uint8_t subindex = 0) const {
    return offset_in(outputs, index, subindex);
  }
  int input_offset(std::uint16_t index, std::uint8_t subindex = 0) const { return offset_in(inputs, index, subindex); }

 private:
  static int offset_in(const std::vector<canopen::PdoMapEntry>& entries, std::uint16_t index, std::uint8_t subindex);
};

/// A slave's distributed clock as configure_distributed_clocks() found it.
struct DcSlave {
  std::uint16_t station = 0;
  std::uint32_t behind_ns = 0;         ///< port 1's receive time less port 0's: the line behind it
  std::uint64_t latched_local_ns = 0;  ///< its local time at the latch (0x0918)
  std::uint32_t delay_ns = 0;          ///< the frame's way from the reference to it (0x0928)
};

struct StateResult {
  bool reached = false;
  AlState state = AlState::kInit;  ///< the state the slave is in
  std::uint16_t code = 0;          ///< the AL status code when it refused
  std::string describe() const;    ///< "PREOP" or "INIT, refused: 0x0016 invalid mailbox configuration"
};

class Master {
 public:
  /// `link` outlives the master. @throws std::invalid_argument from the params.
  explicit Master(Link& link, MasterParams params = {});

  /// Every frame sent and received from now on also into `capture` (nullptr: none). A write that
  /// fails ends the capture (capture_failed()); the exchanges go on.
  void capture_to(PcapngWriter* capture) { capture_ = capture; }
  bool capture_failed() const { return capture_failed_; }

  /// One datagram there and back: `data` (length bytes) goes out and is replaced by what came
  /// back. Not answered after the retries: answered false, `data` as it was. Never throws.
  Reply exchange(Command command, std::uint32_t address, std::uint8_t* data, std::uint16_t length);
  /// The same with this exchange's own reply time-out and retries (a cycle's deadline).
  Reply exchange(Command command, std::uint32_t address, std::uint8_t* data, std::uint16_t length,
                 std::int64_t reply_timeout_ns, int retries);

  /// The slaves on the bus: the working counter of a broadcast read.
  std::uint16_t count_slaves();
  /// Station addresses first_station_address + position for `slaves` slaves, by position.
  /// @throws std::runtime_error naming the position that did not take it.
  std::vector<std::uint16_t> assign_station_addresses(std::uint16_t slaves);
  /// `words` words of a slave's SII from `word_address`, 4 words a read.
  /// @throws std::runtime_error naming the slave when it does not answer or stays busy.
  std::vector<std::uint16_t> read_sii(std::uint16_t station, std::uint16_t word_address, std::uint16_t words);
  /// Its SII read whole (the fixed part, then category by category to the end) and parsed.
  /// @throws std::runtime_error as read_sii, or naming what is wrong with the image.
  SlaveInfo read_slave_info(std::uint16_t station);
  /// Sync manager `index` of a slave: start, length, control byte, enabled.
  /// @throws std::runtime_error when the slave does not take it.
  void configure_sync_manager(std::uint16_t station, std::uint8_t index, std::uint16_t start, std::uint16_t length,
                              std::uint8_t control);
  /// SM0 and SM1 as the slave's mailbox: where and how its SII's sync manager category says
  /// (types 1 and 2), else at its fixed part's offsets and sizes with the usual control bytes
  /// (kSmControlMailboxWrite, kSmControlMailboxRead). PREOP needs them.
  /// @throws std::runtime_error when the slave has no mailbox or does not take them.
  void configure_mailbox(const SlaveInfo& slave);
  /// FMMU `index` of a slave: `length` bytes at `logical` onto its memory at `physical`, read
  /// (the slave's inputs into the frame) or write (the frame's outputs into the slave).
  /// @throws std::runtime_error when the slave does not take it.
  void configure_fmmu(std::uint16_t station, std::uint8_t index, std::uint32_t logical, std::uint16_t length,
                      std::uint16_t physical, bool write);
  /// A slave's process-data watchdog (the ESC's SM watchdog the ESI asks for): `timeout_ns` in
  /// units of its divider (read from 0x0400), rounded up, into 0x0420; 0 turns it off.
  /// @throws std::invalid_argument when the time needs more than 65535 units or is negative,
  /// std::runtime_error when the slave does not take it.
  void configure_process_data_watchdog(std::uint16_t station, std::int64_t timeout_ns);
  /// Asks a slave for `state` and reads its AL status until it is there, refuses (the error
  /// indicator: its code read, then acknowledged) or state_timeout_ns passes.
  /// @throws std::runtime_error when the slave does not answer at all.
  StateResult request_state(std::uint16_t station, AlState state);
  /// A slave's AL state and status code. @throws std::runtime_error when it does not answer.
  StateResult read_state(std::uint16_t station);

  /// An object of a slave's dictionary read over CoE (SDO through its mailboxes, whose layout
  /// `slave` holds; the slave in PREOP or above): expedited, or normal and segmented (mailbox.hpp)
  /// for a value over 4 bytes, up to kMaxUploadBytes.
  /// @throws std::runtime_error naming the slave when the mailbox does not answer, or the object
  /// when its segments do not follow the protocol or it is longer (the transfer aborted first).
  /// `complete_access`: the whole record from `subindex` (0 or 1) on, as the slave lays it out
  /// (sub-index 0 padded to 16 bits), for a slave whose SII offers it (CoE details bit 5).
  SdoResult sdo_upload(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex,
                       bool complete_access = false);
  /// An object written over CoE: `size` bytes (1..4) of `value`.
  /// @throws std::runtime_error as sdo_upload, std::invalid_argument for a size outside 1..4.
  SdoResult sdo_download(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex, std::uint32_t value,
                         std::uint8_t size);

  /// A record written whole by CoE's complete access from sub-index 0 (`record`: sub-index 0 as
  /// 16 bits, then each entry in its size): a normal download with as much as the receive mailbox
  /// holds, the rest in download segments.
  /// @throws std::runtime_error as sdo_upload (and for an answer that is not the segment's).
  SdoResult sdo_download_record(const SlaveInfo& slave, std::uint16_t index, const std::vector<std::uint8_t>& record);

  /// A sync manager's PDO assignment written over CoE (the slave in PREOP, ETG.1000.6's order): the
  /// assignment `assign_index` (0x1C12 outputs, 0x1C13 inputs) emptied, `entries` mapped in order
  /// into the PDOs from `first_pdo` on (0x1600, 0x1A00), a PDO at most 8 entries and 64 bits (what
  /// every CoE slave takes, CANopen's PDO included), each assigned after the one before. A slave
  /// whose SII offers complete access gets each record whole (three SDOs for one PDO).
  /// @throws std::runtime_error naming the object and the abort code when the slave refuses,
  /// std::invalid_argument when the entries need more than 4 PDOs or one is wider than 32 bits.
  void write_pdo_assignment(const SlaveInfo& slave, std::uint16_t assign_index, std::uint16_t first_pdo,
                            const std::vector<canopen::PdoMapEntry>& entries);
  /// The slave's process data mapped as its CoE objects say (0x1C12 / 0x1C13: the assigned PDOs,
  /// their mapping objects' entries), SM2 and SM3 set at the SII's addresses with those lengths,
  /// and FMMU 0 (outputs) and 1 (inputs) onto the logical image from `logical` on. The slave in
  /// PREOP. @throws std::runtime_error naming the object when an SDO is refused or the SII has no
  /// sync manager for the process data.
  ProcessDataLayout map_process_data(const SlaveInfo& slave, std::uint32_t logical);

  /// Distributed clocks along a line of slaves (`stations` in the line's order), the first with a
  /// 64-bit clock (0x0008) the reference, following the master's time (as IgH's master runs them;
  /// SOEM follows the reference instead): the receive times latched (BWR 0x0900); for each slave
  /// with a clock, ports 0 and 1's times (0x0900, 0x0904: how long the frame was behind it) and its
  /// local time at that frame (0x0918); each one's propagation delay from the reference, the one
  /// before's plus half the difference of what each saw behind it (0x0928); and its offset (0x0920)
  /// so that its system time is `master_time_ns` (the master's clock as the latch frame went) plus
  /// its delay. Slaves without a clock are cable between the others. Returns the slaves with a
  /// clock, in order. @throws std::runtime_error when a single slave asked for has no clock, or a
  /// slave does not take it.
  std::vector<DcSlave> configure_distributed_clocks(const std::vector<std::uint16_t>& stations,
                                                    std::uint64_t master_time_ns);
  /// The same for one slave, the reference (delay 0).
  void configure_distributed_clock(std::uint16_t station, std::uint64_t master_time_ns);
  /// SYNC0 of a slave's distributed clock (after configure_distributed_clock), as SOEM's
  /// ec_dcsync0 sets it: the unit off (0x0981 = 0), the cycle (0x09A0), the first pulse at the first
  /// whole cycle of system time at least `lead_ns` ahead of the slave's time now plus `shift_ns`
  /// (0x0990), the unit on with SYNC0 (0x0981 = 0x03). Returns that start time.
  /// @throws std::invalid_argument for a cycle outside 1 ns..2^32-1 ns, a shift outside
  /// [0, cycle) or a negative lead; std::runtime_error when the slave does not take it.
  std::uint64_t configure_sync0(std::uint16_t station, std::int64_t cycle_ns, std::int64_t shift_ns,
                                std::int64_t lead_ns = 100'000'000);
  /// One drift-compensation write: `master_time_ns` into the slave's 0x0910 (FPWR), within the
  /// given reply time-out and retries. Never throws.
  Reply write_system_time(std::uint16_t station, std::uint64_t master_time_ns, std::int64_t reply_timeout_ns,
                          int retries);
  /// The slave's 0x092C: the filtered difference between the times written and its own [ns],
  /// positive when its clock is behind. @throws std::runtime_error when it does not answer.
  std::int64_t read_system_time_difference(std::uint16_t station);

  /// A look into a slave's send mailbox between SDO transfers, as a cycle can afford it: SM1's
  /// status read (one FPRD), and only when the mailbox is full, the mailbox read. A CoE emergency is
  /// counted with its code (true); anything else there, an answer nobody waits for, is taken and
  /// counted (mailbox_unexpected()). Within the given reply time-out and retries. Never throws.
  bool poll_emergency(const SlaveInfo& slave, std::int64_t reply_timeout_ns, int retries);
  std::uint64_t mailbox_unexpected() const { return mailbox_unexpected_; }

  /// CoE emergencies the slaves posted, met in their send mailboxes on the way to an SDO answer or
  /// by poll_emergency(), and the last one's error code (0: the errors gone).
  std::uint64_t emergencies() const { return emergencies_; }
  std::uint16_t last_emergency_code() const { return last_emergency_code_; }

  std::uint64_t frames_sent() const { return frames_sent_; }
  std::uint64_t frames_lost() const { return frames_lost_; }

 private:
  /// An FPRD/FPWR of a register that must come back with working counter 1.
  void write_register(std::uint16_t station, std::uint16_t address, const std::uint8_t* data, std::uint16_t length,
                      const char* what);
  void read_register(std::uint16_t station, std::uint16_t address, std::uint8_t* data, std::uint16_t length,
                     const char* what);
  void record(Bytes frame);
  /// The entries of the PDOs assigned in `assign_index` (0x1C12, 0x1C13), in order.
  std::vector<canopen::PdoMapEntry> assigned_entries(const SlaveInfo& slave, std::uint16_t assign_index);
  /// A CoE SDO response: its 8 bytes and what the message carries after them.
  struct CoeAnswer {
    SdoBytes sdo{};
    std::vector<std::uint8_t> more;
  };
  /// One SDO request through the mailboxes and its response (emergencies before it counted).
  CoeAnswer coe_request(const SlaveInfo& slave, const SdoBytes& request, const std::uint8_t* more = nullptr,
                        std::size_t more_bytes = 0);
  /// One expedited SDO request and its response read.
  SdoResult sdo_transfer(const SlaveInfo& slave, const SdoBytes& request);
  /// An expedited response (or an abort) read. @throws std::runtime_error when not understood.
  SdoResult expedited_answer(const SlaveInfo& slave, const CoeAnswer& answer);
  /// The rest of a normal upload whose first response is `first`: its segments.
  SdoResult normal_upload(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex, const CoeAnswer& first);
  /// write_pdo_assignment by complete access, the PDOs laid out: false at the first refusal.
  bool write_pdo_assignment_whole(const SlaveInfo& slave, std::uint16_t assign_index, std::uint16_t first_pdo,
                                  const std::vector<std::vector<canopen::PdoMapEntry>>& pdos);
  /// write_pdo_assignment an SDO an entry (CiA 301's procedure), the PDOs already laid out.
  void write_pdo_assignment_by_entry(const SlaveInfo& slave, std::uint16_t assign_index, std::uint16_t first_pdo,
                                     const std::vector<std::vector<canopen::PdoMapEntry>>& pdos);
  /// The master's abort of a transfer (no answer comes).
  void abort_transfer(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex, std::uint32_t code);

  Link& link_;
  MasterParams params_;
  FrameBuilder frame_;
  std::array<std::uint8_t, kMaxEthernetFrameBytes> received_{};
  std::uint8_t next_index_ = 0;
  std::uint8_t mailbox_counter_ = 0;
  PcapngWriter* capture_ = nullptr;
  bool capture_failed_ = false;
  std::uint64_t frames_sent_ = 0;
  std::uint64_t frames_lost_ = 0;
  std::uint64_t emergencies_ = 0;
  std::uint16_t last_emergency_code_ = 0;
  std::uint64_t mailbox_unexpected_ = 0;
};

}  // namespace pmlsm::ethercat
