#include "pmlsm/canopen/cia402_slave.hpp"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/sync.hpp"

namespace pmlsm::canopen {

namespace {
/// Malformed frames and refused RPDOs logged before they are only counted.
constexpr std::uint64_t kLogLimit = 20;
}  // namespace

std::string describe(const Cia402SlaveCounters& c) {
  char text[320];
  std::snprintf(text, sizeof text,
                "SYNCs %" PRIu64 " (not stepped %" PRIu64 "), RPDOs %" PRIu64 " (refused %" PRIu64
                "), SDO requests %" PRIu64 ", frames in %" PRIu64 " out %" PRIu64 " (send failures %" PRIu64
                "), malformed %" PRIu64 ", ignored %" PRIu64 ", EMCYs %" PRIu64,
                c.syncs, c.unstepped_syncs, c.rpdos, c.rejected_rpdos, c.sdo_requests, c.frames_in, c.frames_out,
                c.send_failures, c.malformed, c.ignored, c.emcys);
  return text;
}

void IntervalStatistics::add(std::int64_t interval_ns) {
  const double us = static_cast<double>(interval_ns) * 1e-3;
  ++count_;
  sum_us_ += us;
  sum_sq_us_ += us * us;
  max_us_ = std::max(max_us_, us);
  const auto bucket = static_cast<std::size_t>(std::clamp(us / kBucketUs, 0.0, static_cast<double>(kBuckets - 1)));
  ++buckets_[bucket];
}

double IntervalStatistics::mean_us() const { return count_ ? sum_us_ / static_cast<double>(count_) : 0.0; }

double IntervalStatistics::std_us() const {
  if (count_ < 2) return 0.0;
  const double m = mean_us();
  return std::sqrt(std::max(0.0, sum_sq_us_ / static_cast<double>(count_) - m * m));
}

double IntervalStatistics::p99_us() const {
  const auto target = static_cast<std::uint64_t>(std::ceil(0.99 * static_cast<double>(count_)));
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < kBuckets; ++i) {
    seen += buckets_[i];
    if (seen >= target) return (static_cast<double>(i) + 1.0) * kBucketUs;
  }
  return max_us_;
}

Cia402Slave::Cia402Slave(const Cia402SlaveParams& params, DictionaryFactory make_dictionary, drive::Drive& drive,
                         can::CanBus& bus, Cia402SlaveEvents& events)
    : params_(params),
      make_dictionary_(std::move(make_dictionary)),
      drive_(drive),
      bus_(bus),
      events_(events),
      od_(make_dictionary_()),
      application_({params.scaling, params.inject_fault_at_period, std::nullopt}, od_, drive, *this),
      sdo_(od_, params_.node),
      nmt_(params_.node) {
  reload_pdos();
}

Cia402Slave::PdoChannel Cia402Slave::load_pdo(const ObjectDictionary& od, std::uint16_t communication_index) {
  PdoChannel ch;
  const Result<PdoCommunication> comm = read_pdo_communication(od, communication_index);
  const Result<PdoMap> map = read_pdo_map(od, static_cast<std::uint16_t>(communication_index + kPdoMappingOffset));
  if (!comm || !map) return ch;
  ch.valid = comm.value.valid && !map.value.empty();
  ch.cob_id = comm.value.cob_id;
  ch.transmission_type = comm.value.transmission_type;
  ch.map = map.value;
  return ch;
}

void Cia402Slave::start(std::int64_t now_ns) {
  last_sync_ns_ = last_master_heartbeat_ns_ = now_ns;
  application_.set_enabled_since_ns(now_ns);
  if (const auto boot = nmt_.boot()) send(*boot);
}

void Cia402Slave::send(const CanFrame& f) {
  if (bus_.send(f)) {
    ++counters_.frames_out;
  } else {
    ++counters_.send_failures;
  }
}

void Cia402Slave::malformed(const CanFrame& f, const char* why, std::int64_t now_ns) {
  ++counters_.malformed;
  if (counters_.malformed > kLogLimit) return;
  char line[256];
  std::snprintf(line, sizeof line, "ignored malformed frame id 0x%03X dlc %u: %s%s", static_cast<unsigned>(f.id),
                static_cast<unsigned>(f.dlc), why,
                counters_.malformed == kLogLimit ? " (further ones only counted)" : "");
  events_.log(true, line, now_ns);
}

void Cia402Slave::reload_pdos() {
  rpdo1_ = load_pdo(od_, kObjectRpdo1Communication);
  tpdo1_ = load_pdo(od_, kObjectTpdo1Communication);
  tpdo2_ = load_pdo(od_, kObjectTpdo2Communication);
  tpdo3_ = load_pdo(od_, kObjectTpdo3Communication);
}

