#include "pmlsm/canopen/cia402_drive.hpp"

#include <cstdio>
#include <string>
#include <utility>

#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/cia402_application.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/pdo.hpp"

namespace pmlsm::canopen {

namespace {

constexpr std::int64_t kNsPerMs = 1000000;

std::string hex(std::uint32_t value, int digits) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%0*X", digits, value);
  return text;
}

}  // namespace

void Cia402DriveConfig::validate() const {
  RangeCheck check;
  canopen::visit_parameters(*this, check);
  check_relations();
}

void Cia402DriveConfig::check_relations() const {
  const auto bad = [](const char* key, const std::string& why) {
    throw std::invalid_argument(std::string(key) + ": " + why);
  };
  if (master_node_id == node_id) bad("master.node_id", "must differ from drive.node_id " + std::to_string(node_id));
  if (drive_heartbeat_ms > 0 && drive_heartbeat_timeout_ms <= drive_heartbeat_ms) {
    bad("master.drive_heartbeat_timeout_ms", "must exceed drive.heartbeat_ms " + std::to_string(drive_heartbeat_ms) +
                                                 ", got " + std::to_string(drive_heartbeat_timeout_ms));
  }
  if (master_heartbeat_timeout_ms <= master_heartbeat_ms) {
    bad("master.heartbeat_timeout_ms", "must exceed master.heartbeat_ms " + std::to_string(master_heartbeat_ms) +
                                           ", got " + std::to_string(master_heartbeat_timeout_ms));
  }
}

namespace {
const Cia402DriveConfig& validated(const Cia402DriveConfig& config) {
  config.validate();
  return config;
}
}  // namespace

Cia402Drive::Cia402Drive(const Cia402DriveConfig& config, can::CanBus& bus, Clock clock)
    : config_(validated(config)),
      bus_(bus),
      clock_(std::move(clock)),
      node_(config.node_id),
      master_node_(config.master_node_id),
      scaling_(config.scaling),
      remote_(config.enable_timeout_cycles),
      sdo_(node_, config.sdo_timeout_ms),
      sync_(config.sync_overflow) {
  if (!clock_) throw std::invalid_argument("clock: must be set");
  if (config_.drive_heartbeat_ms > 0) heartbeat_.emplace(node_, config_.drive_heartbeat_timeout_ms);
  next_master_heartbeat_ns_ = now_ns();
}

void Cia402Drive::send(const can::CanFrame& frame) { bus_.send(frame); }

namespace {
constexpr int kMaxQueuedFramesPerService = 64;
}  // namespace

bool Cia402Drive::service(std::int64_t timeout_ns) {
  const std::int64_t now = now_ns();
  if (now >= next_master_heartbeat_ns_) {
    send(encode_heartbeat(master_node_, NmtState::kOperational));
    next_master_heartbeat_ns_ = now + config_.master_heartbeat_ms * kNsPerMs;
  }
  // What queued while the loop was away (a lockstep tick waits on the controller, a busy host
  // holds the thread) is taken before the consumer judges the drive: its heartbeats are in
  // there. Bounded, so a flooded bus cannot hold the loop.
  can::CanFrame frame{};
  int queued = 0;
  while (queued < kMaxQueuedFramesPerService && bus_.receive(frame, std::chrono::nanoseconds(0))) {
    handle(frame);
    ++queued;
  }
  if (heartbeat_ && heartbeat_->poll(now_ms()) == HeartbeatEvent::kTimedOut) {
    lose("drive heartbeat lost");
  }
  if (queued > 0) return true;
  // Never wait past the next heartbeat we owe.
  std::int64_t wait = timeout_ns;
  if (wait > next_master_heartbeat_ns_ - now) wait = next_master_heartbeat_ns_ - now;
  if (wait < 0) wait = 0;
  if (!bus_.receive(frame, std::chrono::nanoseconds(wait))) return false;
  handle(frame);
  return true;
}

