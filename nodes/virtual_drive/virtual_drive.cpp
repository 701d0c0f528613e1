// virtual_drive: the rig in a box. The simulated drive (plant + current loop, configs/system.yaml
// and a scenario, as plant_sim) behind a CiA 402 slave on a CAN bus: UDP multicast in
// python-can's udp_multicast format (--can-group, --can-port, --can-iface) or SocketCAN
// (--can-interface NAME). Its control is CAN only; on DDS it publishes NodeStatus and, with
// --publish-truth (lockstep), PlantTruth for the evaluator (never read by a controller).
//
// CANopen (node id and the rest from configs/canopen/drive.yaml, the file drive_bridge reads):
//   - NMT slave: boot-up on start (pre-operational); start / stop / enter pre-operational /
//     reset node / reset communication honoured; heartbeat producer per 0x1017.
//   - SDO server (expedited) in pre-operational and operational.
//   - Dictionary: make_cia402_dictionary plus the device's part from --dictionary
//     (configs/canopen/virtual_drive_od.yaml, EDS-like: identity, 0x2001 "periods stepped" (u32
//     ro, mappable) and 0x2002 "command tick" (u32 rw, mappable), the PDOs' defaults), written
//     as a master would, with every check. The shipped PDOs, all synchronous (type 1):
//       RPDO1 0x200+id: 0x6040 controlword u16, 0x6071 target torque i16, 0x2002 command tick u32
//       TPDO1 0x180+id: 0x6041 statusword u16, 0x6077 torque actual i16, 0x606C velocity i32
//       TPDO2 0x280+id: 0x6064 position actual i32, 0x2001 periods stepped u32
//     The mappings can be changed over SDO (CiA 301's procedure) while pre-operational.
//   - PDOs only in operational. An RPDO1 is unpacked when it arrives; a controlword (RPDO1 or
//     an SDO write of 0x6040) is decoded with decode_controlword(previous) and requested from
//     the power state machine. Force only in operation enabled: target torque (per mille of
//     the rated force) -> newtons.
//
// Clocks:
//   lockstep (default): the SYNC is the clock. At a SYNC in operational: when an RPDO1 (or SDO
//     write of 0x2002) came since the last step and its command tick == periods stepped, one
//     period is integrated with its force and periods stepped grows by one; otherwise (a
//     repeated or early SYNC) nothing is integrated. The first SYNC answered only samples
//     (periods stepped 0: tick 0's feedback is the initial state). Then TPDO1 and TPDO2.
//     Ends after the scenario's ticks.
//   realtime: integrates on its own absolute 1 ms clock with the latest target torque; answers
//     each SYNC with the latest state. In operation enabled, no SYNC for sync_timeout_ms ->
//     fault 0x8700, no master heartbeat for the consumer time (0x1016.1) -> fault 0x8130 (both
//     counted from the later of the last one received and the entry into operation enabled).
//     Ends on SIGINT / SIGTERM.
//   --inject-fault-at-tick N: fault 0x5000 at period N.
//   PlantTruth (--publish-truth, lockstep): tick k is the state after the drive stepped k periods
//   since the run began, the run beginning at the first SYNC answered after NMT start (what the
//   master's start() learns as its base); the stamp's run id is the bridge's, from its latched
//   DriveState. Samples wait in a buffer sized for the scenario until the evaluator has matched
//   and the run id is known, so none is lost to discovery. Realtime has no PlantTruth: the
//   drive's own clock does not know the master's ticks.
//   A fault: PowerStateMachine::fault(code), force zero, EMCY with the code, a log line with the
//   time; cleared only by fault reset and enable via the controlword (EMCY 0x0000 on reset).
//
// Malformed frames (wrong DLC for the COB-ID, an unknown COB-ID, RTR / 29-bit frames, an
// undecodable NMT / SYNC / heartbeat) are counted and ignored.
//
// Exit codes: 0 ok; 2 bad config or command line; 1 runtime error (socket); 5 the drive faulted.
#include "pmlsm/util/data_files.hpp"
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cinttypes>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "DriveStatePubSubTypes.h"
#include "PlantTruthPubSubTypes.h"
#include "can_options.hpp"
#include "msg_mapping.hpp"
#include "node_support.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/canopen/sdo_server.hpp"
#include "pmlsm/canopen/sync.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/drive/power_state.hpp"
#include "pmlsm/sim/closed_loop.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "pmlsm/util/clock.hpp"
#include "pmlsm/util/exit_codes.hpp"

