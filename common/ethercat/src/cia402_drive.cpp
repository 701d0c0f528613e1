#include "pmlsm/ethercat/cia402_drive.hpp"

#include <algorithm>
#include <cstdio>
#include <string>

#include "pmlsm/canopen/cia402_application.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/util/clock.hpp"
#include "pmlsm/util/little_endian.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm::ethercat {

namespace {

constexpr std::int64_t kNsPerMs = 1'000'000;

const Cia402DriveConfig& validated(const Cia402DriveConfig& config) {
  config.validate();
  return config;
}

MasterParams master_params(const Cia402DriveConfig& c) {
  MasterParams p;
  p.reply_timeout_ns = static_cast<std::int64_t>(c.reply_timeout_ms) * kNsPerMs;
  p.retries = static_cast<int>(c.retries);
  p.state_timeout_ns = static_cast<std::int64_t>(c.state_timeout_ms) * kNsPerMs;
  return p;
}

}  // namespace

void Cia402DriveConfig::validate() const {
  RangeCheck check;
  visit_parameters(*this, check);
  if (canopen::supported_mode_bit(mode) == 0) {
    throw std::invalid_argument("drive.mode: must be a cyclic synchronous mode (8, 9, 10), got " +
                                std::to_string(static_cast<int>(mode)));
  }
  if (sync0 && !distributed_clocks) {
    throw std::invalid_argument(
        "drive.sync0: SYNC0 comes from the drive's distributed clock: needs "
        "drive.distributed_clocks true");
  }
  if (outputs_mapping.empty() != inputs_mapping.empty()) {
    throw std::invalid_argument(std::string("pdo.") + (outputs_mapping.empty() ? "outputs" : "inputs") +
                                ": both directions are mapped, or neither (the drive's own assignment)");
  }
}

Cia402Drive::Cia402Drive(const Cia402DriveConfig& config, Link& link, std::function<std::int64_t()> master_clock)
    : config_(validated(config)),
      master_(link, master_params(config)),
      scaling_(config.scaling),
      remote_(config.enable_timeout_cycles),
      own_clock_(static_cast<bool>(master_clock)),
      // Unless the owner gives one, the host's CLOCK_MONOTONIC: the drive loop's tick grid runs on it.
      master_clock_(master_clock ? std::move(master_clock) : monotonic_ns) {}

std::uint64_t Cia402Drive::master_time_ns() const { return static_cast<std::uint64_t>(master_clock_()); }

void Cia402Drive::pace_cycle() {
  // A drive's state machine runs in its cycle (on SYNC0 in DC mode): a walk at wire speed would
  // outrun it. On the host's clock only; a clock of the owner's paces itself.
  if (own_clock_) return;
  sleep_until_monotonic_ns((monotonic_ns() / kNsPerMs + 1) * kNsPerMs);
}

