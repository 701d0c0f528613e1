// A virtual EtherCAT slave controller (ESC): the memory a slave's ESC holds, registers at
// 0x0000-0x0FFF and process-data RAM from 0x1000 (the register map of ETG.1000.4 and of the
// ET1100 and LAN9252 chips), and what it does to each datagram that passes it on the ring. A real
// ESC works in hardware as the frame goes through; this one does the same to a frame in memory:
//
//   - it answers a datagram addressed to it: by position (auto increment: the ADP it sees is 0;
//     it counts the ADP up either way), by its station address (0x0010), by broadcast, or through
//     its FMMUs for a logical address;
//   - a read copies its memory into the datagram's data (a broadcast read ORs it in), a write
//     copies the data into its writable registers and RAM, and each adds to the working counter
//     (1 read, 1 write, 3 read-write);
//   - writing AL control (0x0120) asks for an AL state: the state machine below answers in AL
//     status (0x0130) and, refused, with the error indicator and an AL status code (0x0134);
//   - the SII EEPROM interface (0x0502-0x050F) reads its SII image 8 bytes at a time;
//   - a message written to the end of its receive mailbox (SM0) goes to its mailbox handler, and
//     the answer waits in its send mailbox (SM1, status "full") until the master has read it to its
//     last byte; reading an empty send mailbox is not done (working counter unchanged).
//
// The AL state machine (ETG.1000.6): INIT -> PREOP needs the mailbox sync managers (SM0, SM1) set
// as the SII declares them; PREOP -> SAFEOP needs the process-data sync managers (SM2 outputs, SM3
// inputs) active with the lengths the slave's mapping has; SAFEOP -> OP; any state -> INIT;
// OP -> SAFEOP and SAFEOP or OP -> PREOP back down. Anything else is refused with code 0x0011;
// BOOT is not supported (0x0013). A refusal sets the error indicator, which stays until the
// master acknowledges it (AL control's bit 4). SAFEOP -> OP asks the application first (a drive
// synchronous to SYNC0 refuses with 0x0030 while SYNC0 is off).
//
// SYNC0 (the DC cyclic unit, ETG.1000.4 and the ET1100's 0x0980-0x09A3): the master writes the
// cycle (0x09A0, ns), the first pulse's system time (0x0990) and then activates the unit with SYNC0
// (0x0981 bits 0 and 1). From then on a pulse falls at the start time and every cycle after it, on
// the slave's system time; 0x0990 reads the next one, 0x098E bit 0 says one fell since it was last
// read. Like an ET1100, which compares the low 32 bits, a start time already past when the unit is
// activated fires only when those bits come round again (up to 4.3 s later: counted, a master's
// error). Each pulse is the application's SYNC0 interrupt (set_sync0_handler), as the clock passes
// it: before a frame that comes after it passes the slave. The ESC counts the pulses without new
// outputs since the one before (the SM event missed a drive counts). A clock moved more than 1000
// cycles past the next pulse at once hands the application the last 1000 and counts the rest as
// dropped.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "pmlsm/ethercat/dc_clock.hpp"
#include "pmlsm/ethercat/frame.hpp"
#include "pmlsm/ethercat/link.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/ethercat/sii.hpp"