namespace {

using namespace pmlsm;
namespace co = pmlsm::canopen;
using co::CanFrame;

namespace pdds = pmlsm::dds;
namespace msg = pmlsm_msgs::msg;
namespace node_state = pmlsm_msgs::msg::NodeStatus_Constants;

// The lockstep contract's objects (configs/canopen/virtual_drive_od.yaml declares them).
constexpr std::uint16_t kObjectPeriodsStepped = 0x2001;
constexpr std::uint16_t kObjectCommandTick = 0x2002;
constexpr std::uint16_t kObjectTpdo2Communication = 0x1801;
constexpr std::uint16_t kObjectTpdo2Mapping = 0x1A01;
constexpr std::uint16_t kEmcySyncLost = 0x8700;  // CiA 301 monitoring: SYNC data length / lost
constexpr std::uint64_t kMalformedLogLimit = 20;

struct Options {
  node::CommonOptions common;
  node::CanOptions can;
  std::string dictionary_path = pmlsm::data_file("configs/canopen/virtual_drive_od.yaml");
  std::optional<std::uint64_t> inject_fault_at_tick;
  bool publish_truth = false;
};

/// PlantTruth of the lockstep periods, stamped with the bridge's run (its latched DriveState).
/// Held until the evaluator matched and the run id is known; the buffer is reserved for the
/// whole scenario at construction, so the tick loop never allocates.
class TruthPublisher {
 public:
  TruthPublisher(node::NodeRuntime& rt, std::uint64_t ticks)
      : rt_(rt),
        writer_(rt.participant.make_writer<msg::PlantTruthPubSubType>(pdds::topics::kPlantTruth)),
        state_reader_(rt.participant.make_reader<msg::DriveStatePubSubType>(pdds::topics::kDriveState, rt.wakeup)) {
    pending_.resize(ticks + 1);
  }

  /// The truth of tick `tick` (the drive's periods since the run began).
  void add(std::uint64_t tick, const SimulatedDrive& drive, double applied_force_n) {
    if (tick < published_ + queued_ || queued_ + published_ >= pending_.size()) {
      ++dropped_;  // a tick already held (a repeated answer) or beyond the scenario
      return;
    }
    msg::PlantTruth& t = pending_[queued_ + published_];
    node::to_msg(drive.plant().truth(), {applied_force_n, drive.last_u_d_v(), drive.last_u_q_v()}, t);
    t.stamp(node::make_stamp(tick, rt_.period_s, 0));
    ++queued_;
  }

  /// Sends what is held once it can be stamped and heard.
  void flush() {
    while (state_reader_.take(state_)) {
      if (state_.stamp().run_id() != 0) run_id_ = state_.stamp().run_id();
    }
    if (queued_ == 0 || run_id_ == 0 || writer_.matched_readers() == 0) return;
    for (; queued_ > 0; --queued_, ++published_) {
      msg::PlantTruth& t = pending_[published_];
      t.stamp().run_id(run_id_);
      writer_.write(t);
    }
  }

  /// At the end: waits up to `timeout` for what is held to go out, then for its acknowledgments.
  void finish(std::chrono::duration<double> timeout) {
    node::wait_until(rt_.wakeup, timeout, [&] {
      flush();
      return queued_ == 0;
    });
    if (queued_ > 0) {
      std::fprintf(stderr, "virtual_drive: %llu PlantTruth samples never sent (%s)\n",
                   static_cast<unsigned long long>(queued_),
                   run_id_ == 0 ? "no DriveState of the bridge: run id unknown" : "no PlantTruth reader");
    }
    writer_.wait_for_acknowledgments(node::kFlushTimeout);
  }

  std::uint64_t published() const { return published_; }
  std::uint64_t dropped() const { return dropped_; }