// The boot is one sequence of set-up steps, each naming what failed; kept in one place so the
// order ETG.1000.6 and CiA 402 ask for is visible.
// NOLINTNEXTLINE(readability-function-size)
void Cia402Drive::boot() {
  const std::uint16_t slaves = master_.count_slaves();
  if (slaves <= config_.position) {
    throw Cia402DriveError("no drive at position " + std::to_string(config_.position) +
                           " (drive.position): " + std::to_string(slaves) + " slave(s) answer on the bus");
  }
  const std::vector<std::uint16_t> stations = master_.assign_station_addresses(slaves);
  const std::uint16_t station = stations[config_.position];
  try {
    slave_ = master_.read_slave_info(station);
  } catch (const std::runtime_error& e) {
    throw Cia402DriveError(e.what());
  }
  const std::string name = "the drive at position " + std::to_string(config_.position) + " (" +
                           (slave_.name.empty() ? format_hex(station, 4) : slave_.name) + ")";
  if (slave_.vendor_id != config_.vendor_id || slave_.product_code != config_.product_code) {
    throw Cia402DriveError(name + " is vendor " + format_hex(slave_.vendor_id, 8) + " product " +
                           format_hex(slave_.product_code, 8) + "; the rig file expects vendor " +
                           format_hex(config_.vendor_id, 8) + " product " + format_hex(config_.product_code, 8) +
                           " (drive.vendor_id, drive.product_code)");
  }
  const auto walk_to = [&](AlState state) {
    const StateResult r = master_.request_state(station, state);
    if (!r.reached) {
      throw Cia402DriveError(name + " did not reach " + to_string(state) + ": it is in " + r.describe());
    }
  };
  const auto sdo = [&](bool write, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size,
                       const char* what) {
    const SdoResult r =
        write ? master_.sdo_download(slave_, index, sub, value, size) : master_.sdo_upload(slave_, index, sub);
    if (!r.done) {
      throw Cia402DriveError(name + ": SDO " + (write ? "write " : "read ") + format_hex(index, 4) + ":" +
                             std::to_string(sub) + " (" + what + ") " + r.describe());
    }
    return r.value;
  };
  try {
    walk_to(AlState::kInit);  // whatever a master before this one left it in
    master_.configure_mailbox(slave_);
    walk_to(AlState::kPreOp);
    const std::string mode_text = std::string("modes of operation, ") + canopen::mode_name(config_.mode);
    sdo(true, canopen::kObjectModesOfOperation, 0, static_cast<std::uint8_t>(config_.mode), 1, mode_text.c_str());
    sdo(true, canopen::kObjectInterpolationTimePeriod, 1, 1, 1, "interpolation time period value");
    sdo(true, canopen::kObjectInterpolationTimePeriod, 2, static_cast<std::uint8_t>(static_cast<std::int8_t>(-3)), 1,
        "interpolation time index");
    if (!config_.outputs_mapping.empty()) {
      master_.write_pdo_assignment(slave_, kObjectRxPdoAssign, kRxPdoMapping, config_.outputs_mapping);
      master_.write_pdo_assignment(slave_, kObjectTxPdoAssign, kTxPdoMapping, config_.inputs_mapping);
    }
    layout_ = master_.map_process_data(slave_, kLogicalAddress);
    const auto locate = [&](bool output, std::uint16_t index, std::uint8_t bits, bool required, const char* what) {
      const std::vector<canopen::PdoMapEntry>& entries = output ? layout_.outputs : layout_.inputs;
      for (const canopen::PdoMapEntry& e : entries) {
        if (e.index == index && e.subindex == 0 && e.bit_length != bits) {
          throw Cia402DriveError(name + ": " + format_hex(index, 4) + " (" + what + ") is mapped with " +
                                 std::to_string(e.bit_length) + " bits, not " + std::to_string(bits));
        }
      }
      const int at = output ? layout_.output_offset(index) : layout_.input_offset(index);
      if (at < 0 && required) {
        throw Cia402DriveError(name + ": its " + (output ? "outputs (0x1C12's RxPDOs)" : "inputs (0x1C13's TxPDOs)") +
                               " do not map " + format_hex(index, 4) + " (" + what + ")");
      }
      return at;
    };
    controlword_at_ = locate(true, canopen::kObjectControlword, 16, true, "controlword");
    const std::int8_t mode = config_.mode;
    target_torque_at_ =
        locate(true, canopen::kObjectTargetTorque, 16, mode == canopen::kModeCyclicSynchronousTorque, "target torque");
    target_velocity_at_ = locate(true, canopen::kObjectTargetVelocity, 32,
                                 mode == canopen::kModeCyclicSynchronousVelocity, "target velocity");
    target_position_at_ = locate(true, canopen::kObjectTargetPosition, 32,
                                 mode == canopen::kModeCyclicSynchronousPosition, "target position");
    velocity_offset_at_ = locate(true, canopen::kObjectVelocityOffset, 32, false, "velocity offset");
    torque_offset_at_ = locate(true, canopen::kObjectTorqueOffset, 16, false, "torque offset");
    torque_demand_at_ = locate(false, canopen::kObjectTorqueDemand, 16, false, "torque demand");
    load_position_at_ = layout_.input_offset(canopen::kObjectAdditionalPositionActual, 1);
    load_acceleration_at_ = locate(false, canopen::kObjectLoadAcceleration, 32, false, "load acceleration");
    for (const canopen::PdoMapEntry& e : layout_.inputs) {
      if (e.index == canopen::kObjectAdditionalPositionActual && e.subindex == 1 && e.bit_length != 32) {
        throw Cia402DriveError(name + ": 0x60E4:1 (additional position actual value) is mapped with " +
                               std::to_string(e.bit_length) + " bits, not 32");
      }
    }
    command_tick_at_ = locate(true, canopen::kObjectCommandTick, 32, false, "command tick");
    statusword_at_ = locate(false, canopen::kObjectStatusword, 16, true, "statusword");
    torque_actual_at_ = locate(false, canopen::kObjectTorqueActual, 16, true, "torque actual value");
    velocity_actual_at_ = locate(false, canopen::kObjectVelocityActual, 32, true, "velocity actual value");
    position_actual_at_ = locate(false, canopen::kObjectPositionActual, 32, true, "position actual value");
    periods_at_ = locate(false, canopen::kObjectPeriodsStepped, 32, false, "periods stepped");
    if (!config_.realtime && !lockstep_contract()) {
      throw Cia402DriveError(name +
                             ": lockstep needs the command tick 0x2002 in its outputs and the periods stepped "
                             "0x2001 in its inputs (the virtual drive's contract); a drive without them runs "
                             "realtime only (--clock realtime)");
    }
    outputs_.assign(layout_.output_bytes, 0);
    inputs_.assign(layout_.input_bytes, 0);
    scratch_.assign(std::max(layout_.output_bytes, layout_.input_bytes), 0);
    const std::uint32_t displayed =
        sdo(false, canopen::kObjectModesOfOperationDisplay, 0, 0, 0, "modes of operation display");
    const auto mode_value = static_cast<std::int8_t>(static_cast<std::uint8_t>(displayed & 0xFFU));
    if (mode_value != config_.mode) {
      throw Cia402DriveError(name + ": 0x6061 (modes of operation display) is " + std::to_string(mode_value) +
                             " after 0x6060 = " + std::to_string(config_.mode) + ": the drive did not enter " +
                             canopen::mode_name(config_.mode));
    }
    if (config_.distributed_clocks) {
      // Every clock on the line, so the drive's delay from the reference is measured.
      const std::vector<DcSlave> line = master_.configure_distributed_clocks(stations, master_time_ns());
      if (std::none_of(line.begin(), line.end(), [&](const DcSlave& s) { return s.station == station; })) {
        throw Cia402DriveError(name +
                               ": no 64-bit distributed clock (set drive.distributed_clocks false for a "
                               "drive without one)");
      }
      line_delay_ns_ = line.back().delay_ns;
    }
    if (config_.sync0) {
      if (!config_.realtime) {
        throw Cia402DriveError(
            "drive.sync0: SYNC0 runs on the drive's clock, which a lockstep run does not "
            "follow: realtime only (--clock realtime)");
      }
      // ETG.1020: the sync mode and the cycle in PREOP, then SYNC0 on the grid of the drive's clock.
      sdo(true, kObjectOutputSyncParameters, kSyncParameterMode, kSyncModeDcSync0, 2, "SM2 sync mode, DC SYNC0");
      sdo(true, kObjectOutputSyncParameters, kSyncParameterCycleTime, static_cast<std::uint32_t>(kNsPerMs), 4,
          "SM2 cycle time");
      sdo(true, kObjectInputSyncParameters, kSyncParameterMode, kSyncModeDcSync0, 2, "SM3 sync mode, DC SYNC0");
      sync0_start_ns_ =
          master_.configure_sync0(station, kNsPerMs, static_cast<std::int64_t>(config_.sync0_shift_us) * 1000);
    }
    master_.configure_process_data_watchdog(
        station, config_.realtime ? static_cast<std::int64_t>(config_.watchdog_ms) * kNsPerMs : 0);
    walk_to(AlState::kSafeOp);
    booted_ = true;
    if (!read_inputs()) throw Cia402DriveError(name + ": its inputs could not be read in SAFEOP");
    // Valid outputs before OP (ETG.1000.6): the master's word and a command tick that steps nothing.
    if (!send_outputs(remote_.next_controlword(), still(), periods_ - 1U)) {
      throw Cia402DriveError(name + ": its outputs were not taken in SAFEOP");
    }
    walk_to(AlState::kOp);
  } catch (const std::invalid_argument& e) {
    throw Cia402DriveError(name + ": " + e.what());
  } catch (const Cia402DriveError&) {
    throw;
  } catch (const std::runtime_error& e) {
    throw Cia402DriveError(e.what());
  }
}

