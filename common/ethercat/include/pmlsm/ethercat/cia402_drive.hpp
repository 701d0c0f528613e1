// The drive loop's backend for a real (or virtual) CiA 402 drive on EtherCAT: our master (Master)
// taking one slave to OP in a cyclic synchronous mode and exchanging its process data once a
// tick, behind the same seam and with the same contract as the CANopen master
// (canopen::Cia402Drive): the power-state walk, faults, quick stop, a lost drive at zero force.
// Pure: a Link, no DDS, no threads; tested against the virtual drive in this thread.
//
// Boot (boot()): the slaves counted (the drive at drive.position must answer), station addresses
// set, the drive's SII read and its identity compared with the rig file's (vendor id, product
// code), INIT, the mailbox, PREOP; by SDO 0x6060 = drive.mode and 0x60C2 = 1 ms; the rig file's
// mapping written (0x1C12 / 0x1C13 and the PDOs, when it has a pdo section); the process data
// mapped as the drive's 0x1C12 / 0x1C13 say (map_process_data), in which the master finds
// controlword 0x6040 and the mode's target (outputs: target torque 0x6071, velocity 0x60FF or
// position 0x607A), statusword 0x6041, torque actual 0x6077, velocity actual 0x606C and position
// actual 0x6064 (inputs); a missing one stops the boot naming it. 0x6061 read back = the mode.
// With drive.distributed_clocks, the drive's clock set to the master's time
// (Master::configure_distributed_clocks) and, each cycle after the outputs, the master's time
// written to it (its drift control follows), plus the frame's way there (half the running mean of
// the cycle's round trips; a ring's delay would be measured by the ports' receive times instead).
// The process-data watchdog set (realtime: drive.watchdog_ms; lockstep: off, since a lockstep tick
// waits on the slowest node), SAFEOP, one cycle of outputs that step nothing, OP. Errors throw
// Cia402DriveError naming the slave, the object or register and what came back.
//
// The setpoint (drive::Setpoint) by mode, as far as the mapping carries it:
//   cst  0x6071 = force_n
//   csv  0x60FF = velocity_mps, 0x60B2 torque offset = feedforward_force_n
//   csp  0x607A = position_m + origin, 0x60B1 velocity offset = velocity_mps, 0x60B2 as in csv
// where origin makes the target the drive's position when it entered operation enabled (the
// reference moves it from there, it never jumps to where the controller started). Outside
// operation enabled the targets hold the drive still: torque and velocity 0, position its own.
// In csv and csp the reading's applied force is the drive's torque demand 0x6074 (or, unmapped,
// its torque actual): the force its own loops applied, for the estimator.
//
// A sensor on the load: the additional position 0x60E4:1 in the inputs is a load encoder's
// position (increments, the drive's scaling), the virtual drive's 0x2003 an accelerometer's
// reading (um/s^2); mapped, the reading carries them (Measurement::load_position_m,
// load_acceleration_mps2), else they are NaN: a drive without the sensor does not map them.
//
// A cycle: apply() writes the outputs (LWR, working counter 1: the drive's SM2 took them) and the
// drive steps one period with them; sample() reads the inputs (LRD, working counter 1): the period
// that step ended. So tick k's reading holds the command of tick k-1, as the CANopen rig's does.
// Lockstep (both command tick 0x2002 in the outputs and periods stepped 0x2001 in the inputs, the
// contract of the virtual drive's dictionary; a drive without them runs realtime only): the
// outputs of tick k carry command tick base + k, and the drive steps only when that equals its
// periods stepped, so outputs sent again (a reply lost) are no second period. sample() of tick k
// wants periods stepped base + k; when the drive is still one behind it sends the outputs again,
// and after master.lockstep.cycle_retries attempts it declares the drive lost (0x8130), never
// hangs. Realtime: each exchange waits master.realtime.reply_deadline_us, once; a cycle without
// inputs keeps the last reading and is counted, master.realtime.max_missed_cycles in a row lose
// the drive. The command tick (when mapped) is the last periods stepped heard.
// A working counter other than 1 is counted; when the drive is lost the master reads the slave's
// AL state and names it (SAFEOP with 0x001B: the drive's watchdog saw no outputs).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <vector>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cia402_remote_state.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/drive/drive.hpp"
#include "pmlsm/drive/loop_statistics.hpp"
#include "pmlsm/ethercat/link.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/plant/load_sensor.hpp"
#include "pmlsm/util/parameter_table.hpp"