// The dispatch of every frame the master receives, one branch per CiA 301 service (SYNC, NMT, the
// drive's TPDO1/2, EMCY, heartbeat, SDO response), kept in one place so the order of the checks is visible.
// NOLINTNEXTLINE(readability-function-size)
void Cia402Drive::handle(const can::CanFrame& frame) {
  if (frame.rtr || frame.extended) return;
  // Our own SYNC and NMT frames are not received back (the bus filters its own sends), so
  // these came from another producer or master on the bus.
  if (frame.id == kCobIdSync) {
    ++counters_.foreign_syncs;
    return;
  }
  if (frame.id == kCobIdNmt) {
    ++counters_.foreign_nmt;
    return;
  }
  const CobIdInfo info = classify(frame.id);
  if (info.node_id != node_.value()) return;
  switch (info.function) {
    case FunctionCode::kRpdo1:
    case FunctionCode::kRpdo2:
    case FunctionCode::kRpdo3:
    case FunctionCode::kRpdo4:
      // Not ours (the bus does not give us our own frames back): a second master commands the
      // drive. Counted and reported; the drive decides what it takes.
      ++counters_.foreign_rpdos;
      return;
    case FunctionCode::kTpdo1:
      if (frame.dlc != 8) {
        ++counters_.malformed;
        return;
      }
      remote_.on_statusword(get_u16_le(frame.data, 0));
      torque_actual_ = static_cast<std::int16_t>(get_u16_le(frame.data, 2));
      velocity_actual_ = static_cast<std::int32_t>(get_u32_le(frame.data, 4));
      tpdo1_generation_ = generation_;
      break;
    case FunctionCode::kTpdo2:
      if (frame.dlc != 8) {
        ++counters_.malformed;
        return;
      }
      position_actual_ = static_cast<std::int32_t>(get_u32_le(frame.data, 0));
      tpdo2_periods_ = get_u32_le(frame.data, 4);
      periods_ = tpdo2_periods_;
      tpdo2_generation_ = generation_;
      break;
    case FunctionCode::kTpdo3:
      if (tpdo3_dlc_ == 0) return;  // no load sensor asked for: not ours to read
      if (frame.dlc != tpdo3_dlc_) {
        ++counters_.malformed;
        return;
      }
      load_reading_ = static_cast<std::int32_t>(get_u32_le(frame.data, tpdo3_offset_));
      tpdo3_generation_ = generation_;
      break;
    case FunctionCode::kEmcy: {
      const Result<EmcyMessage> emcy = decode_emcy(frame);
      if (!emcy) return;
      ++counters_.emcys;
      if (emcy.value.error_code != kEmcyNoError) {
        char text[96];
        std::snprintf(text, sizeof text, "EMCY 0x%04X (%s)", emcy.value.error_code,
                      describe_emcy(emcy.value.error_code));
        remote_.on_drive_error(emcy.value.error_code, text);
      }
      break;
    }
    case FunctionCode::kHeartbeat: {
      seen_ = true;
      const Result<HeartbeatMessage> hb = decode_heartbeat(frame);
      if (!hb) {
        ++counters_.malformed;
        break;
      }
      if (hb.value.boot_up()) boot_up_ = true;
      if (heartbeat_) heartbeat_->on_frame(frame, now_ms());
      if (started_ && hb.value.state != NmtState::kOperational && !remote_.lost()) {
        char text[96];
        std::snprintf(text, sizeof text, "the drive left NMT operational (heartbeat: %s)", to_string(hb.value.state));
        lose(text);
      }
      break;
    }
    case FunctionCode::kSdoTx: {
      const SdoClientEvent event = sdo_.on_frame(frame);
      if (event.kind != SdoClientEventKind::kNone) sdo_event_ = event;
      break;
    }
    default: break;
  }
}

void Cia402Drive::send_sync(bool resend) {
  if (!resend) last_sync_ = sync_.next();
  ++generation_;
  ++counters_.syncs;
  if (resend) ++counters_.sync_resends;
  send(last_sync_);
}

void Cia402Drive::send_rpdo(std::uint16_t controlword, std::int16_t torque, std::uint32_t tick) {
  can::CanFrame frame = make_frame(rpdo_cob_id(1, node_), 8);
  put_u16_le(frame.data, 0, controlword);
  put_u16_le(frame.data, 2, static_cast<std::uint16_t>(torque));
  put_u32_le(frame.data, 4, tick);
  last_rpdo_ = frame;
  rpdo_sent_ = true;
  send(frame);
}

bool Cia402Drive::wait_answer(std::optional<std::uint32_t> expected, std::int64_t deadline_ns) {
  for (;;) {
    const bool complete = tpdo1_generation_ == generation_ && tpdo2_generation_ == generation_ &&
                          (tpdo3_dlc_ == 0 || tpdo3_generation_ == generation_) &&
                          (!expected || tpdo2_periods_ == *expected);
    if (complete) return true;
    const std::int64_t left = deadline_ns - now_ns();
    if (left <= 0) return false;
    service(left);
    if (remote_.lost()) return false;
  }
}