 private:
  node::NodeRuntime& rt_;
  pdds::Writer<msg::PlantTruthPubSubType> writer_;
  pdds::Reader<msg::DriveStatePubSubType> state_reader_;
  msg::DriveState state_;
  std::vector<msg::PlantTruth> pending_;
  std::uint64_t published_ = 0;
  std::uint64_t queued_ = 0;
  std::uint64_t dropped_ = 0;
  std::uint64_t run_id_ = 0;
};

/// The dictionary: CiA 301 / 402's objects (make_cia402_dictionary), then the device's own part
/// from its description (identity, manufacturer objects, the PDOs' defaults). `device` must outlive
/// the dictionary (the entries' names point into it). @throws ConfigError naming the object.
co::ObjectDictionary build_dictionary(co::NodeId node, const CanopenRigConfig& c, const DeviceDictionary& device,
                                      const co::UnitScaling& scaling, std::uint8_t interpolation_ms) {
  co::Cia402DictionaryConfig dc;
  dc.rated_torque = scaling.rated_torque_object();
  dc.producer_heartbeat_ms = c.master.drive_heartbeat_ms;
  dc.interpolation_period_ms = interpolation_ms;
  dc.vendor_id = device.vendor_id;
  dc.product_code = device.product_code;
  dc.revision_number = device.revision_number;
  dc.serial_number = device.serial_number;
  co::ObjectDictionary od = co::make_cia402_dictionary(node, dc);

  for (const DictionaryObject& obj : device.objects) {
    co::Entry e;
    e.index = obj.index;
    e.subindex = obj.subindex;
    e.name = obj.name.c_str();
    e.type = obj.type;
    e.access = obj.access;
    e.pdo_mappable = obj.pdo_mappable;
    e.value = obj.value;
    try {
      od.add(e);
    } catch (const std::invalid_argument& error) {
      throw ConfigError(std::string("device dictionary: ") + error.what());
    }
  }
  const auto must = [](co::Status s, const std::string& what) {
    if (!s) {
      char code[16];
      std::snprintf(code, sizeof code, "0x%08X", static_cast<unsigned>(s.abort_code));
      throw ConfigError("device dictionary: " + what + ": refused (" + s.detail + ", abort " + code + ")");
    }
  };
  must(od.set(co::kObjectConsumerHeartbeatTime, 1,
              co::consumer_heartbeat_entry(static_cast<std::uint8_t>(c.master.master_node_id),
                                           c.master.master_heartbeat_timeout_ms)),
       "0x1016.1");
  // TPDO2's communication and mapping entries, copied from TPDO1's (the same checks); invalid
  // and empty until the description configures them.
  static const char* const kTpdo2CommNames[6] = {"TPDO2 communication: highest sub-index", "TPDO2 COB-ID",
                                                 "TPDO2 transmission type", "TPDO2 inhibit time", "",
                                                 "TPDO2 event timer"};
  for (std::uint8_t sub : {0, 1, 2, 3, 5}) {
    const co::Entry* from = od.find(co::kObjectTpdo1Communication, sub);
    if (from == nullptr) throw std::logic_error("virtual_drive dictionary: 0x1800 lacks a sub-index");
    co::Entry copy = *from;
    copy.index = kObjectTpdo2Communication;
    copy.name = kTpdo2CommNames[sub];
    if (sub == 1) copy.value = co::tpdo_cob_id(2, node) | co::kPdoCobIdInvalid;
    od.add(copy);
  }
  for (std::uint8_t sub = 0; sub <= 8; ++sub) {
    const co::Entry* from = od.find(co::kObjectTpdo1Mapping, sub);
    if (from == nullptr) throw std::logic_error("virtual_drive dictionary: 0x1A00 lacks a sub-index");
    co::Entry copy = *from;
    copy.index = kObjectTpdo2Mapping;
    if (sub == 0) copy.name = "TPDO2 mapping: number of entries";
    copy.value = 0;
    od.add(copy);
  }
  // The PDOs' defaults as a master would write them (CiA 301's order, with every check): PDO
  // invalid, mapping count 0, the entries, the count, the transmission type, PDO valid.
  for (const PdoDefault& pdo : device.pdos) {
    const std::uint16_t comm = pdo.channel == "rpdo1"   ? co::kObjectRpdo1Communication
                               : pdo.channel == "tpdo1" ? co::kObjectTpdo1Communication
                                                        : kObjectTpdo2Communication;
    const auto map = static_cast<std::uint16_t>(comm + co::kPdoMappingOffset);
    const std::uint32_t cob = pdo.cob_id + (pdo.node_relative ? node.value() : 0U);
    const auto write = [&](std::uint16_t index, std::uint8_t sub, std::uint32_t value, const std::string& what) {
      must(od.write(index, sub, co::SdoData{value, 0}), pdo.channel + " " + what);
    };
    write(comm, 1, cob | co::kPdoCobIdInvalid, "COB-ID (invalid while remapped)");
    write(map, 0, 0, "mapping count 0");
    for (std::size_t i = 0; i < pdo.mapping.size(); ++i) {
      char entry[80];  // the longest: 20 digits of %zu, 4 hex digits, 3 + 3 decimals
      std::snprintf(entry, sizeof entry, "mapping entry %zu (0x%04X:%u:%u)", i + 1,
                    static_cast<unsigned>(pdo.mapping[i].index), static_cast<unsigned>(pdo.mapping[i].subindex),
                    static_cast<unsigned>(pdo.mapping[i].bit_length));
      write(map, static_cast<std::uint8_t>(i + 1), co::encode_pdo_mapping(pdo.mapping[i]), entry);
    }
    write(map, 0, static_cast<std::uint32_t>(pdo.mapping.size()), "mapping count");
    write(comm, 2, pdo.transmission_type, "transmission type");
    write(comm, 1, cob, "COB-ID");
  }
  for (std::uint16_t mapping : {co::kObjectRpdo1Mapping, co::kObjectTpdo1Mapping, kObjectTpdo2Mapping}) {
    const co::Result<co::PdoMap> pdo_map = co::read_pdo_map(od, mapping);
    if (!pdo_map) throw ConfigError("device dictionary: mapping invalid: " + std::string(pdo_map.detail));
  }
  return od;
}

struct PdoChannel {
  bool valid = false;
  std::uint32_t cob_id = 0;
  std::uint8_t transmission_type = 1;
  co::PdoMap map;
};

PdoChannel load_pdo(const co::ObjectDictionary& od, std::uint16_t communication_index) {
  PdoChannel ch;
  const co::Result<co::PdoCommunication> comm = co::read_pdo_communication(od, communication_index);
  const co::Result<co::PdoMap> map =
      co::read_pdo_map(od, static_cast<std::uint16_t>(communication_index + co::kPdoMappingOffset));
  if (!comm || !map) return ch;
  ch.valid = comm.value.valid && !map.value.empty();
  ch.cob_id = comm.value.cob_id;
  ch.transmission_type = comm.value.transmission_type;
  ch.map = map.value;
  return ch;
}

/// Intervals between SYNCs as they arrive (the master's tick jitter plus the bus): mean, standard
/// deviation, p99 (10 us buckets up to 10 ms) and max. Fixed storage: no allocation per SYNC.
class IntervalStatistics {
 public:
  void add(std::int64_t interval_ns) {
    const double us = static_cast<double>(interval_ns) * 1e-3;
    ++count_;
    sum_us_ += us;
    sum_sq_us_ += us * us;
    max_us_ = std::max(max_us_, us);
    const auto bucket = static_cast<std::size_t>(std::clamp(us / kBucketUs, 0.0, static_cast<double>(kBuckets - 1)));
    ++buckets_[bucket];
  }
  std::uint64_t count() const { return count_; }
  double mean_us() const { return count_ ? sum_us_ / static_cast<double>(count_) : 0.0; }
  double std_us() const {
    if (count_ < 2) return 0.0;
    const double m = mean_us();
    return std::sqrt(std::max(0.0, sum_sq_us_ / static_cast<double>(count_) - m * m));
  }
  double p99_us() const {
    const auto target = static_cast<std::uint64_t>(std::ceil(0.99 * static_cast<double>(count_)));
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBuckets; ++i) {
      seen += buckets_[i];
      if (seen >= target) return (static_cast<double>(i) + 1.0) * kBucketUs;
    }
    return max_us_;
  }
  double max_us() const { return max_us_; }