namespace pmlsm::ethercat {

/// Register addresses of an ESC.
namespace reg {
inline constexpr std::uint16_t kType = 0x0000;
inline constexpr std::uint16_t kRevision = 0x0001;
inline constexpr std::uint16_t kBuild = 0x0002;
inline constexpr std::uint16_t kFmmuCount = 0x0004;
inline constexpr std::uint16_t kSyncManagerCount = 0x0005;
inline constexpr std::uint16_t kRamSizeKib = 0x0006;
inline constexpr std::uint16_t kFeatures = 0x0008;  ///< u16: bit 2 distributed clocks, bit 3 64-bit DC
inline constexpr std::uint16_t kStationAddress = 0x0010;
inline constexpr std::uint16_t kStationAlias = 0x0012;
inline constexpr std::uint16_t kDlStatus = 0x0110;
inline constexpr std::uint16_t kAlControl = 0x0120;
inline constexpr std::uint16_t kAlStatus = 0x0130;
inline constexpr std::uint16_t kAlStatusCode = 0x0134;
inline constexpr std::uint16_t kWatchdogDivider = 0x0400;            ///< u16: (value + 2) x 40 ns a unit
inline constexpr std::uint16_t kWatchdogTimeProcessData = 0x0420;    ///< u16 units; 0: off
inline constexpr std::uint16_t kWatchdogStatusProcessData = 0x0440;  ///< bit 0: 1 running or off, 0 expired
inline constexpr std::uint16_t kSiiControl = 0x0502;
inline constexpr std::uint16_t kSiiAddress = 0x0504;
inline constexpr std::uint16_t kSiiData = 0x0508;
inline constexpr std::uint16_t kFmmu0 = 0x0600;
inline constexpr std::uint16_t kSyncManager0 = 0x0800;
inline constexpr std::uint16_t kDcReceiveTimePort0 = 0x0900;      ///< u32; a write latches every port's
inline constexpr std::uint16_t kDcSystemTime = 0x0910;            ///< u64: read the time, write to follow
inline constexpr std::uint16_t kDcReceiveTimeUnit = 0x0918;       ///< u64: the latch in local time
inline constexpr std::uint16_t kDcSystemTimeOffset = 0x0920;      ///< u64
inline constexpr std::uint16_t kDcSystemTimeDelay = 0x0928;       ///< u32
inline constexpr std::uint16_t kDcSystemTimeDifference = 0x092C;  ///< u32: bit 31 own time behind, 30-0 ns
inline constexpr std::uint16_t kDcActivation = 0x0981;            ///< u8: bit 0 cyclic unit, bit 1 SYNC0
inline constexpr std::uint16_t kDcSync0Status = 0x098E;           ///< u8: bit 0 a pulse since the last read
inline constexpr std::uint16_t kDcStartTime = 0x0990;             ///< u64: write the first pulse; read the next
inline constexpr std::uint16_t kDcSync0CycleTime = 0x09A0;        ///< u32 ns (0: a single pulse)
inline constexpr std::uint16_t kProcessRam = 0x1000;
}  // namespace reg

inline constexpr std::size_t kFmmuBytes = 16;
inline constexpr std::size_t kSyncManagerBytes = 8;
/// A sync manager's control byte as masters set it for each use (mode, direction, interrupt,
/// watchdog): SM0 the mailbox the master writes, SM1 the one it reads, SM2 outputs, SM3 inputs.
inline constexpr std::uint8_t kSmControlMailboxWrite = 0x26;
inline constexpr std::uint8_t kSmControlMailboxRead = 0x22;
inline constexpr std::uint8_t kSmControlOutputs = 0x64;
inline constexpr std::uint8_t kSmControlInputs = 0x20;
inline constexpr std::uint8_t kAlErrorIndicator = 0x10;  ///< in AL status; in AL control: acknowledge
/// SII EEPROM interface: control/status bits at 0x0502.
inline constexpr std::uint16_t kSiiReadCommand = 0x0100;
inline constexpr std::uint16_t kSiiCommandMask = 0x0700;
inline constexpr std::uint16_t kSiiRead8Bytes = 0x0040;  ///< status: a read fetches 8 bytes
inline constexpr std::uint16_t kSiiBusy = 0x8000;

enum class AlState : std::uint8_t { kInit = 1, kPreOp = 2, kBoot = 3, kSafeOp = 4, kOp = 8 };
/// "INIT", "PREOP", "BOOT", "SAFEOP", "OP"; "?" for another value.
const char* to_string(AlState state);
/// The AL status code's name (ETG.1000.6, ETG.1020): "invalid mailbox configuration" for 0x0016;
/// "unknown AL status code" for one not in the table.
const char* al_status_code_name(std::uint16_t code);

/// AL status codes the virtual ESC answers with.
namespace al_code {
inline constexpr std::uint16_t kNoError = 0x0000;
inline constexpr std::uint16_t kInvalidStateChange = 0x0011;
inline constexpr std::uint16_t kUnknownState = 0x0012;
inline constexpr std::uint16_t kBootstrapNotSupported = 0x0013;
inline constexpr std::uint16_t kInvalidMailboxConfiguration = 0x0016;
inline constexpr std::uint16_t kSyncManagerWatchdog = 0x001B;
inline constexpr std::uint16_t kInvalidOutputConfiguration = 0x001D;
inline constexpr std::uint16_t kInvalidInputConfiguration = 0x001E;
inline constexpr std::uint16_t kInvalidDcSyncConfiguration = 0x0030;
inline constexpr std::uint16_t kInvalidSyncCycleTime = 0x0035;
}  // namespace al_code

/// The SYNC0 unit's state, as the ESC's DC registers hold it.
struct Sync0State {
  bool active = false;                       ///< 0x0981 bits 0 and 1
  std::uint32_t cycle_ns = 0;                ///< 0x09A0
  std::uint64_t next_ns = 0;                 ///< the next pulse's system time (0x0990 read)
  std::uint64_t pulses = 0;                  ///< since the ESC began
  std::uint64_t pulses_without_outputs = 0;  ///< pulses with no outputs completed since the one before
  std::uint64_t late_starts = 0;             ///< activations with the start time already past (the 32-bit wait)
  std::uint64_t dropped = 0;                 ///< pulses passed over when the clock jumped 1000 cycles or more ahead
};

struct EscParams {
  std::uint8_t type = 0x11;  ///< register 0x0000 (ET1100's)
  std::uint8_t fmmus = 8;
  std::uint8_t sync_managers = 8;
  std::vector<std::uint16_t> sii;  ///< the SII EEPROM image in words (at least sii::kMinWords)
  /// The process data the slave's mapping has (0: none): SM2's and SM3's lengths for SAFEOP.
  std::uint16_t output_bytes = 0;
  std::uint16_t input_bytes = 0;
  /// Its distributed clock (64 bits; the local crystal's drift).
  DcClockParams dc;
  /// @throws std::invalid_argument naming what is wrong.
  void validate() const;
};

class Esc {
 public:
  static constexpr std::size_t kMemoryBytes = 0x10000;