namespace pmlsm::ethercat {

struct Cia402DriveConfig {
  /// The drive's position on the ring (0: the first slave after the master).
  std::uint16_t position = 0;
  /// 0x6060: canopen::kModeCyclicSynchronous{Torque,Velocity,Position}.
  std::int8_t mode = canopen::kModeCyclicSynchronousTorque;
  /// The identity the drive's SII must show (0x1018:1 and :2).
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0x00005001;
  canopen::ScalingConfig scaling{675.0, 1e6};
  /// The process-data watchdog the drive is given in realtime (ETG: the ESI's SM watchdog).
  std::uint32_t watchdog_ms = 100;
  /// The drive's distributed clock set to the master's time at boot and kept on it, a write of the
  /// master's time each cycle (Master::configure_distributed_clocks, write_system_time).
  bool distributed_clocks = true;
  /// The drive synchronous to SYNC0 (ETG.1020's DC mode): 0x1C32:01 / 0x1C33:01 = 2 and the cycle
  /// in 0x1C32:02 at boot, SYNC0 every cycle from the slave's clock (Master::configure_sync0),
  /// `sync0_shift_us` into the cycle. Needs distributed_clocks; realtime only (the slave's clock
  /// paces the drive, not the master's frames).
  bool sync0 = false;
  std::uint32_t sync0_shift_us = 0;
  /// The objects the master maps into the outputs and the inputs at boot (the rig file's pdo
  /// section), in order; empty: the drive's own assignment is taken as it is.
  std::vector<canopen::PdoMapEntry> outputs_mapping;
  std::vector<canopen::PdoMapEntry> inputs_mapping;

  bool realtime = false;
  /// Set-up frames: how long a reply may take, and how often a frame is sent again.
  std::uint32_t reply_timeout_ms = 20;
  std::uint32_t retries = 2;
  std::uint32_t state_timeout_ms = 2000;
  std::uint32_t enable_timeout_cycles = 200;
  /// Lockstep: how long one exchange of a cycle waits for its reply, and how many times the
  /// outputs go again before the drive is lost.
  std::uint32_t cycle_timeout_ms = 50;
  std::uint32_t cycle_retries = 5;
  /// Realtime: how long an exchange waits for its reply within the tick.
  std::uint32_t reply_deadline_us = 400;
  std::uint32_t max_missed_cycles = 10;
  /// The ranges of visit_parameters, and the mappings both given or both empty.
  /// @throws std::invalid_argument naming the key and the value.
  void validate() const;
};

/// Every setting of Cia402DriveConfig a rig file (configs/ethercat/drive.yaml) sets, declared once
/// with its key, range and why; `realtime` is the program's.
template <typename Config, typename Visitor>
void visit_parameters(Config& m, Visitor& v) {
  v.integer("drive.position", m.position, {0.0, 65535.0, "a position on the ring: 16 bits of auto-increment address"});
  v.choice("drive.mode", m.mode, &canopen::mode_from_string);
  v.integer("drive.vendor_id", m.vendor_id, {0.0, 4294967295.0, "ETG's vendor id, 0x1018:1"});
  v.integer("drive.product_code", m.product_code, {0.0, 4294967295.0, "the vendor's product code, 0x1018:2"});
  canopen::visit_scaling_parameters(m.scaling, v);
  v.integer("drive.watchdog_ms", m.watchdog_ms,
            {1.0, 6500.0, "the ESC's 16-bit watchdog in its default 100 us units: up to 6.5 s"});
  v.flag("drive.distributed_clocks", m.distributed_clocks);
  v.flag("drive.sync0", m.sync0);
  v.integer("drive.sync0_shift_us", m.sync0_shift_us, {0.0, 999.0, "into the 1 ms cycle: 0 to 999 us"});
  v.integer("master.reply_timeout_ms", m.reply_timeout_ms, {1.0, 10000.0, "1 ms to 10 s for a frame there and back"});
  v.integer("master.retries", m.retries, {0.0, 100.0, "0 to 100 resends of a set-up frame"});
  v.integer("master.state_timeout_ms", m.state_timeout_ms,
            {1.0, 600000.0, "1 ms to 10 minutes for an AL state change"});
  v.integer("master.enable_timeout_cycles", m.enable_timeout_cycles,
            {1.0, 1000000.0, "1 to a million control cycles in one power state"});
  v.integer("master.lockstep.cycle_timeout_ms", m.cycle_timeout_ms,
            {1.0, 60000.0, "1 ms to a minute for a cycle's reply"});
  v.integer("master.lockstep.cycle_retries", m.cycle_retries, {0.0, 1000.0, "0 to 1000 resends of a cycle"});
  v.integer("master.realtime.reply_deadline_us", m.reply_deadline_us,
            {10.0, 1000000.0, "10 us to 1 s into the tick (a tick is far shorter)"});
  v.integer("master.realtime.max_missed_cycles", m.max_missed_cycles,
            {1.0, 100000.0, "1 to 100,000 cycles in a row without the inputs"});
}

class Cia402DriveError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Cia402DriveCounters {
  std::uint64_t cycles = 0;                  ///< outputs sent (resends included)
  std::uint64_t output_resends = 0;          ///< lockstep: outputs sent again for one tick
  std::uint64_t frames_lost = 0;             ///< exchanges without a reply
  std::uint64_t working_counter_errors = 0;  ///< replies with a working counter other than 1
  std::uint64_t missed_inputs = 0;           ///< realtime: cycles without the inputs in time
  std::uint64_t dc_writes = 0;               ///< the master's time written to the drive's clock
  std::uint64_t dc_writes_lost = 0;          ///< of them not answered or not taken
  std::uint64_t mailbox_polls = 0;           ///< looks into the drive's send mailbox for emergencies
  /// SYNC0: outputs sent `sync0_shift_us` or more after their tick's start (tick 0 on a whole
  /// millisecond of the master's clock, each a millisecond on), after the pulse that was to take them.
  std::uint64_t outputs_after_sync0 = 0;
};

class Cia402Drive final : public drive::Drive {
 public:
  /// Where the image sits in the logical address space.
  static constexpr std::uint32_t kLogicalAddress = 0x00010000;