std::int64_t Cia402Drive::exchange_timeout_ns() const {
  return config_.realtime ? static_cast<std::int64_t>(config_.reply_deadline_us) * 1000
                          : static_cast<std::int64_t>(config_.cycle_timeout_ms) * kNsPerMs;
}

int Cia402Drive::exchange_retries() const { return config_.realtime ? 0 : static_cast<int>(config_.retries); }

Cia402Drive::Targets Cia402Drive::still() const {
  Targets t;
  t.position = position_actual_;
  return t;
}

bool Cia402Drive::send_outputs(std::uint16_t controlword, const Targets& targets, std::uint32_t command_tick) {
  std::uint8_t* out = outputs_.data();
  put_le16(out + controlword_at_, controlword);
  if (target_torque_at_ >= 0) put_le16(out + target_torque_at_, static_cast<std::uint16_t>(targets.torque));
  if (target_velocity_at_ >= 0) put_le32(out + target_velocity_at_, static_cast<std::uint32_t>(targets.velocity));
  if (target_position_at_ >= 0) put_le32(out + target_position_at_, static_cast<std::uint32_t>(targets.position));
  if (velocity_offset_at_ >= 0) {
    put_le32(out + velocity_offset_at_, static_cast<std::uint32_t>(targets.velocity_offset));
  }
  if (torque_offset_at_ >= 0) put_le16(out + torque_offset_at_, static_cast<std::uint16_t>(targets.torque_offset));
  if (command_tick_at_ >= 0) put_le32(out + command_tick_at_, command_tick);
  return send_outputs_again();
}