  /// @throws std::invalid_argument from the params.
  explicit Esc(EscParams params);

  /// A datagram passes this slave: done if it is addressed, the working counter and (auto
  /// increment) the ADP in `header` counted on. `data` holds header.length bytes.
  void pass(DatagramHeader& header, std::uint8_t* data, std::uint16_t& working_counter);

  /// The wall time is `now_ns` (the owner's clock, set before a frame passes): its distributed
  /// clock runs on to it, and 0x0910 and 0x092C read its system time and difference then.
  void set_time(std::int64_t now_ns);
  /// How long the frame passing now takes to come back to port 1 from the slaves behind this one
  /// [ns]; -1: port 1 closed (the last slave of the line). A receive-time latch (0x0900) then holds
  /// port 1's time too (0x0904), from which a master measures the line's propagation delays.
  void set_port1_return_ns(std::int64_t ns) { port1_return_ns_ = ns; }
  const DcClock& dc() const { return dc_; }
  DcClock& dc() { return dc_; }

  AlState al_state() const;
  std::uint16_t al_status_code() const;
  std::uint16_t station_address() const;
  /// A byte, word or long of its memory, little-endian (the application's view, as its PDI).
  std::uint8_t byte_at(std::uint16_t address) const { return memory_[address]; }
  std::uint16_t word_at(std::uint16_t address) const;
  std::uint32_t long_at(std::uint16_t address) const;
  /// The application writes process RAM (inputs) or a register it owns.
  void write_memory(std::uint16_t address, const std::uint8_t* bytes, std::size_t size);
  /// The process-data watchdog's time (0x0420 units of the divider 0x0400; ETG.1000.4 and the
  /// ET1100's defaults: 2498 and 1000, 100 ms) in ns; 0: off.
  std::int64_t process_data_watchdog_ns() const;
  /// The application found the process data late by the watchdog: 0x0440 says expired, and it
  /// drops from OP to SAFEOP with the error indicator and code 0x001B until the master
  /// acknowledges. The next outputs completed set 0x0440 running again.
  void process_data_watchdog_expired();
  /// How many times the master completed SM2's buffer (wrote its last byte) while SM2 is enabled
  /// as a buffer: the outputs of a process-data cycle, what an application synchronous to SM2
  /// (the ESC's SM2 event, a drive run without distributed clocks) runs a cycle on.
  std::uint64_t outputs_written() const { return outputs_written_; }
  /// What answers the messages the master writes into its receive mailbox (SM0), into its send
  /// mailbox (SM1); nullptr: none (a message is taken and nothing answered). `handler` outlives
  /// the ESC.
  void set_mailbox_handler(MailboxHandler* handler) { mailbox_handler_ = handler; }
  /// A message of the slave's own (a CoE emergency) into its send mailbox: at once when the master
  /// has read the one before, else queued behind it (up to kSendQueue; beyond, dropped and
  /// counted). False when it has no send mailbox set up or the message was dropped.
  bool post_mailbox(const std::uint8_t* message, std::size_t size);
  static constexpr std::size_t kSendQueue = 4;
  std::uint64_t mailbox_messages_dropped() const { return mailbox_dropped_; }
  /// What the application does when the master asks PREOP -> SAFEOP, before the ESC checks SM2 and
  /// SM3 against the process data's lengths: it may take a new mapping (set_process_data_bytes)
  /// or refuse with an AL status code (0: go on). Empty: nothing.
  void set_before_safeop(std::function<std::uint16_t()> before) { before_safeop_ = std::move(before); }
  /// What the application does when the master asks SAFEOP -> OP: an AL status code to refuse
  /// with, or 0. Empty: nothing.
  void set_before_op(std::function<std::uint16_t()> before) { before_op_ = std::move(before); }
  /// The SYNC0 unit (see the file comment).
  const Sync0State& sync0() const { return sync0_; }
  /// What the application does at each SYNC0 pulse (its interrupt), given the owner's wall time
  /// of set_time(). Empty: nothing.
  void set_sync0_handler(std::function<void(std::int64_t now_ns)> handler) { sync0_handler_ = std::move(handler); }
  /// The time to the next SYNC0 pulse on the slave's clock [ns] (0 when due); -1 when SYNC0 is off.
  std::int64_t ns_to_next_sync0() const;
  /// The process data's lengths SAFEOP checks SM2 and SM3 against (the application's mapping).
  void set_process_data_bytes(std::uint16_t output_bytes, std::uint16_t input_bytes) {
    params_.output_bytes = output_bytes;
    params_.input_bytes = input_bytes;
  }