std::optional<ConsumerHeartbeat> Cia402Slave::consumer() const {
  const auto entry = od_.get(kObjectConsumerHeartbeatTime, 1);
  if (!entry) return std::nullopt;
  const auto c = decode_consumer_heartbeat_entry(static_cast<std::uint32_t>(*entry));
  if (!c || c.value.time_ms == 0 || c.value.node_id == 0) return std::nullopt;
  return c.value;
}

void Cia402Slave::emergency(std::uint16_t code) {
  if (!sync_emcy_allowed(nmt_.state())) return;
  EmcyMessage m;
  m.error_code = code;
  m.error_register = static_cast<std::uint8_t>(od_.get_or(kObjectErrorRegister, 0, 0));
  send(encode_emcy(params_.node, m));
  ++counters_.emcys;
}

void Cia402Slave::step_period(std::int64_t now_ns) { application_.step_period(now_ns); }

void Cia402Slave::send_tpdos() {
  ++tpdo_syncs_;
  for (const PdoChannel* ch : {&tpdo1_, &tpdo2_, &tpdo3_}) {
    if (!ch->valid || ch->transmission_type == 0) continue;
    if (tpdo_syncs_ % ch->transmission_type != 0) continue;
    const Result<CanFrame> f = pack_pdo(ch->map, od_, ch->cob_id);
    if (f) {
      send(f.value);
    } else {
      ++counters_.send_failures;
    }
  }
}

void Cia402Slave::on_sync(std::int64_t now_ns) {
  ++counters_.syncs;
  if (counters_.syncs > 1 && nmt_.pdo_allowed()) sync_intervals_.add(now_ns - last_sync_ns_);
  last_sync_ns_ = now_ns;
  if (!nmt_.pdo_allowed()) return;  // pre-operational: consumed, no PDOs
  if (params_.lockstep) {
    const auto tick = static_cast<std::uint64_t>(od_.get_or(kObjectCommandTick, 0, 0));
    if (!first_answered_) {
      first_answered_ = true;  // tick 0's feedback: the initial state; the run's base
      run_base_ = application_.periods();
      events_.run_tick(0, application_.applied_force_n());
    } else if (command_pending_ && tick == (application_.periods() & 0xFFFFFFFFULL)) {
      command_pending_ = false;
      step_period(now_ns);
      events_.run_tick(application_.periods() - run_base_, application_.applied_force_n());
    } else {
      ++counters_.unstepped_syncs;
    }
  }
  send_tpdos();
  // Tick 0 is the initial state: a run of N ticks steps N - 1 periods.
  if (params_.lockstep && params_.ticks > 0 && first_answered_ && run_periods() + 1 >= params_.ticks) {
    finished_ = true;
  }
}

void Cia402Slave::on_rpdo1(const CanFrame& f, std::int64_t now_ns) {
  const Status s = unpack_pdo(rpdo1_.map, od_, f);
  if (!s) {
    ++counters_.rejected_rpdos;
    if (counters_.rejected_rpdos <= kLogLimit) {
      char line[256];
      std::snprintf(line, sizeof line, "RPDO1 refused: %s (abort 0x%08X)", s.detail,
                    static_cast<unsigned>(s.abort_code));
      events_.log(true, line, now_ns);
    }
    return;
  }
  ++counters_.rpdos;
  bool controlword = false;
  for (const PdoMapEntry& e : rpdo1_.map) {
    if (e.index == kObjectControlword) controlword = true;
    if (e.index == kObjectCommandTick) command_pending_ = true;
  }
  if (controlword) application_.apply_controlword(now_ns);
}

void Cia402Slave::on_sdo(const CanFrame& f, std::int64_t now_ns) {
  const SdoServerResult r = sdo_.handle(f);
  if (r.respond) send(r.response);
  ++counters_.sdo_requests;
  if (!r.status || r.request.kind != SdoRequestKind::kDownload) return;
  const std::uint16_t index = r.request.index;
  if (index == kObjectControlword) application_.apply_controlword(now_ns);
  if (index == kObjectCommandTick) command_pending_ = true;
  if (index >= kRpdoCommunicationFirst && index <= 0x1BFF) reload_pdos();
  if (index == kObjectModesOfOperation) application_.update_objects();
}

void Cia402Slave::on_nmt(const CanFrame& f, std::int64_t now_ns) {
  const Result<NmtTransition> r = nmt_.on_frame(f);
  if (!r) {
    malformed(f, r.detail, now_ns);
    return;
  }
  if (!r.value.accepted) return;
  if (r.value.from != r.value.to) {
    events_.log(false, std::string("NMT ") + to_string(r.value.from) + " -> " + to_string(r.value.to), now_ns);
    // A master that starts the node begins a run: its first SYNC answered is the run's base.
    if (r.value.to == NmtState::kOperational) first_answered_ = false;
  }
  if (r.value.reset != NmtReset::kNone) reset(r.value.reset, now_ns);
}