bool Cia402Drive::cycle_exchange(Command command, std::uint32_t address, std::uint16_t length) {
  // On the master's clock, the one the drive's distributed clock follows.
  const std::int64_t sent_ns = master_clock_();
  const Reply r =
      master_.exchange(command, address, scratch_.data(), length, exchange_timeout_ns(), exchange_retries());
  if (!r.answered) {
    ++counters_.frames_lost;
    return false;
  }
  const std::int64_t trip_ns = master_clock_() - sent_ns;
  round_trips_.record_latency_ns(trip_ns);
  // A frame's way to the drive, taken as half its way there and back (a running mean over ~16).
  transit_ns_ += (trip_ns / 2 - transit_ns_) / 16;
  if (r.working_counter != 1) {
    ++counters_.working_counter_errors;
    return false;
  }
  return true;
}

bool Cia402Drive::send_outputs_again() {
  ++counters_.cycles;
  std::copy(outputs_.begin(), outputs_.end(), scratch_.begin());
  return cycle_exchange(Command::kLwr, layout_.outputs_logical, layout_.output_bytes);
}

bool Cia402Drive::read_inputs() {
  if (!cycle_exchange(Command::kLrd, layout_.inputs_logical, layout_.input_bytes)) return false;
  std::copy(scratch_.begin(), scratch_.begin() + layout_.input_bytes, inputs_.begin());
  remote_.on_statusword(get_le16(inputs_.data() + statusword_at_));
  torque_actual_ = static_cast<std::int16_t>(get_le16(inputs_.data() + torque_actual_at_));
  if (torque_demand_at_ >= 0) torque_demand_ = static_cast<std::int16_t>(get_le16(inputs_.data() + torque_demand_at_));
  if (load_position_at_ >= 0) load_position_ = static_cast<std::int32_t>(get_le32(inputs_.data() + load_position_at_));
  if (load_acceleration_at_ >= 0) {
    load_acceleration_ = static_cast<std::int32_t>(get_le32(inputs_.data() + load_acceleration_at_));
  }
  velocity_actual_ = static_cast<std::int32_t>(get_le32(inputs_.data() + velocity_actual_at_));
  position_actual_ = static_cast<std::int32_t>(get_le32(inputs_.data() + position_actual_at_));
  if (periods_at_ >= 0) periods_ = get_le32(inputs_.data() + periods_at_);
  const std::optional<drive::PowerState> state = drive::decode_statusword(remote_.statusword());
  const bool faulted = state == drive::PowerState::kFaultReactionActive || state == drive::PowerState::kFault;
  if (faulted && !was_faulted_) read_error_code();
  was_faulted_ = faulted;
  return true;
}