void Cia402Drive::lose(const char* what) { remote_.lose(what); }

std::uint32_t Cia402Drive::sdo(bool write, std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                               std::uint8_t size, const char* name) {
  const std::string what = std::string("SDO ") + (write ? "write " : "read ") + hex(index, 4) + ":" +
                           hex(sub, 2).substr(2) + " (" + name + ")" +
                           (write ? " = " + std::to_string(value) : std::string());
  sdo_event_.reset();
  const Result<can::CanFrame> request =
      write ? sdo_.download(index, sub, SdoData{value, size}, now_ms()) : sdo_.upload(index, sub, now_ms());
  if (!request) throw Cia402DriveError(what + ": " + request.detail);
  send(request.value);
  for (;;) {
    if (sdo_event_) break;
    const SdoClientEvent timeout = sdo_.poll(now_ms());
    if (timeout.kind == SdoClientEventKind::kTimedOut) {
      if (timeout.send_abort) send(timeout.abort_frame);
      throw Cia402DriveError(what + ": no response from node " + std::to_string(node_.value()) + " within " +
                             std::to_string(config_.sdo_timeout_ms) + " ms");
    }
    service(kNsPerMs);
  }
  const SdoClientEvent event = *sdo_event_;
  sdo_event_.reset();
  switch (event.kind) {
    case SdoClientEventKind::kAborted:
      throw Cia402DriveError(what + ": aborted by the drive with " + hex(event.abort_code, 8) + " (" +
                             describe(event.abort_code) + ")");
    case SdoClientEventKind::kFailed:
      if (event.send_abort) send(event.abort_frame);
      throw Cia402DriveError(what + ": " + to_string(event.error) + ": " + event.detail);
    case SdoClientEventKind::kUploaded: return event.data.data;
    default: return 0;
  }
}

void Cia402Drive::boot() {
  // A drive that booted before the bridge (and whose heartbeat is off) answers a reset of its
  // communication with a fresh boot-up.
  if (config_.reset_communication) {
    seen_ = false;
    boot_up_ = false;
    send(encode_nmt(NmtCommand::kResetCommunication, node_));
  }
  // After our reset only its boot-up counts: a heartbeat sent before the reset may still be on
  // its way, and SDOs sent before the drive has reset would be lost in the reset.
  const std::int64_t deadline = now_ns() + config_.boot_timeout_ms * kNsPerMs;
  while (config_.reset_communication ? !boot_up_ : !seen_) {
    const std::int64_t left = deadline - now_ns();
    if (left <= 0) {
      throw Cia402DriveError(
          "drive node " + std::to_string(node_.value()) + ": no " +
          (config_.reset_communication ? "boot-up after NMT reset communication" : "boot-up or heartbeat") +
          " (COB-ID " + hex(heartbeat_cob_id(node_), 3) + ") within " + std::to_string(config_.boot_timeout_ms) +
          " ms on " + bus_.describe());
    }
    service(left);
  }
  sdo(true, kObjectModesOfOperation, 0, static_cast<std::uint8_t>(kModeCyclicSynchronousTorque), 1,
      "modes of operation, cyclic synchronous torque");
  sdo(true, kObjectInterpolationTimePeriod, 1, 1, 1, "interpolation time period value");
  sdo(true, kObjectInterpolationTimePeriod, 2, static_cast<std::uint8_t>(static_cast<std::int8_t>(-3)), 1,
      "interpolation time index");
  sdo(true, kObjectProducerHeartbeatTime, 0, config_.drive_heartbeat_ms, 2, "producer heartbeat time");
  sdo(true, kObjectConsumerHeartbeatTime, 1,
      consumer_heartbeat_entry(master_node_.value(), config_.master_heartbeat_timeout_ms), 4,
      "consumer heartbeat time");
  const std::uint32_t mode = sdo(false, kObjectModesOfOperationDisplay, 0, 0, 0, "modes of operation display");
  const auto mode_value = static_cast<std::int8_t>(static_cast<std::uint8_t>(mode & 0xFFU));
  if (mode_value != kModeCyclicSynchronousTorque) {
    throw Cia402DriveError("0x6061 (modes of operation display) is " + std::to_string(mode_value) +
                           " after 0x6060 = 10: the drive did not enter cyclic synchronous torque");
  }
  if (config_.load_sensor != LoadSensorKind::kNone) enable_load_sensor();
  send(encode_nmt(NmtCommand::kStart, node_));
}