 private:
  static constexpr std::size_t kBuckets = 1000;
  static constexpr double kBucketUs = 10.0;
  std::array<std::uint64_t, kBuckets> buckets_{};
  std::uint64_t count_ = 0;
  double sum_us_ = 0, sum_sq_us_ = 0, max_us_ = 0;
};

class VirtualDrive {
 public:
  VirtualDrive(const Options& opt, node::NodeRuntime& rt, const CanopenRigConfig& config,
               const DeviceDictionary& device, can::CanBus& bus, TruthPublisher* truth)
      : opt_(opt),
        rt_(rt),
        config_(config),
        device_(device),
        bus_(bus),
        truth_(truth),
        realtime_(rt.cfg.clock == node::Clock::kRealtime),
        period_s_(rt.period_s),
        period_ns_(static_cast<std::int64_t>(std::llround(period_s_ * 1e9))),
        ticks_(scenario_ticks(rt.cfg.scenario, period_s_)),
        node_(config.master.node_id),
        scaling_(config.master.scaling),
        interpolation_ms_(interpolation_ms(period_s_)),
        od_(build_dictionary(node_, config_, device_, scaling_, interpolation_ms_)),
        sdo_(od_, node_),
        nmt_(node_),
        drive_(rt.cfg.params, scenario_initial_condition(rt.cfg.scenario)),
        motor_constant_n_per_a_(rt.cfg.params.plant.electrical.motor_constant_n_per_a) {
    power_.step();  // initialisation done: not ready to switch on -> switch on disabled
    feedback_ = drive_.sample();
    reload_pdos();
    update_objects();
  }

  int run();

 private:
  static std::uint8_t interpolation_ms(double period_s) {
    const double ms = period_s * 1e3;
    if (std::fabs(ms - std::round(ms)) > 1e-9 || ms < 1.0 || ms > 255.0) {
      throw ConfigError("timing.control_period_s " + std::to_string(period_s) +
                        ": the virtual drive needs a whole number of milliseconds in [1, 255] (0x60C2)");
    }
    return static_cast<std::uint8_t>(std::lround(ms));
  }
  static double seconds_since(std::int64_t start_ns, std::int64_t now_ns) {
    return static_cast<double>(now_ns - start_ns) * 1e-9;
  }

  void send(const CanFrame& f) {
    if (bus_.send(f)) {
      ++frames_out_;
    } else {
      ++send_failures_;
    }
  }
  void malformed(const CanFrame& f, const char* why) {
    ++malformed_;
    if (malformed_ <= kMalformedLogLimit) {
      std::fprintf(stderr, "virtual_drive: ignored malformed frame id 0x%03X dlc %u: %s%s\n",
                   static_cast<unsigned>(f.id), static_cast<unsigned>(f.dlc), why,
                   malformed_ == kMalformedLogLimit ? " (further ones only counted)" : "");
    }
  }

  void reload_pdos() {
    rpdo1_ = load_pdo(od_, co::kObjectRpdo1Communication);
    tpdo1_ = load_pdo(od_, co::kObjectTpdo1Communication);
    tpdo2_ = load_pdo(od_, kObjectTpdo2Communication);
  }

  std::optional<co::ConsumerHeartbeat> consumer() const {
    const auto entry = od_.get(co::kObjectConsumerHeartbeatTime, 1);
    if (!entry) return std::nullopt;
    const auto c = co::decode_consumer_heartbeat_entry(static_cast<std::uint32_t>(*entry));
    if (!c || c.value.time_ms == 0 || c.value.node_id == 0) return std::nullopt;
    return c.value;
  }

  double commanded_force() const {
    const auto per_mille = static_cast<std::int16_t>(od_.get_or(co::kObjectTargetTorque, 0, 0));
    return scaling_.per_mille_to_force(per_mille);
  }

  void update_objects() {
    const drive::PowerState s = power_.state();
    const bool faulted = s == drive::PowerState::kFault || s == drive::PowerState::kFaultReactionActive;
    od_.set(co::kObjectStatusword, 0, power_.statusword());
    od_.set(co::kObjectErrorCode, 0, power_.error_code());
    od_.set(co::kObjectErrorRegister, 0, faulted ? co::kErrorRegisterGeneric : 0);
    od_.set(co::kObjectModesOfOperationDisplay, 0, od_.get_or(co::kObjectModesOfOperation, 0, 0));
    od_.set(co::kObjectPositionActual, 0, scaling_.metres_to_increments(feedback_.encoder_position_m).value);
    od_.set(co::kObjectVelocityActual, 0, scaling_.velocity_to_increments(feedback_.velocity_mps).value);
    // Torque actual, as a drive measures it: the force its current loop produces, K_f i_q.
    od_.set(co::kObjectTorqueActual, 0, scaling_.force_to_per_mille(motor_constant_n_per_a_ * feedback_.i_q_a).value);
    od_.set(kObjectPeriodsStepped, 0, static_cast<std::int64_t>(periods_ & 0xFFFFFFFFULL));
  }