void Cia402Drive::read_error_code() {
  // The drive entered fault: its 0x603F by one mailbox exchange (the force is already off); a CoE
  // emergency it posted comes out of the mailbox on the way and is named too.
  std::uint16_t code = 0;
  try {
    const SdoResult r = master_.sdo_upload(slave_, canopen::kObjectErrorCode, 0);
    if (r.done) code = static_cast<std::uint16_t>(r.value);
  } catch (const std::runtime_error&) {
    code = 0;  // the mailbox did not answer: the fault stands without its code
  }
  // Its emergency, read on the way to 0x603F's answer or by a cycle's look into the mailbox.
  const bool emergency = master_.emergencies() > emergencies_at_fault_check_;
  emergencies_at_fault_check_ = master_.emergencies();
  if (code == 0 && emergency) code = master_.last_emergency_code();
  char text[160];
  if (code != 0) {
    std::snprintf(text, sizeof text, "the drive faulted: %s0x603F = 0x%04X (%s)", emergency ? "CoE emergency, " : "",
                  code, canopen::describe_emcy(code));
  } else {
    std::snprintf(text, sizeof text, "the drive faulted (0x603F not read)");
  }
  remote_.on_drive_error(code, text);
}

void Cia402Drive::lose(const char* what) {
  if (remote_.lost()) return;
  char text[192];
  try {
    const StateResult state = master_.read_state(slave_.station_address);
    std::snprintf(text, sizeof text, "%s; the slave is in %s", what, state.describe().c_str());
  } catch (const std::runtime_error&) {
    std::snprintf(text, sizeof text, "%s; the slave does not answer (a cable pulled, the drive off)", what);
  }
  remote_.lose(text);
}

bool Cia402Drive::idle_cycle(std::uint16_t controlword) {
  for (std::uint32_t attempt = 0; attempt <= config_.cycle_retries; ++attempt) {
    if (send_outputs(controlword, still(), periods_ - 1U) && read_inputs()) return true;
  }
  return false;
}

void Cia402Drive::start() {
  if (!booted_) throw Cia402DriveError("start() before boot()");
  bool answered = false;
  for (std::uint32_t attempt = 0; attempt <= config_.cycle_retries && !answered; ++attempt) answered = read_inputs();
  if (!answered) {
    lose("no inputs at the start of the run");
    throw Cia402DriveError(std::string("the drive did not answer: ") + remote_.problem());
  }
  base_ = periods_;
  started_ = true;
  tick_ = 0;
  last_measurement_ = measurement();
}