  /// @throws std::invalid_argument for a bad config. `link` outlives the drive. `master_clock` (ns,
  /// monotonic; empty: the host's CLOCK_MONOTONIC, on which the drive loop ticks) is the master's
  /// time the drive's distributed clock follows, and so the grid SYNC0 falls on.
  Cia402Drive(const Cia402DriveConfig& config, Link& link, std::function<std::int64_t()> master_clock = {});

  /// The boot (see the file comment): the drive in OP, not stepped. @throws Cia402DriveError.
  void boot();
  /// Learns the drive's periods stepped (the run's base) by one read, without stepping it.
  /// @throws Cia402DriveError when the drive does not answer.
  void start();
  /// Walks the drive to operation enabled before the run, one cycle that steps nothing at a time
  /// (realtime: a cycle a millisecond of the host's clock).
  /// @throws Cia402DriveError naming the state it is stuck in (or the fault).
  void enable_and_wait();
  /// The drive's 0x092C (the difference of its clock to the master's times written, filtered)
  /// [ns]; nullopt without distributed clocks or when it does not answer. Not for the cycle: one
  /// more exchange with the set-up time-outs.
  std::optional<std::int64_t> dc_difference_ns();
  /// The run over: the slave walked to SAFEOP (outputs no longer taken), then INIT. Never throws;
  /// false when it did not follow (its AL state in last_problem()).
  bool release();

  // drive::Drive
  drive::Measurement sample() override;
  /// The force alone: apply_setpoint({force_n}) (in csv and csp: the drive held still).
  void apply(double force_n) override;
  void apply_setpoint(const drive::Setpoint& setpoint) override;
  drive::TransitionResult request(drive::DriveCommand command) override { return remote_.request(command); }
  void fault(std::uint16_t error_code) override { remote_.fault(error_code); }
  drive::PowerState power_state() const override { return remote_.power_state(); }
  std::uint16_t error_code() const override { return remote_.error_code(); }
  std::uint64_t fault_count() const override { return remote_.fault_count(); }
  bool simulated() const override { return false; }

  bool lost() const noexcept { return remote_.lost(); }
  /// In OP after boot() and not released since.
  bool booted() const noexcept { return booted_; }
  /// Why the drive was lost or faulted, its error code, a stuck walk ("" when none).
  const char* last_problem() const noexcept { return remote_.problem(); }
  std::optional<drive::PowerState> stuck_in() const noexcept { return remote_.stuck_in(); }
  std::uint16_t statusword() const noexcept { return remote_.statusword(); }
  std::uint16_t controlword() const noexcept { return remote_.last_controlword(); }
  /// The drive's periods stepped (0x2001), when it maps them.
  std::uint32_t periods_stepped() const noexcept { return periods_; }
  bool lockstep_contract() const noexcept { return command_tick_at_ >= 0 && periods_at_ >= 0; }
  std::uint64_t ticks() const noexcept { return tick_; }
  const Cia402DriveCounters& counters() const noexcept { return counters_; }
  /// The first SYNC0 pulse the boot set, in the drive's system time; 0 without SYNC0.
  std::uint64_t sync0_start_ns() const noexcept { return sync0_start_ns_; }
  /// The cycle's exchanges there and back (the bus cycle time), the first kRoundTripsKept kept.
  drive::LatencySummary round_trips() { return round_trips_.latency(); }
  static constexpr std::size_t kRoundTripsKept = 1U << 17;
  /// Every this many cycles the drive's send mailbox is looked into (Master::poll_emergency): a
  /// CoE emergency the drive posted (a warning, or a fault's) is read within 10 ms, not only at
  /// the next SDO transfer.
  static constexpr std::uint64_t kMailboxPollCycles = 10;
  /// The drive's CoE emergencies read so far, and the last one's error code.
  std::uint64_t emergencies() const noexcept { return master_.emergencies(); }
  std::uint16_t last_emergency_code() const noexcept { return master_.last_emergency_code(); }
  const Cia402DriveConfig& config() const noexcept { return config_; }
  const canopen::UnitScaling& scaling() const noexcept { return scaling_; }
  const SlaveInfo& slave() const noexcept { return slave_; }
  const ProcessDataLayout& layout() const noexcept { return layout_; }
  /// The load's sensor the inputs carry: an encoder (0x60E4:1 mapped), an accelerometer (0x2003) or none.
  LoadSensorKind load_sensor() const noexcept;
  Master& master() noexcept { return master_; }