void Cia402Drive::enable_load_sensor() {
  const bool encoder = config_.load_sensor == LoadSensorKind::kEncoder;
  const PdoMapEntry wanted =
      encoder ? PdoMapEntry{kObjectAdditionalPositionActual, 1, 32} : PdoMapEntry{kObjectLoadAcceleration, 0, 32};
  const std::string name = std::string("drive.load_sensor ") + to_string(config_.load_sensor) + ": ";
  const std::uint32_t count = sdo(false, kObjectTpdo3Mapping, 0, 0, 0, "TPDO3 mapping: number of entries");
  if (count > kPdoMaxEntries) throw Cia402DriveError(name + "0x1A02:00 holds " + std::to_string(count) + " entries");
  std::uint32_t bits = 0;
  std::string mapped;
  bool found = false;
  for (std::uint32_t i = 1; i <= count; ++i) {
    const PdoMapEntry e =
        decode_pdo_mapping(sdo(false, kObjectTpdo3Mapping, static_cast<std::uint8_t>(i), 0, 0, "TPDO3 mapping entry"));
    mapped += (mapped.empty() ? "" : ", ") + hex(e.index, 4) + ":" + std::to_string(e.subindex) + ":" +
              std::to_string(e.bit_length);
    if (e.index == wanted.index && e.subindex == wanted.subindex && e.bit_length == wanted.bit_length && !found) {
      found = true;
      tpdo3_offset_ = static_cast<std::uint8_t>(bits / 8);
    }
    bits += e.bit_length;
  }
  if (!found || bits % 8 != 0 || bits > kPdoMaxBits) {
    throw Cia402DriveError(name + "the drive's TPDO3 (0x1A02) does not map " + hex(wanted.index, 4) + ":" +
                           std::to_string(wanted.subindex) + ":32 (it maps " + (mapped.empty() ? "nothing" : mapped) +
                           ")");
  }
  tpdo3_dlc_ = static_cast<std::uint8_t>(bits / 8);
  // Valid, synchronous at every SYNC, on the node's TPDO3 id.
  sdo(true, kObjectTpdo3Communication, 2, kPdoTransmissionSyncEvery, 1, "TPDO3 transmission type");
  sdo(true, kObjectTpdo3Communication, 1, tpdo_cob_id(3, node_), 4, "TPDO3 COB-ID, valid");
}

bool Cia402Drive::idle_exchange(std::uint16_t controlword) {
  // A command tick one behind the drive's periods: the drive takes the controlword and does
  // not step.
  send_rpdo(controlword, 0, periods_ - 1U);
  for (std::uint32_t attempt = 0; attempt <= config_.sync_retries; ++attempt) {
    send_sync(attempt > 0);
    if (wait_answer(std::nullopt, now_ns() + config_.sync_timeout_ms * kNsPerMs)) return true;
    if (remote_.lost()) return false;
  }
  return false;
}

void Cia402Drive::start() {
  send_sync(false);
  bool answered = false;
  for (std::uint32_t attempt = 0; attempt <= config_.sync_retries && !answered; ++attempt) {
    if (attempt > 0) send_sync(true);
    answered = wait_answer(std::nullopt, now_ns() + config_.sync_timeout_ms * kNsPerMs);
    if (remote_.lost()) break;
  }
  if (!answered) {
    throw Cia402DriveError("drive node " + std::to_string(node_.value()) + ": no TPDO1 + TPDO2 (COB-IDs " +
                           hex(tpdo_cob_id(1, node_), 3) + ", " + hex(tpdo_cob_id(2, node_), 3) + ") after " +
                           std::to_string(config_.sync_retries + 1) + " SYNCs" +
                           (remote_.lost() ? std::string(": ") + remote_.problem() : std::string()));
  }
  // Hold the drive where it is: an RPDO1 it does not step on, with the master's word.
  send_rpdo(remote_.next_controlword(), 0, periods_ - 1U);
  base_ = periods_;
  started_ = true;
  tick_ = 0;
  last_measurement_ = measurement();
}

