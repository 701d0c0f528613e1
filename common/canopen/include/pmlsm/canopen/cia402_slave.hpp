// The drive's end of the bus: a CiA 402 slave over a drive backend (pmlsm/drive/drive.hpp), the
// counterpart of Cia402Drive (the master). Pure: frames and times in, frames out through a
// CanBus's send(); no threads, no clock of its own, no DDS. nodes/virtual_drive runs it over a
// simulated drive on a real bus; the unit tests run it against the master on an in-memory bus.
//
//   - NMT slave: boot-up at start(); start / stop / enter pre-operational / reset node / reset
//     communication honoured (a reset restores the dictionary from the factory); heartbeat
//     producer per 0x1017 (poll()).
//   - SDO server (expedited) in pre-operational and operational.
//   - PDOs only in operational, after the dictionary's communication and mapping entries (which
//     a master may change over SDO while pre-operational). An RPDO1 is unpacked when it arrives;
//     a controlword (RPDO1 or an SDO write of 0x6040) is decoded with decode_controlword(previous)
//     and requested from the drive's power state machine. Force only in operation enabled:
//     target torque (per mille of the rated force) -> newtons.
//   - Lockstep (params.lockstep): the SYNC is the clock. At a SYNC in operational, when an RPDO1
//     (or an SDO write of 0x2002) came since the last step and its command tick == periods
//     stepped (0x2001), one period is applied and periods stepped grows by one; otherwise (a
//     repeated or early SYNC) nothing is. The first SYNC answered after NMT start only samples
//     (the run's tick 0 is the initial state). Then the synchronous TPDOs. finished() after the
//     run's ticks.
//   - Realtime: step_period() on the owner's clock with the latest target torque, then
//     check_timeouts(): in operation enabled, no SYNC for sync_timeout_ms -> fault 0x8700, no
//     heartbeat of the consumer-watched master (0x1016.1) -> fault 0x8130 (both counted from the
//     later of the last one received and the entry into operation enabled). Each SYNC is
//     answered with the latest state.
//   - A fault: the drive's fault(code) (force zero), EMCY with the code; cleared only by fault
//     reset and enable through the controlword (EMCY 0x0000 then).
//   - Malformed frames (wrong DLC for the COB-ID, an unknown COB-ID, RTR or 29-bit frames, an
//     undecodable NMT / SYNC / heartbeat) are counted and ignored, never thrown.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/canopen/cia402_application.hpp"
#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/canopen/sdo_server.hpp"
#include "pmlsm/drive/drive.hpp"

namespace pmlsm::canopen {

// TPDO2's entries, which make_cia402_dictionary leaves out (the lockstep contract's objects are
// the application's: cia402_application.hpp). TPDO3's (a load sensor's) are cia402_dictionary.hpp's.
inline constexpr std::uint16_t kObjectTpdo2Communication = 0x1801;
inline constexpr std::uint16_t kObjectTpdo2Mapping = 0x1A01;

struct Cia402SlaveParams {
  NodeId node{1};
  /// Target torque per mille -> newtons, metres and m/s -> increments.
  ScalingConfig scaling;
  /// The SYNC is the clock (true), or the owner's clock calls step_period() (false).
  bool lockstep = true;
  /// Lockstep: the run's ticks; finished() once ticks - 1 periods are stepped (tick 0 is the
  /// initial state). 0: never finished.
  std::uint64_t ticks = 0;
  /// Realtime: no SYNC for this long in operation enabled -> fault 0x8700.
  std::uint32_t sync_timeout_ms = 10;
  /// Fault 0x5000 (device hardware) when this many periods are stepped.
  std::optional<std::uint64_t> inject_fault_at_period;
};

/// What the slave tells its owner. Called from the slave's calls, on the owner's thread.
class Cia402SlaveEvents {
 public:
  virtual ~Cia402SlaveEvents() = default;
  /// Lockstep: tick `run_tick` of the run is the drive's state now (0: the initial state, at
  /// the first SYNC answered after NMT start); `applied_force_n` what the period applied.
  virtual void run_tick(std::uint64_t run_tick, double applied_force_n) = 0;
  /// A line for the log: a state change (error false) or a fault or refusal (error true), with
  /// `now_ns` the time the slave was given.
  virtual void log(bool error, const std::string& line, std::int64_t now_ns) = 0;
};

struct Cia402SlaveCounters {
  std::uint64_t frames_in = 0, frames_out = 0, send_failures = 0, malformed = 0, ignored = 0;
  std::uint64_t syncs = 0, unstepped_syncs = 0, rpdos = 0, rejected_rpdos = 0, sdo_requests = 0, emcys = 0;
};

/// "SYNCs N (not stepped N), RPDOs N (refused N), SDO requests N, frames in N out N (send
/// failures N), malformed N, ignored N, EMCYs N".
std::string describe(const Cia402SlaveCounters& c);

/// Intervals between SYNCs as they arrive (the master's tick jitter plus the bus): mean, standard
/// deviation, p99 (10 us buckets up to 10 ms) and max. Fixed storage: no allocation per SYNC.
class IntervalStatistics {
 public:
  void add(std::int64_t interval_ns);
  std::uint64_t count() const { return count_; }
  double mean_us() const;
  double std_us() const;
  double p99_us() const;
  double max_us() const { return max_us_; }