 private:
  /// One exchange of a cycle through scratch_, its time there and back recorded: true when
  /// answered with working counter 1 (else counted as lost or as a working counter error).
  bool cycle_exchange(Command command, std::uint32_t address, std::uint16_t length);
  /// The targets a cycle sends, in the dictionary's units.
  struct Targets {
    std::int16_t torque = 0;
    std::int32_t velocity = 0;
    std::int32_t position = 0;
    std::int32_t velocity_offset = 0;
    std::int16_t torque_offset = 0;
  };
  /// Targets that hold the drive still (torque and velocity 0, position where it is).
  Targets still() const;
  /// The outputs out (LWR); true when the drive's SM2 took them (working counter 1).
  bool send_outputs(std::uint16_t controlword, const Targets& targets, std::uint32_t command_tick);
  bool send_outputs_again();
  /// The inputs in (LRD); true when read (working counter 1), the values taken.
  bool read_inputs();
  std::int64_t exchange_timeout_ns() const;
  int exchange_retries() const;
  /// The drive at zero force for good, `what` and the slave's AL state named.
  void lose(const char* what);
  /// One cycle that steps nothing: the controlword with a command tick one behind.
  bool idle_cycle(std::uint16_t controlword);
  void read_error_code();
  drive::Measurement measurement() const;
  std::uint64_t master_time_ns() const;
  /// Realtime, on the host's clock: waits for the next whole cycle (a set-up cycle at the drive's pace).
  void pace_cycle();

  Cia402DriveConfig config_;
  Master master_;
  canopen::UnitScaling scaling_;
  canopen::Cia402RemoteState remote_;
  SlaveInfo slave_;
  ProcessDataLayout layout_;
  // Byte offsets of the objects in the image (-1: not mapped).
  int controlword_at_ = -1;
  int target_torque_at_ = -1;
  int target_velocity_at_ = -1;
  int target_position_at_ = -1;
  int velocity_offset_at_ = -1;
  int torque_offset_at_ = -1;
  int torque_demand_at_ = -1;
  int load_position_at_ = -1;
  int load_acceleration_at_ = -1;
  int command_tick_at_ = -1;
  int statusword_at_ = -1;
  int torque_actual_at_ = -1;
  int velocity_actual_at_ = -1;
  int position_actual_at_ = -1;
  int periods_at_ = -1;
  std::vector<std::uint8_t> outputs_;
  std::vector<std::uint8_t> inputs_;
  std::vector<std::uint8_t> scratch_;  ///< a datagram's data, copied so a lost reply keeps the image

  // the drive as last read
  std::int16_t torque_actual_ = 0;
  std::int16_t torque_demand_ = 0;
  std::int32_t load_position_ = 0;
  std::int32_t load_acceleration_ = 0;
  std::int32_t velocity_actual_ = 0;
  std::int32_t position_actual_ = 0;
  std::uint32_t periods_ = 0;
  bool was_faulted_ = false;
  bool was_enabled_ = false;
  double position_origin_m_ = 0;  ///< csp: the drive's position less the reference's at enable

  std::uint32_t base_ = 0;
  bool booted_ = false;
  bool started_ = false;
  std::uint32_t missed_in_row_ = 0;
  std::uint64_t tick_ = 0;
  drive::Measurement last_measurement_;
  Cia402DriveCounters counters_;
  drive::LoopStatistics round_trips_{kRoundTripsKept};
  std::int64_t transit_ns_ = 0;                   ///< a frame's way to the drive, estimated from the round trips
  std::uint64_t sync0_start_ns_ = 0;              ///< the first SYNC0 pulse in the drive's system time (0: none)
  std::int64_t line_delay_ns_ = 0;                ///< the reference clock to the line's last clock
  std::uint64_t tick0_ns_ = 0;                    ///< tick 0\'s start on the master\'s clock (a whole millisecond)
  std::uint64_t emergencies_at_fault_check_ = 0;  ///< the master's count when a fault was last read
  bool own_clock_;                                ///< the owner gave the master's clock
  std::function<std::int64_t()> master_clock_;
};

}  // namespace pmlsm::ethercat