  void send_emcy(std::uint16_t code) {
    if (!co::sync_emcy_allowed(nmt_.state())) return;
    co::EmcyMessage m;
    m.error_code = code;
    m.error_register = static_cast<std::uint8_t>(od_.get_or(co::kObjectErrorRegister, 0, 0));
    send(co::encode_emcy(node_, m));
    ++emcys_;
  }

  void raise_fault(std::uint16_t code, const std::string& why, std::int64_t now_ns) {
    const std::uint64_t before = power_.fault_count();
    power_.fault(code);
    if (power_.fault_count() == before) return;  // already faulted: the first cause is kept
    update_objects();
    send_emcy(code);
    std::fprintf(stderr,
                 "virtual_drive: FAULT 0x%04X (%s): %s at period %" PRIu64 ", %.3f s after start [wall %.6f s]; "
                 "force off, EMCY sent\n",
                 static_cast<unsigned>(code), co::describe_emcy(code), why.c_str(), periods_,
                 seconds_since(start_ns_, now_ns), static_cast<double>(wall_time_ns()) * 1e-9);
  }

  void apply_controlword(std::int64_t now_ns) {
    const auto cw = static_cast<std::uint16_t>(od_.get_or(co::kObjectControlword, 0, 0));
    const std::optional<drive::DriveCommand> command = drive::decode_controlword(cw, previous_controlword_);
    const bool changed = cw != previous_controlword_;
    previous_controlword_ = cw;
    if (!command) return;
    const drive::TransitionResult r = power_.request(*command);
    if (r.accepted && r.to != r.from) {
      std::printf("virtual_drive: controlword 0x%04X (%s): %s -> %s%s [wall %.6f s]\n", static_cast<unsigned>(cw),
                  drive::to_string(*command), drive::to_string(r.from), drive::to_string(r.to),
                  power_.force_allowed() ? "" : ", zero force", static_cast<double>(wall_time_ns()) * 1e-9);
      if (r.to == drive::PowerState::kOperationEnabled) enabled_since_ns_ = now_ns;
    } else if (!r.accepted && changed) {
      std::printf("virtual_drive: controlword 0x%04X (%s) refused in %s: %s\n", static_cast<unsigned>(cw),
                  drive::to_string(*command), drive::to_string(r.from), r.reason);
    }
    const bool was_fault = r.from == drive::PowerState::kFault;
    update_objects();
    if (was_fault && r.accepted && r.to != r.from) send_emcy(co::kEmcyNoError);  // errors gone
  }

  void step_period(std::int64_t now_ns) {
    if (opt_.inject_fault_at_tick && periods_ == *opt_.inject_fault_at_tick && !injected_) {
      injected_ = true;
      raise_fault(co::kEmcyDeviceHardware, "injected (--inject-fault-at-tick)", now_ns);
    }
    applied_force_n_ = power_.force_allowed() ? commanded_force() : 0.0;
    drive_.apply_force(applied_force_n_);
    ++periods_;
    power_.step();
    feedback_ = drive_.sample();
    update_objects();
  }

  void send_tpdos() {
    ++tpdo_syncs_;
    for (const PdoChannel* ch : {&tpdo1_, &tpdo2_}) {
      if (!ch->valid || ch->transmission_type == 0) continue;
      if (tpdo_syncs_ % ch->transmission_type != 0) continue;
      const co::Result<CanFrame> f = co::pack_pdo(ch->map, od_, ch->cob_id);
      if (f) {
        send(f.value);
      } else {
        ++send_failures_;
      }
    }
  }

  void on_sync(std::int64_t now_ns) {
    ++syncs_;
    if (syncs_ > 1 && nmt_.pdo_allowed()) sync_intervals_.add(now_ns - last_sync_ns_);
    last_sync_ns_ = now_ns;
    if (!nmt_.pdo_allowed()) return;  // pre-operational: consumed, no PDOs
    if (!realtime_) {
      const auto tick = static_cast<std::uint64_t>(od_.get_or(kObjectCommandTick, 0, 0));
      if (!first_answered_) {
        first_answered_ = true;  // tick 0's feedback: the initial state; the run's base
        run_base_ = periods_;
        if (truth_ != nullptr) truth_->add(0, drive_, applied_force_n_);
      } else if (command_pending_ && tick == (periods_ & 0xFFFFFFFFULL)) {
        command_pending_ = false;
        step_period(now_ns);
        if (truth_ != nullptr) truth_->add(periods_ - run_base_, drive_, applied_force_n_);
      } else {
        ++unstepped_syncs_;
      }
    }
    send_tpdos();
    // Tick 0 is the initial state: a run of N ticks steps N - 1 periods.
    if (!realtime_ && first_answered_ && periods_ - run_base_ + 1 >= ticks_) finished_ = true;
  }