 private:
  static constexpr std::size_t kBuckets = 1000;
  static constexpr double kBucketUs = 10.0;
  std::array<std::uint64_t, kBuckets> buckets_{};
  std::uint64_t count_ = 0;
  double sum_us_ = 0, sum_sq_us_ = 0, max_us_ = 0;
};

class Cia402Slave : Cia402ApplicationEvents {
 public:
  /// The dictionary as the device starts (and as an NMT reset restores it).
  using DictionaryFactory = std::function<ObjectDictionary()>;

  /// `drive`, `bus` and `events` must outlive the slave; `bus` is used to send only.
  /// @throws std::invalid_argument for a scaling UnitScaling refuses; what the factory throws.
  Cia402Slave(const Cia402SlaveParams& params, DictionaryFactory make_dictionary, drive::Drive& drive, can::CanBus& bus,
              Cia402SlaveEvents& events);
  Cia402Slave(const Cia402Slave&) = delete;
  Cia402Slave& operator=(const Cia402Slave&) = delete;

  /// Sends the boot-up (pre-operational) and takes `now_ns` as the start of every time-out.
  void start(std::int64_t now_ns);
  /// One frame from the bus.
  void on_frame(const CanFrame& f, std::int64_t now_ns);
  /// Realtime: one period with the latest target torque.
  void step_period(std::int64_t now_ns);
  /// Realtime: the SYNC and master-heartbeat watches.
  void check_timeouts(std::int64_t now_ns);
  /// The heartbeat when it is due (0x1017).
  void poll(std::int64_t now_ns);

  bool finished() const { return finished_; }
  /// Periods stepped since the run began (lockstep: the first SYNC answered after NMT start).
  std::uint64_t run_periods() const { return application_.periods() - run_base_; }
  std::uint64_t periods() const { return application_.periods(); }
  NmtState nmt_state() const { return nmt_.state(); }
  const Cia402SlaveCounters& counters() const { return counters_; }
  const IntervalStatistics& sync_intervals() const { return sync_intervals_; }
  const ObjectDictionary& dictionary() const { return od_; }

 private:
  struct PdoChannel {
    bool valid = false;
    std::uint32_t cob_id = 0;
    std::uint8_t transmission_type = 1;
    PdoMap map;
  };
  static PdoChannel load_pdo(const ObjectDictionary& od, std::uint16_t communication_index);

  void send(const CanFrame& f);
  void malformed(const CanFrame& f, const char* why, std::int64_t now_ns);
  void reload_pdos();
  std::optional<ConsumerHeartbeat> consumer() const;
  // Cia402ApplicationEvents: the owner's log; the emergency as an EMCY frame.
  void log(bool error, const std::string& line, std::int64_t now_ns) override { events_.log(error, line, now_ns); }
  void emergency(std::uint16_t code) override;
  void send_tpdos();
  void on_sync(std::int64_t now_ns);
  void on_rpdo1(const CanFrame& f, std::int64_t now_ns);
  void on_sdo(const CanFrame& f, std::int64_t now_ns);
  void on_nmt(const CanFrame& f, std::int64_t now_ns);
  void reset(NmtReset kind, std::int64_t now_ns);

  Cia402SlaveParams params_;
  DictionaryFactory make_dictionary_;
  drive::Drive& drive_;
  can::CanBus& bus_;
  Cia402SlaveEvents& events_;
  ObjectDictionary od_;
  Cia402Application application_;
  SdoServer sdo_;
  NmtSlave nmt_;
  PdoChannel rpdo1_, tpdo1_, tpdo2_, tpdo3_;
  IntervalStatistics sync_intervals_;
  Cia402SlaveCounters counters_;

  std::uint64_t run_base_ = 0;
  std::uint64_t tpdo_syncs_ = 0;
  bool command_pending_ = false;
  bool first_answered_ = false;
  bool finished_ = false;
  std::int64_t last_sync_ns_ = 0;
  std::int64_t last_master_heartbeat_ns_ = 0;
};

}  // namespace pmlsm::canopen