void Cia402Drive::enable_and_wait() {
  if (!started_) start();
  for (;;) {
    const Cia402MasterOutput out = remote_.walk();
    if (out.status == Cia402MasterStatus::kOperationEnabled) break;
    if (out.status == Cia402MasterStatus::kFaultResetNeeded) {
      throw Cia402DriveError("drive node " + std::to_string(node_.value()) + " is in fault (error code " +
                             hex(remote_.error_code(), 4) + "): fault reset first");
    }
    if (out.timed_out) {
      throw Cia402DriveError(
          "drive node " + std::to_string(node_.value()) + " never reached operation enabled: stuck in " +
          (out.stuck_in ? drive::to_string(*out.stuck_in) : "an invalid statusword") + " (statusword " +
          hex(remote_.statusword(), 4) + ", controlword " + hex(out.controlword, 4) + ") for " +
          std::to_string(config_.enable_timeout_cycles) + " cycles");
    }
    if (!idle_exchange(out.controlword)) {
      throw Cia402DriveError("drive node " + std::to_string(node_.value()) +
                             " stopped answering during the enable walk" +
                             (remote_.lost() ? std::string(": ") + remote_.problem() : std::string()));
    }
  }
  base_ = periods_;
  last_measurement_ = measurement();
}

drive::Measurement Cia402Drive::measurement() const {
  drive::Measurement m = scaling_.measurement(position_actual_, velocity_actual_, torque_actual_);
  if (config_.load_sensor == LoadSensorKind::kEncoder) m.load_position_m = scaling_.increments_to_metres(load_reading_);
  if (config_.load_sensor == LoadSensorKind::kAccelerometer) {
    m.load_acceleration_mps2 = static_cast<double>(load_reading_) * kLoadAccelerationPerUnit;
  }
  return m;
}

drive::Measurement Cia402Drive::sample() {
  if (!started_) {
    base_ = 0;
    started_ = true;
  }
  const std::uint64_t k = tick_++;
  if (remote_.lost()) {
    while (service(0)) {
    }
    return last_measurement_;
  }
  if (config_.realtime) {
    send_sync(false);
    if (wait_answer(std::nullopt, now_ns() + config_.tpdo_deadline_us * 1000LL)) {
      missed_in_row_ = 0;
    } else {
      ++counters_.tpdo_missing;
      if (++missed_in_row_ >= config_.max_missed_answers) {
        char text[96];
        std::snprintf(text, sizeof text, "no TPDOs for %u ticks in a row: drive lost", missed_in_row_);
        lose(text);
      }
    }
    last_measurement_ = measurement();
    return last_measurement_;
  }
  const std::uint32_t expected = base_ + static_cast<std::uint32_t>(k);
  send_sync(false);
  for (std::uint32_t attempt = 0;; ++attempt) {
    if (wait_answer(expected, now_ns() + config_.sync_timeout_ms * kNsPerMs)) break;
    if (remote_.lost()) return last_measurement_;
    if (attempt >= config_.sync_retries) {
      char text[160];
      std::snprintf(text, sizeof text, "no answer to the SYNC of tick %llu after %u resends: drive lost",
                    static_cast<unsigned long long>(k), config_.sync_retries);
      lose(text);
      return last_measurement_;
    }
    // The drive did not step: our RPDO1 of the last tick was lost. Send it again first.
    if (k > 0 && tpdo2_generation_ == generation_ && periods_ == expected - 1U && rpdo_sent_) {
      ++counters_.rpdo_resends;
      send(last_rpdo_);
    }
    send_sync(true);
  }
  while (service(0)) {  // EMCYs and heartbeats already queued
  }
  last_measurement_ = measurement();
  return last_measurement_;
}

void Cia402Drive::apply(double force_n) {
  const bool enabled = power_state() == drive::PowerState::kOperationEnabled;
  const std::uint16_t controlword = remote_.next_controlword();
  const std::int16_t torque = enabled ? scaling_.force_to_per_mille(force_n).value : std::int16_t{0};
  const std::uint64_t k = tick_ == 0 ? 0 : tick_ - 1;  // the tick sampled last
  const std::uint32_t command_tick = config_.realtime ? periods_ : base_ + static_cast<std::uint32_t>(k);
  send_rpdo(controlword, torque, command_tick);
}

drive::TransitionResult Cia402Drive::request(drive::DriveCommand command) { return remote_.request(command); }

void Cia402Drive::fault(std::uint16_t error_code) { remote_.fault(error_code); }

drive::PowerState Cia402Drive::power_state() const { return remote_.power_state(); }

}  // namespace pmlsm::canopen
