// The drive loop's backend for a real (or virtual) CiA 402 drive on a CAN bus: the master's
// whole protocol in one pure class over a CanBus and a clock (no DDS, no threads), so that it
// is tested against an in-test slave.
//
// Bus contract (node id N, the master's heartbeat node id M, default 127):
//   RPDO1 0x200+N: 0x6040 controlword u16, 0x6071 target torque i16 (per mille of the rated
//                  force 0x6076), 0x2002 command tick u32 (the tick whose command this is)
//   TPDO1 0x180+N: 0x6041 statusword u16, 0x6077 torque actual i16, 0x606C velocity actual i32
//   TPDO2 0x280+N: 0x6064 position actual i32, 0x2001 periods stepped u32
//   TPDO3 0x380+N: with a sensor on the load (drive.load_sensor), its reading: 0x60E4:1 additional
//                  position actual i32 (a load encoder's, the drive's increments) or 0x2003 load
//                  acceleration i32 (um/s^2), where the drive's 0x1A02 maps it
//   SYNC  0x080 with a counter 1..240. All PDOs synchronous.
// Lockstep: the drive, on SYNC, steps one period only when the latest RPDO1's command tick
// equals its periods stepped, then answers TPDO1 + TPDO2. The master's tick k is the drive's
// periods stepped base + k, where base is what the drive had stepped when the run began
// (start()). sample() of tick k sends SYNC and waits for the answer whose periods stepped is
// base + k; on a time-out it resends the same SYNC (first the RPDO1 of tick k-1 again when the
// drive is still at k-1: the RPDO1 was lost), and after `sync_retries` resends it declares the
// drive lost (fault 0x8130), never hangs. apply() sends RPDO1 with command tick base + k.
// Before the run (start(), enable_and_wait()) RPDO1 carries command tick periods stepped - 1,
// which the drive does not step on: the power state walk moves no plant period.
// Realtime: sample() sends SYNC and takes the newest TPDOs within the deadline (missing ones
// counted; max_missed_answers in a row: the drive is lost); RPDO1 carries the last periods
// stepped heard.
// Once started, a drive heartbeat in another NMT state than operational (an NMT stop or reset
// from elsewhere) loses the drive: fault 0x8130, zero force. A SYNC or NMT command from another
// master, and the drive's frames with a wrong length, are counted (counters()) and ignored.
//
// Boot (boot()): NMT reset communication (unless disabled), wait for the drive's boot-up or
// heartbeat; SDO writes 0x6060 = 10 (cyclic
// synchronous torque), 0x60C2 = 1 ms (sub 1 = 1, sub 2 = -3), 0x1017 producer heartbeat,
// 0x1016:01 consumer (M << 16 | ms); read back 0x6061 = 10; with a load sensor, read TPDO3's
// mapping 0x1A02 (it must map the sensor's object, 32 bits) and make TPDO3 valid (0x1802:01 =
// 0x380+N); NMT start. Then every answer waits for TPDO3 too. The master's heartbeat
// (0x700+M, operational) is produced from construction, during every wait. Errors throw
// Cia402DriveError naming what is missing, the object and the abort code.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cia402_master.hpp"
#include "pmlsm/canopen/cia402_remote_state.hpp"
#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/canopen/sdo.hpp"
#include "pmlsm/canopen/sync.hpp"
#include "pmlsm/drive/drive.hpp"
#include "pmlsm/plant/load_sensor.hpp"
#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm::canopen {

struct Cia402DriveConfig {
  int node_id = 1;
  int master_node_id = 127;
  ScalingConfig scaling{675.0, 1e6};

  bool realtime = false;
  /// Lockstep: how long one SYNC waits for its answer before it is resent.
  std::uint32_t sync_timeout_ms = 50;
  /// Lockstep: resends of a SYNC before the drive is declared lost.
  std::uint32_t sync_retries = 5;
  /// Realtime: how long into the tick sample() waits for the TPDOs.
  std::uint32_t tpdo_deadline_us = 400;
  /// Realtime: this many ticks in a row without the TPDOs and the drive is lost (fault 0x8130).
  std::uint32_t max_missed_answers = 10;
  std::uint32_t boot_timeout_ms = 5000;
  /// boot() starts with NMT reset communication to the drive (then waits for its boot-up).
  bool reset_communication = true;
  std::uint32_t sdo_timeout_ms = 500;
  /// The drive's heartbeat (0x1017) and how long the master waits for it (0: not watched).
  std::uint16_t drive_heartbeat_ms = 100;
  std::uint16_t drive_heartbeat_timeout_ms = 350;
  /// The master's heartbeat period and what the drive is told to allow (0x1016).
  std::uint16_t master_heartbeat_ms = 100;
  std::uint16_t master_heartbeat_timeout_ms = 350;
  /// SYNC counter overflow (2..240).
  std::uint8_t sync_overflow = 240;
  /// Cycles in one state while a move is expected before the walk is stuck.
  std::uint32_t enable_timeout_cycles = 200;
  /// The drive's load sensor (the system file's kinds), read in TPDO3 (none: TPDO3 left as the
  /// drive has it).
  LoadSensorKind load_sensor = LoadSensorKind::kNone;
  /// The ranges of visit_parameters, then check_relations().
  /// @throws std::invalid_argument naming the key (as the rig file writes it) and the value.
  void validate() const;
  /// What ties two values together: the node ids differ, each heartbeat time-out exceeds its period.
  /// @throws std::invalid_argument naming the key and the value.
  void check_relations() const;
};