  void on_rpdo1(const CanFrame& f, std::int64_t now_ns) {
    const co::Status s = co::unpack_pdo(rpdo1_.map, od_, f);
    if (!s) {
      ++rejected_rpdos_;
      if (rejected_rpdos_ <= kMalformedLogLimit) {
        std::fprintf(stderr, "virtual_drive: RPDO1 refused: %s (abort 0x%08X)\n", s.detail,
                     static_cast<unsigned>(s.abort_code));
      }
      return;
    }
    ++rpdos_;
    bool controlword = false;
    for (const co::PdoMapEntry& e : rpdo1_.map) {
      if (e.index == co::kObjectControlword) controlword = true;
      if (e.index == kObjectCommandTick) command_pending_ = true;
    }
    if (controlword) apply_controlword(now_ns);
  }

  void on_sdo(const CanFrame& f, std::int64_t now_ns) {
    const co::SdoServerResult r = sdo_.handle(f);
    if (r.respond) send(r.response);
    ++sdo_requests_;
    if (!r.status || r.request.kind != co::SdoRequestKind::kDownload) return;
    const std::uint16_t index = r.request.index;
    if (index == co::kObjectControlword) apply_controlword(now_ns);
    if (index == kObjectCommandTick) command_pending_ = true;
    if (index >= co::kRpdoCommunicationFirst && index <= 0x1BFF) reload_pdos();
    if (index == co::kObjectModesOfOperation) update_objects();
  }

  void on_nmt(const CanFrame& f) {
    const co::Result<co::NmtTransition> r = nmt_.on_frame(f);
    if (!r) {
      malformed(f, r.detail);
      return;
    }
    if (!r.value.accepted) return;
    if (r.value.from != r.value.to) {
      std::printf("virtual_drive: NMT %s -> %s\n", co::to_string(r.value.from), co::to_string(r.value.to));
      // A master that starts the node begins a run: its first SYNC answered is the run's base.
      if (r.value.to == co::NmtState::kOperational) first_answered_ = false;
    }
    if (r.value.reset != co::NmtReset::kNone) reset(r.value.reset);
  }

  void reset(co::NmtReset kind) {
    co::ObjectDictionary fresh = build_dictionary(node_, config_, device_, scaling_, interpolation_ms_);
    for (const co::Entry& e : fresh) {
      if (kind == co::NmtReset::kNode || (e.index >= 0x1000 && e.index <= 0x1FFF)) od_.store(e, e.value);
    }
    if (kind == co::NmtReset::kNode) {
      command_pending_ = false;
      previous_controlword_ = 0;
    }
    reload_pdos();
    update_objects();  // the live values (statusword, actuals, periods stepped) stay what they are
    std::printf("virtual_drive: %s: dictionary reset, boot-up\n",
                kind == co::NmtReset::kNode ? "reset node" : "reset communication");
    if (const auto boot = nmt_.boot()) send(*boot);
  }

  void on_frame(const CanFrame& f, std::int64_t now_ns) {
    ++frames_in_;
    if (f.extended || f.rtr) {
      malformed(f, "29-bit or remote frame (CANopen here uses 11-bit data frames)");
      return;
    }
    const std::uint32_t id = f.id;
    if (id == co::kCobIdNmt) {
      on_nmt(f);
      return;
    }
    if (id == co::kCobIdSync) {
      const co::Result<co::SyncMessage> s = co::decode_sync(f);
      if (!s) {
        malformed(f, s.detail);
      } else if (co::sync_emcy_allowed(nmt_.state())) {
        on_sync(now_ns);
      }
      return;
    }
    if (rpdo1_.valid && id == rpdo1_.cob_id) {
      if (f.dlc != rpdo1_.map.byte_length()) {
        malformed(f, "RPDO1: DLC is not the mapping's length");
      } else if (nmt_.pdo_allowed()) {
        on_rpdo1(f, now_ns);
      } else {
        ++ignored_;
      }
      return;
    }
    if (id == co::sdo_rx_cob_id(node_)) {
      if (f.dlc != 8) malformed(f, "SDO request: DLC must be 8 (answered with an abort)");
      if (nmt_.sdo_allowed()) on_sdo(f, now_ns);
      return;
    }
    const auto watched = consumer();
    if (watched && id == co::kCobIdHeartbeatBase + watched->node_id) {
      const co::Result<co::HeartbeatMessage> hb = co::decode_heartbeat(f);
      if (!hb) {
        malformed(f, hb.detail);
      } else {
        last_master_heartbeat_ns_ = now_ns;
      }
      return;
    }
    const co::CobIdInfo info = co::classify(id);
    if (info.function == co::FunctionCode::kUnknown) {
      malformed(f, "unknown COB-ID");
      return;
    }
    const bool rpdo = info.function == co::FunctionCode::kRpdo1 || info.function == co::FunctionCode::kRpdo2 ||
                      info.function == co::FunctionCode::kRpdo3 || info.function == co::FunctionCode::kRpdo4;
    if (rpdo && info.node_id == node_.value() && id != co::rpdo_cob_id(1, node_)) {
      malformed(f, "an RPDO this node does not have");
      return;
    }
    ++ignored_;  // another node's traffic, or RPDO1 while not valid
  }