void Cia402Drive::enable_and_wait() {
  if (!started_) start();
  for (;;) {
    const canopen::Cia402MasterOutput out = remote_.walk();
    if (out.status == canopen::Cia402MasterStatus::kOperationEnabled) break;
    if (out.status == canopen::Cia402MasterStatus::kFaultResetNeeded) {
      throw Cia402DriveError("the drive is in fault (" + std::string(remote_.problem()) + "): fault reset first");
    }
    if (out.timed_out) {
      throw Cia402DriveError(std::string("the drive never reached operation enabled: stuck in ") +
                             (out.stuck_in ? drive::to_string(*out.stuck_in) : "an invalid statusword") +
                             " (statusword " + format_hex(remote_.statusword(), 4) + ", controlword " +
                             format_hex(out.controlword, 4) + ") for " + std::to_string(config_.enable_timeout_cycles) +
                             " cycles");
    }
    if (config_.realtime) pace_cycle();
    if (!idle_cycle(out.controlword)) {
      lose("no answer during the enable walk");
      throw Cia402DriveError(std::string("the drive stopped answering during the enable walk: ") + remote_.problem());
    }
  }
  base_ = periods_;
  last_measurement_ = measurement();
}

bool Cia402Drive::release() {
  if (!booted_) return true;
  try {
    for (const AlState state : {AlState::kSafeOp, AlState::kInit}) {
      const StateResult r = master_.request_state(slave_.station_address, state);
      if (!r.reached) {
        const std::string text = std::string("release: not in ") + to_string(state) + ": " + r.describe();
        remote_.set_problem(text.c_str());
        return false;
      }
    }
  } catch (const std::runtime_error& e) {
    remote_.set_problem(e.what());
    return false;
  }
  booted_ = false;
  return true;
}

drive::Measurement Cia402Drive::measurement() const {
  drive::Measurement m = scaling_.measurement(position_actual_, velocity_actual_, torque_actual_);
  if (config_.mode != canopen::kModeCyclicSynchronousTorque) {
    // The drive's loops chose the force: its torque demand says which (torque actual: the current
    // loop's result, the nearest account a mapping without 0x6074 gives).
    m.applied_force_n = scaling_.per_mille_to_force(torque_demand_at_ >= 0 ? torque_demand_ : torque_actual_);
  }
  if (load_position_at_ >= 0) m.load_position_m = scaling_.increments_to_metres(load_position_);
  if (load_acceleration_at_ >= 0) {
    m.load_acceleration_mps2 = static_cast<double>(load_acceleration_) * canopen::kLoadAccelerationPerUnit;
  }
  return m;
}

LoadSensorKind Cia402Drive::load_sensor() const noexcept {
  if (load_position_at_ >= 0) return LoadSensorKind::kEncoder;
  if (load_acceleration_at_ >= 0) return LoadSensorKind::kAccelerometer;
  return LoadSensorKind::kNone;
}

drive::Measurement Cia402Drive::sample() {
  const std::uint64_t k = tick_++;
  // The run's ticks are on whole milliseconds of the master's clock from the first on.
  if (k == 0) tick0_ns_ = master_time_ns() / kNsPerMs * kNsPerMs;
  if (!booted_ || remote_.lost()) return last_measurement_;
  if (!started_) {
    base_ = periods_;
    started_ = true;
  }
  if (config_.realtime) {
    if (read_inputs()) {
      missed_in_row_ = 0;
    } else {
      ++counters_.missed_inputs;
      if (++missed_in_row_ >= config_.max_missed_cycles) {
        char text[96];
        std::snprintf(text, sizeof text, "no inputs for %u cycles in a row: drive lost", missed_in_row_);
        lose(text);
      }
    }
    last_measurement_ = measurement();
    return last_measurement_;
  }
  // Lockstep: the drive has stepped tick k-1's command when its periods stepped are base + k.
  const std::uint32_t expected = base_ + static_cast<std::uint32_t>(k);
  for (std::uint32_t attempt = 0;; ++attempt) {
    if (read_inputs() && periods_ == expected) break;
    if (attempt >= config_.cycle_retries) {
      char text[160];
      std::snprintf(text, sizeof text, "tick %llu not stepped after %u attempts (periods stepped %u, expected %u)",
                    static_cast<unsigned long long>(k), config_.cycle_retries + 1, periods_, expected);
      lose(text);
      return last_measurement_;
    }
    // The outputs of the tick before did not arrive (or not in OP): they go again; the command
    // tick keeps a second arrival from stepping twice.
    if (k > 0) {
      ++counters_.output_resends;
      send_outputs_again();
    }
  }
  last_measurement_ = measurement();
  return last_measurement_;
}