/// Every setting of Cia402DriveConfig a rig file sets, declared once (pmlsm/util/parameter_table.hpp)
/// with its key in configs/canopen/drive.yaml, its range and why; realtime and
/// reset_communication are the program's. validate() checks these ranges and the reader of the
/// file reads by this table. Config is Cia402DriveConfig or const Cia402DriveConfig.
template <typename Config, typename Visitor>
void visit_parameters(Config& m, Visitor& v) {
  const Plausible node_id{1.0, 127.0, "a CANopen node id (CiA 301: 1 to 127)"};
  const Plausible heartbeat{1.0, 65535.0, "a heartbeat time of 0x1016/0x1017: 16 bits of milliseconds"};
  v.integer("drive.node_id", m.node_id, node_id);
  visit_scaling_parameters(m.scaling, v);
  v.integer("drive.heartbeat_ms", m.drive_heartbeat_ms, {0.0, 65535.0, "0x1017: 0 (none) or 16 bits of milliseconds"});
  v.choice("drive.load_sensor", m.load_sensor, &load_sensor_kind_from_string);
  v.integer("master.node_id", m.master_node_id, node_id);
  v.integer("master.heartbeat_ms", m.master_heartbeat_ms, heartbeat);
  v.integer("master.heartbeat_timeout_ms", m.master_heartbeat_timeout_ms, heartbeat);
  v.integer("master.drive_heartbeat_timeout_ms", m.drive_heartbeat_timeout_ms, heartbeat);
  v.integer("master.boot_timeout_ms", m.boot_timeout_ms, {1.0, 600000.0, "1 ms to 10 minutes for a boot-up"});
  v.integer("master.sdo_timeout_ms", m.sdo_timeout_ms, {1.0, 60000.0, "1 ms to a minute for an SDO answer"});
  v.integer("master.enable_timeout_cycles", m.enable_timeout_cycles,
            {1.0, 1000000.0, "1 to a million control cycles in one power state"});
  v.integer("master.sync_overflow", m.sync_overflow, {2.0, 240.0, "the SYNC counter's overflow (CiA 301 0x1019)"});
  v.integer("master.lockstep.sync_timeout_ms", m.sync_timeout_ms,
            {1.0, 60000.0, "1 ms to a minute for a SYNC's answer"});
  v.integer("master.lockstep.sync_retries", m.sync_retries, {0.0, 1000.0, "0 to 1000 resends of a SYNC"});
  v.integer("master.realtime.tpdo_deadline_us", m.tpdo_deadline_us,
            {0.0, 1000000.0, "0 to 1 s into the tick (a tick is far shorter)"});
  v.integer("master.realtime.max_missed_answers", m.max_missed_answers,
            {1.0, 100000.0, "1 to 100,000 ticks in a row without the TPDOs"});
}

class Cia402DriveError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Cia402DriveCounters {
  std::uint64_t syncs = 0;  ///< SYNCs sent (resends included)
  std::uint64_t sync_resends = 0;
  std::uint64_t rpdo_resends = 0;
  std::uint64_t tpdo_missing = 0;  ///< realtime: ticks without a full answer in time
  std::uint64_t emcys = 0;
  std::uint64_t stale_tpdos = 0;    ///< answers to an older period, ignored
  std::uint64_t malformed = 0;      ///< the drive's frames with a wrong length, ignored
  std::uint64_t foreign_syncs = 0;  ///< SYNCs another producer sent (CiA 301 allows one)
  std::uint64_t foreign_nmt = 0;    ///< NMT commands another master sent
  std::uint64_t foreign_rpdos = 0;  ///< RPDOs to this drive another master sent (this one sends RPDO1 only)
};

class Cia402Drive final : public drive::Drive {
 public:
  /// Monotonic time in nanoseconds.
  using Clock = std::function<std::int64_t()>;

  /// @throws std::invalid_argument for a bad config. `bus` must outlive the drive.
  Cia402Drive(const Cia402DriveConfig& config, can::CanBus& bus, Clock clock);