  void check_timeouts(std::int64_t now_ns) {
    if (power_.state() != drive::PowerState::kOperationEnabled) return;
    const std::int64_t sync_ref = std::max(last_sync_ns_, enabled_since_ns_);
    const std::int64_t sync_timeout_ns = static_cast<std::int64_t>(config_.drive_sync_timeout_ms) * 1000000;
    if (now_ns - sync_ref > sync_timeout_ns) {
      raise_fault(kEmcySyncLost, "no SYNC for " + std::to_string(config_.drive_sync_timeout_ms) + " ms", now_ns);
      return;
    }
    if (const auto watched = consumer()) {
      const std::int64_t hb_ref = std::max(last_master_heartbeat_ns_, enabled_since_ns_);
      if (now_ns - hb_ref > static_cast<std::int64_t>(watched->time_ms) * 1000000) {
        raise_fault(co::kEmcyHeartbeatError,
                    "no heartbeat of master node " + std::to_string(watched->node_id) + " for " +
                        std::to_string(watched->time_ms) + " ms",
                    now_ns);
      }
    }
  }

  const Options& opt_;
  node::NodeRuntime& rt_;
  CanopenRigConfig config_;
  DeviceDictionary device_;  // before od_: its entries' names point into it
  can::CanBus& bus_;
  TruthPublisher* truth_;
  bool realtime_;
  double period_s_;
  std::int64_t period_ns_;
  std::uint64_t ticks_;
  co::NodeId node_;
  co::UnitScaling scaling_;
  std::uint8_t interpolation_ms_;
  co::ObjectDictionary od_;
  co::SdoServer sdo_;
  co::NmtSlave nmt_;
  SimulatedDrive drive_;
  double motor_constant_n_per_a_;
  drive::PowerStateMachine power_;
  DriveFeedback feedback_;
  PdoChannel rpdo1_, tpdo1_, tpdo2_;
  IntervalStatistics sync_intervals_;

  double applied_force_n_ = 0.0;
  std::uint64_t periods_ = 0;
  std::uint64_t run_base_ = 0;
  std::uint16_t previous_controlword_ = 0;
  bool command_pending_ = false;
  bool first_answered_ = false;
  bool injected_ = false;
  bool finished_ = false;
  std::int64_t start_ns_ = 0;
  std::int64_t last_sync_ns_ = 0;
  std::int64_t last_master_heartbeat_ns_ = 0;
  std::int64_t enabled_since_ns_ = 0;

  std::uint64_t frames_in_ = 0, frames_out_ = 0, send_failures_ = 0, malformed_ = 0, ignored_ = 0;
  std::uint64_t syncs_ = 0, tpdo_syncs_ = 0, unstepped_syncs_ = 0, rpdos_ = 0, rejected_rpdos_ = 0;
  std::uint64_t sdo_requests_ = 0, emcys_ = 0, deadline_misses_ = 0;
};

int VirtualDrive::run() {
  start_ns_ = monotonic_ns();
  last_sync_ns_ = last_master_heartbeat_ns_ = enabled_since_ns_ = start_ns_;
  std::printf("virtual_drive: node %u on %s, %s clock, %s%" PRIu64 " ticks of %.3g ms (scenario), rated force %.6g N, "
              "%.6g increments/m\n",
              static_cast<unsigned>(node_.value()), bus_.describe().c_str(), realtime_ ? "realtime" : "lockstep",
              realtime_ ? "until SIGINT/SIGTERM, " : "", ticks_, period_s_ * 1e3, config_.master.scaling.rated_force_n,
              config_.master.scaling.increments_per_metre);
  rt_.status.publish(node_state::STATE_RUNNING, 0, period_s_, "on the CAN bus");
  if (const auto boot = nmt_.boot()) send(*boot);
  std::int64_t next_tick_ns = start_ns_ + period_ns_;
  CanFrame frame{};
  while (!pdds::stop_requested() && !finished_) {
    std::int64_t now = monotonic_ns();
    std::int64_t wait_ns = 2000000;  // lockstep: bounded, for heartbeats and signals
    if (realtime_) wait_ns = std::max<std::int64_t>(0, std::min<std::int64_t>(next_tick_ns - now, 1000000));
    if (bus_.receive(frame, std::chrono::nanoseconds(wait_ns))) {
      on_frame(frame, monotonic_ns());
      if (finished_) break;
    }
    now = monotonic_ns();
    if (realtime_ && now >= next_tick_ns) {
      // Absolute time: tick k is due at start + k T; a late loop catches up, a very late one
      // (over 100 periods) skips ahead and counts it.
      int steps = 0;
      while (now >= next_tick_ns && steps < 100) {
        step_period(now);
        check_timeouts(now);
        next_tick_ns += period_ns_;
        ++steps;
      }
      if (steps > 1) deadline_misses_ += static_cast<std::uint64_t>(steps - 1);
      if (now >= next_tick_ns) {
        const std::int64_t behind = (now - next_tick_ns) / period_ns_ + 1;
        deadline_misses_ += static_cast<std::uint64_t>(behind);
        next_tick_ns += behind * period_ns_;
      }
    }
    const auto hb_ms = static_cast<std::uint16_t>(od_.get_or(co::kObjectProducerHeartbeatTime, 0, 0));
    if (const auto hb = nmt_.poll_heartbeat(hb_ms, static_cast<std::uint64_t>(now / 1000000))) send(*hb);
    if (truth_ != nullptr) truth_->flush();
  }
  const can::CanBusCounters bus = bus_.counters();
  std::printf("virtual_drive: summary: periods stepped %" PRIu64 " of %" PRIu64 ", SYNCs %" PRIu64
              " (not stepped %" PRIu64 "), RPDOs %" PRIu64 " (refused %" PRIu64 "), SDO requests %" PRIu64
              ", frames in %" PRIu64 " out %" PRIu64 " (send failures %" PRIu64 "), malformed %" PRIu64
              " (bus-level %" PRIu64 "), ignored %" PRIu64 ", EMCYs %" PRIu64 ", faults %" PRIu64
              " (last error 0x%04X), deadline misses %" PRIu64 ", power state %s, NMT %s%s\n",
              periods_ - run_base_, realtime_ ? ticks_ : ticks_ - 1, syncs_, unstepped_syncs_, rpdos_, rejected_rpdos_, sdo_requests_, frames_in_,
              frames_out_, send_failures_, malformed_, bus.malformed_dropped, ignored_, emcys_, power_.fault_count(),
              static_cast<unsigned>(power_.error_code()), deadline_misses_, drive::to_string(power_.state()),
              co::to_string(nmt_.state()), pdds::stop_requested() ? ", stopped by signal" : "");
  if (sync_intervals_.count() > 0) {
    std::printf("virtual_drive: SYNC intervals at the drive over %llu SYNCs: mean %.1f us, std %.1f us, p99 %.0f us, "
                "max %.1f us\n",
                static_cast<unsigned long long>(sync_intervals_.count()), sync_intervals_.mean_us(),
                sync_intervals_.std_us(), sync_intervals_.p99_us(), sync_intervals_.max_us());
  }
  if (truth_ != nullptr) {
    truth_->finish(std::chrono::duration<double>(opt_.common.peer_timeout_s));
    std::printf("virtual_drive: PlantTruth: %llu ticks published, %llu repeated answers not published\n",
                static_cast<unsigned long long>(truth_->published()), static_cast<unsigned long long>(truth_->dropped()));
  }
  if (power_.fault_count() > 0) {
    std::fprintf(stderr, "virtual_drive: the drive faulted %" PRIu64 " time(s) during the run: exit 5\n",
                 power_.fault_count());
    rt_.status.publish(node_state::STATE_SAFE, periods_, period_s_, "the drive faulted during the run");
    return kExitSafeState;
  }
  rt_.status.publish(node_state::STATE_STOPPING, periods_, period_s_, "done");
  return kExitOk;
}