void Cia402Drive::apply(double force_n) {
  drive::Setpoint setpoint;
  setpoint.force_n = force_n;
  apply_setpoint(setpoint);
}

void Cia402Drive::apply_setpoint(const drive::Setpoint& setpoint) {
  if (!booted_) return;
  const bool enabled = power_state() == drive::PowerState::kOperationEnabled;
  const std::uint16_t controlword = remote_.next_controlword();
  if (remote_.lost()) return;
  // csp: the reference's motion from the drive's position at enable.
  if (enabled && !was_enabled_) {
    position_origin_m_ = scaling_.increments_to_metres(position_actual_) - setpoint.position_m;
  }
  was_enabled_ = enabled;
  Targets targets = still();
  if (enabled) {
    targets.torque = scaling_.force_to_per_mille(setpoint.force_n).value;
    targets.velocity = scaling_.velocity_to_increments(setpoint.velocity_mps).value;
    targets.position = scaling_.metres_to_increments(position_origin_m_ + setpoint.position_m).value;
    targets.velocity_offset = config_.mode == canopen::kModeCyclicSynchronousPosition ? targets.velocity : 0;
    targets.torque_offset = config_.mode == canopen::kModeCyclicSynchronousTorque
                                ? std::int16_t{0}
                                : scaling_.force_to_per_mille(setpoint.feedforward_force_n).value;
  }
  const std::uint64_t k = tick_ == 0 ? 0 : tick_ - 1;  // the tick sampled last
  const std::uint32_t command_tick = config_.realtime ? periods_ : base_ + static_cast<std::uint32_t>(k);
  send_outputs(controlword, targets, command_tick);
  // Sent after the pulse that was to take them: sync0_shift_us or more past their tick's start.
  if (sync0_start_ns_ != 0 && master_time_ns() >= tick0_ns_ + k * kNsPerMs + config_.sync0_shift_us * 1000ULL) {
    ++counters_.outputs_after_sync0;
  }
  if (config_.distributed_clocks) {
    ++counters_.dc_writes;
    // The reference's time as the frame reaches it: now plus its way there, half the round trip
    // less the line beyond it (the drive adds its own delay from the reference, 0x0928).
    const std::int64_t to_reference_ns = std::max<std::int64_t>(transit_ns_ - line_delay_ns_, 0);
    const Reply r = master_.write_system_time(slave_.station_address,
                                              master_time_ns() + static_cast<std::uint64_t>(to_reference_ns),
                                              exchange_timeout_ns(), exchange_retries());
    if (!r.answered || r.working_counter != 1) ++counters_.dc_writes_lost;
  }
  if (counters_.cycles % kMailboxPollCycles == 0) {
    ++counters_.mailbox_polls;
    master_.poll_emergency(slave_, exchange_timeout_ns(), exchange_retries());
  }
}

std::optional<std::int64_t> Cia402Drive::dc_difference_ns() {
  if (!config_.distributed_clocks || !booted_) return std::nullopt;
  try {
    return master_.read_system_time_difference(slave_.station_address);
  } catch (const std::runtime_error&) {
    return std::nullopt;
  }
}

}  // namespace pmlsm::ethercat