 private:
  bool addressed(const DatagramHeader& header) const;
  void physical(const DatagramHeader& header, std::uint8_t* data, std::uint16_t& working_counter);
  void logical(const DatagramHeader& header, std::uint8_t* data, std::uint16_t& working_counter);
  void read_into(std::uint16_t address, std::uint8_t* out, std::size_t size, bool or_in) const;
  void write_from(std::uint16_t address, const std::uint8_t* in, std::size_t size);
  void after_write(std::uint16_t address, std::size_t size);
  void request_state(std::uint8_t control);
  void refuse(std::uint16_t code);
  void sii_command();
  /// Whether SM `index` is active with `start`, `length` and the control byte `control`.
  bool sync_manager_is(std::size_t index, std::uint16_t start, std::uint16_t length, std::uint8_t control) const;
  bool sync_manager_active_with(std::size_t index, std::uint16_t length) const;

  /// Sync manager `index` as a mailbox: its area, whether it is one and enabled.
  struct MailboxArea {
    bool active = false;
    std::uint16_t start = 0;
    std::uint16_t length = 0;
  };
  MailboxArea mailbox_area(std::size_t index) const;
  /// A read of `length` bytes at `address` that the send mailbox holds back (empty): not done.
  bool send_mailbox_empty_for(std::uint16_t address, std::uint16_t length) const;
  /// After a read: the send mailbox read to its last byte is empty again.
  void after_read(std::uint16_t address, std::uint16_t length);
  void mailbox_received();
  void set_sync_manager_full(std::size_t index, bool full);
  /// The DC registers the master wrote: a latch of the receive times, a system time to follow, the
  /// offset, the delay.
  void dc_written(std::uint16_t address, std::size_t size);
  /// 0x0910 and 0x092C from the clock.
  void show_dc();
  /// The SYNC0 registers written: the unit on or off.
  void sync0_written();
  /// The pulses up to the clock's system time now: counted, each to the handler, 0x0990 and 0x098E
  /// shown.
  void run_sync0(std::int64_t now_ns);