class VirtualDriveComponent final : public node::Component {
 public:
  VirtualDriveComponent(const node::ComponentContext& context, Options options)
      : opt_(std::move(options)),
        canopen_(node::load_canopen_config(opt_.can)),
        device_(load_device_dictionary(opt_.dictionary_path)),
        rt_("virtual_drive", opt_.common, context),
        truth_(make_truth()),
        bus_(node::open_can_bus(opt_.can)),
        drive_(opt_, rt_, canopen_, device_, *bus_, truth_ ? &*truth_ : nullptr) {}
  int run() override { return drive_.run(); }

 private:
  /// PlantTruth's publisher, after the checks against the runtime. @throws ConfigError
  std::optional<TruthPublisher> make_truth() {
    if (rt_.cfg.command_level == node::CommandLevel::kVoltage) {
      throw ConfigError("--command-level voltage: the virtual drive runs its own current loop (cyclic synchronous torque)");
    }
    if (opt_.publish_truth && rt_.cfg.clock == node::Clock::kRealtime) {
      // The drive's own clock does not know the master's ticks: no truth to stamp them with. The
      // evaluator (--truth optional) then reports what the bridge's topics give.
      std::printf("virtual_drive: --publish-truth: PlantTruth is published in lockstep only; realtime: none\n");
      return std::nullopt;
    }
    std::optional<TruthPublisher> truth;
    if (opt_.publish_truth) truth.emplace(rt_, scenario_ticks(rt_.cfg.scenario, rt_.period_s));
    return truth;
  }

  Options opt_;
  CanopenRigConfig canopen_;
  DeviceDictionary device_;
  node::NodeRuntime rt_;
  std::optional<TruthPublisher> truth_;
  std::unique_ptr<can::CanBus> bus_;
  VirtualDrive drive_;
};

}  // namespace

namespace pmlsm::node {

MadeComponent make_virtual_drive(const ComponentContext& context, int argc, char** argv) {
  CLI::App app{"virtual_drive: the simulated PMLSM drive behind a CiA 402 CANopen slave"};
  Options opt;
  add_common_options(app, opt.common);
  add_can_options(app, opt.can);
  app.add_option("--dictionary", opt.dictionary_path,
                 "the device's part of the object dictionary (identity, manufacturer objects, PDO defaults), EDS-like")
      ->capture_default_str();
  app.add_option("--inject-fault-at-tick", opt.inject_fault_at_tick,
                 "fault 0x5000 (device hardware) at this period; cleared by fault reset and enable");
  app.add_flag("--publish-truth", opt.publish_truth,
               "lockstep: publish PlantTruth on DDS (for the evaluator), stamped with the bridge's run (realtime: none)");
  if (const auto code = parse_command_line(app, argc, argv)) return {nullptr, *code};
  return {std::make_unique<VirtualDriveComponent>(context, std::move(opt))};
}

}  // namespace pmlsm::node