void Cia402Slave::reset(NmtReset kind, std::int64_t now_ns) {
  const ObjectDictionary fresh = make_dictionary_();
  for (const Entry& e : fresh) {
    if (kind == NmtReset::kNode || (e.index >= 0x1000 && e.index <= 0x1FFF)) od_.store(e, e.value);
  }
  if (kind == NmtReset::kNode) {
    command_pending_ = false;
    application_.forget_controlword();
  }
  reload_pdos();
  application_.update_objects();  // the live values (statusword, actuals, periods stepped) stay what they are
  events_.log(
      false,
      std::string(kind == NmtReset::kNode ? "reset node" : "reset communication") + ": dictionary reset, boot-up",
      now_ns);
  if (const auto boot = nmt_.boot()) send(*boot);
}

void Cia402Slave::on_frame(const CanFrame& f, std::int64_t now_ns) {
  ++counters_.frames_in;
  if (f.extended || f.rtr) {
    malformed(f, "29-bit or remote frame (CANopen here uses 11-bit data frames)", now_ns);
    return;
  }
  const std::uint32_t id = f.id;
  if (id == kCobIdNmt) {
    on_nmt(f, now_ns);
    return;
  }
  if (id == kCobIdSync) {
    const Result<SyncMessage> s = decode_sync(f);
    if (!s) {
      malformed(f, s.detail, now_ns);
    } else if (sync_emcy_allowed(nmt_.state())) {
      on_sync(now_ns);
    }
    return;
  }
  if (rpdo1_.valid && id == rpdo1_.cob_id) {
    if (f.dlc != rpdo1_.map.byte_length()) {
      malformed(f, "RPDO1: DLC is not the mapping's length", now_ns);
    } else if (nmt_.pdo_allowed()) {
      on_rpdo1(f, now_ns);
    } else {
      ++counters_.ignored;
    }
    return;
  }
  if (id == sdo_rx_cob_id(params_.node)) {
    if (f.dlc != 8) malformed(f, "SDO request: DLC must be 8 (answered with an abort)", now_ns);
    if (nmt_.sdo_allowed()) on_sdo(f, now_ns);
    return;
  }
  const auto watched = consumer();
  if (watched && id == kCobIdHeartbeatBase + watched->node_id) {
    const Result<HeartbeatMessage> hb = decode_heartbeat(f);
    if (!hb) {
      malformed(f, hb.detail, now_ns);
    } else {
      last_master_heartbeat_ns_ = now_ns;
    }
    return;
  }
  const CobIdInfo info = classify(id);
  if (info.function == FunctionCode::kUnknown) {
    malformed(f, "unknown COB-ID", now_ns);
    return;
  }
  const bool rpdo = info.function == FunctionCode::kRpdo1 || info.function == FunctionCode::kRpdo2 ||
                    info.function == FunctionCode::kRpdo3 || info.function == FunctionCode::kRpdo4;
  if (rpdo && info.node_id == params_.node.value() && id != rpdo_cob_id(1, params_.node)) {
    malformed(f, "an RPDO this node does not have", now_ns);
    return;
  }
  ++counters_.ignored;  // another node's traffic, or RPDO1 while not valid
}

void Cia402Slave::check_timeouts(std::int64_t now_ns) {
  if (drive_.power_state() != drive::PowerState::kOperationEnabled) return;
  const std::int64_t sync_ref = std::max(last_sync_ns_, application_.enabled_since_ns());
  const std::int64_t sync_timeout_ns = static_cast<std::int64_t>(params_.sync_timeout_ms) * 1000000;
  if (now_ns - sync_ref > sync_timeout_ns) {
    application_.raise_fault(kEmcySyncLost, "no SYNC for " + std::to_string(params_.sync_timeout_ms) + " ms", now_ns);
    return;
  }
  if (const auto watched = consumer()) {
    const std::int64_t hb_ref = std::max(last_master_heartbeat_ns_, application_.enabled_since_ns());
    if (now_ns - hb_ref > static_cast<std::int64_t>(watched->time_ms) * 1000000) {
      application_.raise_fault(kEmcyHeartbeatError,
                               "no heartbeat of master node " + std::to_string(watched->node_id) + " for " +
                                   std::to_string(watched->time_ms) + " ms",
                               now_ns);
    }
  }
}

void Cia402Slave::poll(std::int64_t now_ns) {
  const auto hb_ms = static_cast<std::uint16_t>(od_.get_or(kObjectProducerHeartbeatTime, 0, 0));
  if (const auto hb = nmt_.poll_heartbeat(hb_ms, static_cast<std::uint64_t>(now_ns / 1000000))) send(*hb);
}

}  // namespace pmlsm::canopen