  EscParams params_;
  std::vector<std::uint8_t> memory_;
  MailboxHandler* mailbox_handler_ = nullptr;
  std::function<std::uint16_t()> before_safeop_;
  std::function<std::uint16_t()> before_op_;
  Sync0State sync0_;
  std::uint64_t outputs_at_last_pulse_ = 0;
  std::function<void(std::int64_t)> sync0_handler_;
  std::int64_t now_ns_ = 0;  ///< the owner's time at the last set_time()
  std::int64_t port1_return_ns_ = -1;
  std::uint64_t outputs_written_ = 0;
  DcClock dc_;
  /// Messages waiting for the send mailbox to be read (a ring).
  std::array<std::array<std::uint8_t, kMaxDatagramDataBytes>, kSendQueue> send_queue_{};
  std::array<std::size_t, kSendQueue> send_sizes_{};
  std::size_t send_head_ = 0;
  std::size_t send_count_ = 0;
  std::uint64_t mailbox_dropped_ = 0;
  /// A message into the send mailbox now, marked full.
  void put_into_send_mailbox(const std::uint8_t* message, std::size_t size);
};

/// A line of virtual slaves in one process: a frame passes each in order and comes back, as on a
/// ring of real ones.
class VirtualSegment {
 public:
  /// `slaves` outlive the segment, in the line's order. `clock` (monotonic ns; may be empty): the
  /// time each slave is set to before a frame passes it (Esc::set_time: their distributed clocks
  /// run on it), `hop_ns` later for each slave further down the line (the cable and the slave
  /// before: a frame reaches slave i i hops after the first, and comes back through its port 1
  /// 2 (n - 1 - i) hops after it passed).
  explicit VirtualSegment(std::vector<Esc*> slaves, std::function<std::int64_t()> clock = {}, std::int64_t hop_ns = 0)
      : slaves_(std::move(slaves)), clock_(std::move(clock)), hop_ns_(hop_ns) {}
  /// The frame in `bytes` (an Ethernet frame of `size` bytes) through every slave, in place.
  /// Returns what the parser said of it; a refused frame is left as it was (a real slave drops it).
  FrameError pass(std::uint8_t* bytes, std::size_t size);
  /// The same at `at_ns` instead of the clock's now (the time the frame came: a frame read late
  /// passes among the slaves' own events in the order it came).
  FrameError pass(std::uint8_t* bytes, std::size_t size, std::int64_t at_ns);
  /// Frames received from `link`, passed and sent back, until none comes within `timeout_ns`;
  /// `between_frames` (may be empty) after each: the slaves' applications (their process data).
  /// @return the frames answered.
  std::size_t serve(Link& link, std::int64_t timeout_ns, const std::function<void()>& between_frames = {});

 private:
  std::vector<Esc*> slaves_;
  std::function<std::int64_t()> clock_;
  std::int64_t hop_ns_;
  std::array<std::uint8_t, kMaxEthernetFrameBytes> buffer_{};
};

/// A link to a virtual segment in the same thread: a frame sent passes the slaves at once and is
/// what the next receive() returns; `after_frame` (may be empty) runs after each frame passed, as
/// VirtualSegment::serve's between_frames (the slaves' applications). Deterministic, for tests and
/// in-process rigs.
class VirtualSegmentLink final : public Link {
 public:
  explicit VirtualSegmentLink(VirtualSegment& segment, std::function<void()> after_frame = {})
      : segment_(segment), after_frame_(std::move(after_frame)) {}
  bool send(Bytes ethernet_frame) override;
  std::size_t receive(std::uint8_t* buffer, std::int64_t timeout_ns) override;

 private:
  VirtualSegment& segment_;
  std::function<void()> after_frame_;
  std::array<std::uint8_t, kMaxEthernetFrameBytes> buffer_{};
  std::size_t size_ = 0;
  bool pending_ = false;
};

}  // namespace pmlsm::ethercat