  /// The boot sequence (see the file comment). @throws Cia402DriveError.
  void boot();
  /// Learns the drive's periods stepped (the run's base) by one SYNC, without stepping it.
  /// @throws Cia402DriveError when the drive does not answer.
  void start();
  /// Walks the drive to operation enabled before the run, one non-stepping SYNC exchange a
  /// cycle. @throws Cia402DriveError naming the state it is stuck in (or the fault).
  void enable_and_wait();

  // drive::Drive
  drive::Measurement sample() override;
  void apply(double force_n) override;
  drive::TransitionResult request(drive::DriveCommand command) override;
  void fault(std::uint16_t error_code) override;
  drive::PowerState power_state() const override;
  std::uint16_t error_code() const override { return remote_.error_code(); }
  std::uint64_t fault_count() const override { return remote_.fault_count(); }
  bool simulated() const override { return false; }

  /// Lost: no answer after the retries, or the drive's heartbeat timed out.
  bool lost() const noexcept { return remote_.lost(); }
  /// Why the drive was lost or faulted locally, the EMCY, a stuck walk ("" when none).
  const char* last_problem() const noexcept { return remote_.problem(); }
  /// The walk has been stuck in one state for enable_timeout_cycles (during the run).
  std::optional<drive::PowerState> stuck_in() const noexcept { return remote_.stuck_in(); }
  std::uint16_t statusword() const noexcept { return remote_.statusword(); }
  std::uint16_t controlword() const noexcept { return remote_.last_controlword(); }
  std::uint32_t periods_stepped() const noexcept { return periods_; }
  std::uint64_t ticks() const noexcept { return tick_; }
  const Cia402DriveCounters& counters() const noexcept { return counters_; }
  const Cia402DriveConfig& config() const noexcept { return config_; }
  const UnitScaling& scaling() const noexcept { return scaling_; }

 private:
  std::int64_t now_ns() const { return clock_(); }
  std::uint64_t now_ms() const { return static_cast<std::uint64_t>(clock_() / 1000000); }
  /// Heartbeat production and consumption; received frames dispatched. Waits up to
  /// `timeout_ns` for one frame; true when one was handled.
  bool service(std::int64_t timeout_ns);
  void handle(const can::CanFrame& frame);
  void send(const can::CanFrame& frame);
  void send_sync(bool resend);
  void send_rpdo(std::uint16_t controlword, std::int16_t torque, std::uint32_t tick);
  /// Waits until a TPDO1 + TPDO2 pair with periods stepped `expected` (nullopt: any) arrived
  /// after `since`, or `deadline_ns` passes.
  bool wait_answer(std::optional<std::uint32_t> expected, std::int64_t deadline_ns);
  /// One SYNC exchange that does not step; true when answered.
  bool idle_exchange(std::uint16_t controlword);
  std::uint32_t sdo(bool write, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size,
                    const char* name);
  void lose(const char* what);
  /// boot(): TPDO3's mapping checked for the load sensor's object, TPDO3 made valid.
  void enable_load_sensor();
  drive::Measurement measurement() const;

  Cia402DriveConfig config_;
  can::CanBus& bus_;
  Clock clock_;
  NodeId node_;
  NodeId master_node_;
  UnitScaling scaling_;
  Cia402RemoteState remote_;
  SdoClient sdo_;
  SyncProducer sync_;
  std::optional<HeartbeatConsumer> heartbeat_;
  can::CanFrame last_sync_{};
  can::CanFrame last_rpdo_{};
  bool rpdo_sent_ = false;
  std::int64_t next_master_heartbeat_ns_ = 0;

  // the drive as last heard
  bool seen_ = false;  // boot-up or heartbeat
  bool boot_up_ = false;
  std::int16_t torque_actual_ = 0;
  std::int32_t velocity_actual_ = 0;
  std::int32_t position_actual_ = 0;
  std::uint32_t periods_ = 0;
  // the answer being collected (generation counts SYNCs sent)
  std::uint64_t generation_ = 0;
  std::uint64_t tpdo1_generation_ = 0;
  std::uint64_t tpdo2_generation_ = 0;
  std::uint32_t tpdo2_periods_ = 0;
  std::uint64_t tpdo3_generation_ = 0;
  // TPDO3 with a load sensor: its length and where the sensor's 32 bits are in it (boot()).
  std::uint8_t tpdo3_dlc_ = 0;
  std::uint8_t tpdo3_offset_ = 0;
  std::int32_t load_reading_ = 0;  // increments (0x60E4:1) or um/s^2 (0x2003)
  // SDO transfer outcome
  std::optional<SdoClientEvent> sdo_event_;

  std::uint32_t base_ = 0;
  bool started_ = false;
  std::uint32_t missed_in_row_ = 0;  // realtime: ticks in a row without the TPDOs
  std::uint64_t tick_ = 0;           // the tick the next sample() is
  drive::Measurement last_measurement_;
  Cia402DriveCounters counters_;
};

}  // namespace pmlsm::canopen
