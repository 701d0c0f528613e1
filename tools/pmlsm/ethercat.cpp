// `pmlsm ethercat`: our EtherCAT master on an interface (raw Ethernet) or over UDP (EtherCAT over
// UDP, port 34980), and a virtual CiA 402 slave to try it (or another master) against:
//   pmlsm ethercat --interface eth1 scan                    # the slaves: identity, state, mailbox
//   pmlsm ethercat --interface eth1 state 0x1001 preop      # walk a slave's AL state
//   pmlsm ethercat --interface eth1 sdo read 0x1001 0x6061 0
//   pmlsm ethercat --interface eth1 sdo read 0x1001 0x1C12 0 --complete   # a record whole
//   pmlsm ethercat --interface eth1 sdo write 0x1001 0x6060 0 10 --size 1
//   pmlsm ethercat serve --udp-port 34980                   # a virtual slave (or --interface)
//   pmlsm ethercat serve --udp-port 34980 --drive           # ... driving the simulated motor
//   pmlsm ethercat pcap bus.pcapng --sdo                    # a capture decoded by our parsers
// Station addresses are assigned by position (0x1001 first) on every run, as a scan does.
// --capture FILE writes every frame the master sent and got back as pcapng (Wireshark reads it).
// Exit 0 done; 1 the bus or a slave did not answer, or refused (its AL status code named); 2 bad
// command line; 3 no slave on the bus; 5 serve --drive: the drive faulted while served.
#include <CLI/CLI.hpp>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "pmlsm/dds/shutdown.hpp"
#include "pmlsm/ethercat/capture.hpp"
#include "pmlsm/ethercat/coe_drive.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/ethercat/link.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/ethercat/master.hpp"
#include "pmlsm/ethercat/pcapng.hpp"
#include "pmlsm/ethercat/sii.hpp"
#include "pmlsm/config/canopen_config.hpp"
#include "pmlsm/config/config.hpp"
#include "pmlsm/sim/simulated_drive.hpp"
#include "pmlsm/util/clock.hpp"
#include "pmlsm/util/data_files.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm::tools {
namespace {

using namespace pmlsm::ethercat;

struct EthercatOptions {
  std::string interface;
  std::string udp;  ///< HOST:PORT
  std::string capture;
  std::string station;
  std::string state;
  std::string index;
  std::string subindex;
  std::string value;
  int size = 4;
  int udp_port = -1;  ///< serve: the UDP port (0: one the kernel picks)
  double seconds = 0;
  std::string sii;
  bool drive = false;     ///< serve: the CiA 402 drive over the simulated plant behind the slave
  std::string config;     ///< serve --drive: the system file
  std::string rig;        ///< serve --drive: the CANopen rig file whose scaling the drive takes
  std::string file;       ///< pcap: the capture
  bool sdo_list = false;  ///< pcap --sdo
  bool complete = false;  ///< sdo read --complete
};

std::uint32_t parse_number(const std::string& text, const char* what, std::uint32_t max) {
  try {
    std::size_t used = 0;
    const unsigned long value = std::stoul(text, &used, 0);
    if (used != text.size() || value > max) throw std::out_of_range(text);
    return static_cast<std::uint32_t>(value);
  } catch (const std::logic_error&) {
    throw UsageError(std::string("ethercat: ") + what + ": expected a number up to " + std::to_string(max) +
                     " (0x... for hex), got '" + text + "'");
  }
}

AlState parse_state(const std::string& text) {
  for (const AlState s : {AlState::kInit, AlState::kPreOp, AlState::kSafeOp, AlState::kOp}) {
    std::string name = to_string(s);
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (text == name || text == to_string(s)) return s;
  }
  throw UsageError("ethercat: state: expected init, preop, safeop or op, got '" + text + "'");
}

std::unique_ptr<Link> open_link(const EthercatOptions& o) {
  if (o.interface.empty() == o.udp.empty()) {
    throw UsageError("ethercat: give one of --interface IF (raw Ethernet) and --udp HOST:PORT (EtherCAT over UDP)");
  }
  try {
    if (!o.interface.empty()) return std::make_unique<RawSocketLink>(o.interface);
    const std::size_t colon = o.udp.rfind(':');
    if (colon == std::string::npos) throw UsageError("ethercat: --udp: expected HOST:PORT, got '" + o.udp + "'");
    UdpLinkParams p;
    p.local_address = "0.0.0.0";
    p.local_port = 0;
    p.peer_address = o.udp.substr(0, colon);
    p.peer_port = static_cast<std::uint16_t>(parse_number(o.udp.substr(colon + 1), "--udp port", 65535));
    return std::make_unique<UdpLink>(p);
  } catch (const std::system_error& e) {
    throw UsageError(e.what());
  }
}

/// The master on the link, capturing when asked, with the bus addressed by position.
struct Session {
  std::unique_ptr<Link> link;
  std::unique_ptr<PcapngWriter> capture;
  std::unique_ptr<Master> master;
  std::uint16_t slaves = 0;

  explicit Session(const EthercatOptions& o) : link(open_link(o)) {
    MasterParams params;
    params.state_timeout_ns = 2'000'000'000;
    master = std::make_unique<Master>(*link, params);
    if (!o.capture.empty()) {
      try {
        capture = std::make_unique<PcapngWriter>(o.capture);
      } catch (const std::runtime_error& e) {
        throw UsageError(std::string("ethercat: --capture: ") + e.what());
      }
      master->capture_to(capture.get());
    }
    slaves = master->count_slaves();
    if (slaves > 0) master->assign_station_addresses(slaves);
  }
  ~Session() {
    if (!capture) return;
    try {
      capture->flush();
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "ethercat: --capture: %s\n", e.what());
    }
    if (master->capture_failed())
      std::fprintf(stderr, "ethercat: --capture: a write failed; the capture stops there\n");
  }
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
};

int no_slaves() {
  std::fprintf(stderr, "ethercat: no slave answered on the bus\n");
  return kExitPeerMissing;
}

std::uint16_t station_of(const EthercatOptions& o, const Session& s) {
  const auto station = static_cast<std::uint16_t>(parse_number(o.station, "station", 0xFFFF));
  const auto first = MasterParams{}.first_station_address;
  if (station < first || station >= first + s.slaves) {
    throw UsageError("ethercat: station " + o.station + ": the bus has " + std::to_string(s.slaves) +
                     " slaves, addressed " + format_hex(first, 4) + " to " + format_hex(first + s.slaves - 1U, 4));
  }
  return station;
}

int run_scan(const EthercatOptions& o) {
  Session s(o);
  if (s.slaves == 0) return no_slaves();
  std::printf("%u slaves\n", s.slaves);
  std::printf("%-8s %-7s %-10s %-10s %-10s %-10s %-7s %-18s %s\n", "position", "station", "vendor", "product",
              "revision", "serial", "state", "mailbox", "name");
  for (std::uint16_t position = 0; position < s.slaves; ++position) {
    const auto station = static_cast<std::uint16_t>(MasterParams{}.first_station_address + position);
    const SlaveInfo info = s.master->read_slave_info(station);
    const StateResult state = s.master->read_state(station);
    char mailbox[64] = "none";
    if (info.mailbox_receive_size > 0) {
      std::snprintf(mailbox, sizeof mailbox, "%u/%u bytes%s", info.mailbox_receive_size, info.mailbox_send_size,
                    (info.mailbox_protocols & 0x0004) != 0 ? ", CoE" : "");
    }
    std::printf("%-8u 0x%04X  0x%08X 0x%08X 0x%08X 0x%08X %-7s %-18s %s\n", position, station, info.vendor_id,
                info.product_code, info.revision, info.serial, state.describe().c_str(), mailbox,
                info.name.empty() ? "-" : info.name.c_str());
  }
  return kExitOk;
}

int run_state(const EthercatOptions& o) {
  Session s(o);
  if (s.slaves == 0) return no_slaves();
  const std::uint16_t station = station_of(o, s);
  const AlState target = parse_state(o.state);
  const SlaveInfo info = s.master->read_slave_info(station);
  if (target != AlState::kInit && info.mailbox_receive_size > 0) s.master->configure_mailbox(info);
  // The standard's walk, one state at a time: INIT, PREOP, SAFEOP, OP (or down at once). Before
  // SAFEOP, the process data mapped as the slave's CoE objects say.
  const AlState order[] = {AlState::kInit, AlState::kPreOp, AlState::kSafeOp, AlState::kOp};
  StateResult r = s.master->read_state(station);
  for (const AlState step : order) {
    if (static_cast<int>(step) > static_cast<int>(target) && target != AlState::kInit) break;
    if (target == AlState::kInit && step != AlState::kInit) break;
    if (static_cast<int>(step) <= static_cast<int>(r.state) && step != target) continue;
    if (step == AlState::kSafeOp && (info.mailbox_protocols & 0x0004) != 0) {
      const ProcessDataLayout layout = s.master->map_process_data(info, 0x00010000);
      std::printf("0x%04X: process data %u bytes out, %u bytes in\n", station, layout.output_bytes, layout.input_bytes);
      for (const auto& [what, entries] :
           {std::make_pair("out", &layout.outputs), std::make_pair("in", &layout.inputs)}) {
        std::printf("  %-3s", what);
        for (const canopen::PdoMapEntry& e : *entries) std::printf(" 0x%04X:%u/%u", e.index, e.subindex, e.bit_length);
        std::printf("   (index:sub-index/bits, in order)\n");
      }
    }
    r = s.master->request_state(station, step);
    std::printf("0x%04X: %s\n", station, r.describe().c_str());
    if (!r.reached) return kExitError;
  }
  return kExitOk;
}

int run_sdo(const EthercatOptions& o, bool write) {
  Session s(o);
  if (s.slaves == 0) return no_slaves();
  const std::uint16_t station = station_of(o, s);
  const auto index = static_cast<std::uint16_t>(parse_number(o.index, "index", 0xFFFF));
  const auto subindex = static_cast<std::uint8_t>(parse_number(o.subindex, "subindex", 0xFF));
  const SlaveInfo info = s.master->read_slave_info(station);
  if (info.mailbox_receive_size == 0) throw UsageError("ethercat: slave " + o.station + " has no mailbox (no CoE)");
  if (s.master->read_state(station).state == AlState::kInit) {
    s.master->configure_mailbox(info);
    const StateResult preop = s.master->request_state(station, AlState::kPreOp);
    if (!preop.reached) {
      std::fprintf(stderr, "ethercat: 0x%04X: PREOP for the mailbox: %s\n", station, preop.describe().c_str());
      return kExitError;
    }
  }
  SdoResult r;
  if (write) {
    if (o.size < 1 || o.size > 4) throw UsageError("ethercat: --size: 1 to 4 bytes, got " + std::to_string(o.size));
    const std::uint32_t value = parse_number(o.value, "value", 0xFFFFFFFFU);
    r = s.master->sdo_download(info, index, subindex, value, static_cast<std::uint8_t>(o.size));
  } else {
    if (o.complete && (info.coe_details & kCoeDetailsCompleteAccess) == 0) {
      std::fprintf(stderr, "ethercat: slave %s does not offer complete access (its SII's CoE details: 0x%02X)\n",
                   o.station.c_str(), info.coe_details);
      return kExitError;
    }
    r = s.master->sdo_upload(info, index, subindex, o.complete);
  }
  std::printf("0x%04X 0x%04X:%u %s\n", station, index, subindex, write && r.done ? "written" : r.describe().c_str());
  return r.done ? kExitOk : kExitError;
}

std::vector<std::uint16_t> sii_from_file(const std::string& path) {
  try {
    return read_sii_image(path);
  } catch (const std::runtime_error& e) {
    throw UsageError(std::string("ethercat: --sii ") + e.what());
  }
}

/// The link `serve` answers on. @throws UsageError
std::unique_ptr<Link> serve_link(const EthercatOptions& o, const char* what) {
  try {
    if (!o.interface.empty()) {
      auto link = std::make_unique<RawSocketLink>(o.interface);
      std::printf("serving %s on %s\n", what, o.interface.c_str());
      return link;
    }
    if (o.udp_port >= 0) {
      auto udp = std::make_unique<UdpLink>(UdpLinkParams{"0.0.0.0", static_cast<std::uint16_t>(o.udp_port), "", 0});
      std::printf("serving %s on UDP port %u\n", what, udp->bound_port());
      return udp;
    }
  } catch (const std::system_error& e) {
    throw UsageError(e.what());
  }
  throw UsageError("ethercat serve: give --interface IF or --udp-port PORT");
}

/// Answers frames until a stop signal or --seconds; `between` after each frame and after each
/// wait without one. Returns the frames answered.
std::size_t serve_frames(const EthercatOptions& o, VirtualSegment& segment, Link& link,
                         const std::function<void()>& between) {
  std::fflush(stdout);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(o.seconds);
  std::size_t answered = 0;
  while (!dds::stop_requested() && (o.seconds <= 0 || std::chrono::steady_clock::now() < end)) {
    answered += segment.serve(link, 50'000'000, between);
    between();
  }
  return answered;
}

int run_serve_drive(const EthercatOptions& o) {
  const std::vector<std::uint16_t> sii = o.sii.empty() ? std::vector<std::uint16_t>{} : sii_from_file(o.sii);
  const SystemParams system = load_system_params(o.config.empty() ? data_file("configs/system.yaml") : o.config);
  canopen::Cia402ApplicationParams params;
  params.scaling = load_canopen_config(o.rig.empty() ? data_file("configs/canopen/drive.yaml") : o.rig).master.scaling;
  SimulatedDriveBackend simulated(system, PlantInitialCondition{});
  const std::int64_t start_ns = monotonic_ns();
  VirtualEthercatDrive drive(
      params, simulated,
      [&](bool error, const std::string& line, std::int64_t now_ns) {
        std::fprintf(error ? stderr : stdout, "drive: %s, %.3f s after start\n", line.c_str(),
                     static_cast<double>(now_ns - start_ns) * 1e-9);
      },
      sii);
  VirtualSegment segment({&drive.esc()}, [] { return monotonic_ns(); });
  const std::unique_ptr<Link> link = serve_link(o, "a virtual EtherCAT CiA 402 drive over the simulated motor");
  const std::size_t answered = serve_frames(o, segment, *link, [&] { drive.after_frame(monotonic_ns()); });
  const drive::Measurement m = simulated.sample();
  std::printf(
      "answered %zu frames; AL state %s; %llu periods stepped, %llu cycles outside OP; power state %s; "
      "%llu emergencies (last 0x%04X); motor at %.6f m\n",
      answered, to_string(drive.esc().al_state()), static_cast<unsigned long long>(drive.periods()),
      static_cast<unsigned long long>(drive.cycles_outside_op()), drive::to_string(simulated.power_state()),
      static_cast<unsigned long long>(drive.emergencies()), static_cast<unsigned>(drive.last_emergency()),
      m.position_m);
  if (simulated.fault_count() > 0) {
    std::fprintf(stderr, "ethercat serve: the drive faulted %llu time(s) while served: exit %d\n",
                 static_cast<unsigned long long>(simulated.fault_count()), kExitSafeState);
    return kExitSafeState;
  }
  return kExitOk;
}

int run_serve(const EthercatOptions& o) {
  if (o.drive) return run_serve_drive(o);
  VirtualCia402Slave slave(o.sii.empty() ? std::vector<std::uint16_t>{} : sii_from_file(o.sii));
  VirtualSegment segment({&slave.esc()}, [] { return monotonic_ns(); });
  const std::unique_ptr<Link> link = serve_link(o, "a virtual EtherCAT slave");
  const std::size_t answered = serve_frames(o, segment, *link, [&] { slave.exchange(); });
  std::printf("answered %zu frames; AL state %s; %llu SDO requests\n", answered, to_string(slave.esc().al_state()),
              static_cast<unsigned long long>(slave.coe().requests()));
  std::printf("outputs: controlword 0x%04llX, target torque %lld per mille (%llu refused)\n",
              static_cast<unsigned long long>(slave.dictionary().get_or(0x6040, 0, 0)),
              static_cast<long long>(slave.dictionary().get_or(0x6071, 0, 0)),
              static_cast<unsigned long long>(slave.process().refused_outputs()));
  return kExitOk;
}

/// A capture decoded by our parsers: what it holds, and (--sdo) each CoE SDO message. A malformed
/// file: exit 2, said; a malformed EtherCAT frame in it: counted and named, exit 1.
int run_pcap(const EthercatOptions& o) {
  std::optional<PcapngReader> reader;
  CaptureDecode d;
  try {
    reader.emplace(o.file);
    d = decode_capture(*reader);
  } catch (const std::runtime_error& e) {
    throw UsageError(std::string("ethercat pcap: ") + e.what());
  }
  std::printf(
      "%s: %llu frames: %llu EtherCAT (%llu over UDP, %llu of another type than datagrams), %llu other; %llu "
      "malformed\n",
      o.file.c_str(), static_cast<unsigned long long>(d.frames), static_cast<unsigned long long>(d.ethercat_frames),
      static_cast<unsigned long long>(d.over_udp), static_cast<unsigned long long>(d.other_types),
      static_cast<unsigned long long>(d.other_frames), static_cast<unsigned long long>(d.malformed_frames));
  std::printf("datagrams:");
  for (std::size_t c = 0; c < d.datagrams.size(); ++c) {
    if (d.datagrams[c] > 0) {
      std::printf(" %s %llu", to_string(static_cast<Command>(c)), static_cast<unsigned long long>(d.datagrams[c]));
    }
  }
  std::printf("\nCoE SDO messages: %zu\n", d.sdos.size());
  if (o.sdo_list) {
    for (const CaptureDecode::Sdo& s : d.sdos) {
      std::printf("  frame %llu  station 0x%04X  %s\n", static_cast<unsigned long long>(s.frame), s.seen.station,
                  describe(s.seen).c_str());
    }
  }
  if (d.malformed_frames > 0) {
    std::fprintf(stderr, "ethercat pcap: %llu malformed EtherCAT frames, the first frame %llu: %s\n",
                 static_cast<unsigned long long>(d.malformed_frames),
                 static_cast<unsigned long long>(d.first_malformed), to_string(d.first_error));
    return kExitError;
  }
  return kExitOk;
}

/// A set-up step's failure (no answer, a wrong working counter) as exit 1 with its message.
int guarded(int (*run)(const EthercatOptions&), const EthercatOptions& o) {
  try {
    return run(o);
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const UsageError*>(&e) != nullptr) throw;
    std::fprintf(stderr, "ethercat: %s\n", e.what());
    return kExitError;
  }
}

}  // namespace

void add_ethercat_command(CLI::App& app, int& exit_code) {
  CLI::App* cmd = app.add_subcommand("ethercat",
                                     "EtherCAT: scan the bus, walk a slave's state, read and write "
                                     "objects over CoE; serve a virtual CiA 402 slave; decode a capture");
  cmd->require_subcommand(1);
  auto o = std::make_shared<EthercatOptions>();
  cmd->add_option("--interface", o->interface, "Raw Ethernet on this interface (needs CAP_NET_RAW)");
  cmd->add_option("--udp", o->udp, "EtherCAT over UDP to HOST:PORT (a slave or `pmlsm ethercat serve`)");
  cmd->add_option("--capture", o->capture, "Write every frame sent and received to this pcapng file");
  const auto run = [o, &exit_code](int (*f)(const EthercatOptions&)) {
    return [o, f, &exit_code] { exit_code = guarded(f, *o); };
  };
  CLI::App* scan = cmd->add_subcommand("scan", "The slaves: position, station address, identity, AL state, mailbox");
  scan->callback(run(&run_scan));
  CLI::App* state = cmd->add_subcommand("state", "Walk a slave to an AL state: init, preop, safeop, op");
  state->add_option("station", o->station, "Its station address (0x1001 is the first slave)")->required();
  state->add_option("state", o->state, "init, preop, safeop or op")->required();
  state->callback(run(&run_state));
  CLI::App* sdo = cmd->add_subcommand("sdo", "An object of a slave's dictionary over CoE");
  sdo->require_subcommand(1);
  CLI::App* read = sdo->add_subcommand("read", "Read (SDO upload)");
  CLI::App* write = sdo->add_subcommand("write", "Write (SDO download)");
  for (CLI::App* sub : {read, write}) {
    sub->add_option("station", o->station, "Its station address (0x1001 is the first slave)")->required();
    sub->add_option("index", o->index, "The object's index (0x6060)")->required();
    sub->add_option("subindex", o->subindex, "Its sub-index")->required();
  }
  read->add_flag("--complete", o->complete,
                 "The whole record from the sub-index (0 or 1) on, by CoE's complete access (the slave's SII "
                 "offers it)");
  write->add_option("value", o->value, "The value")->required();
  write->add_option("--size", o->size, "Its size in bytes, 1 to 4")->capture_default_str();
  read->callback(run([](const EthercatOptions& opt) { return run_sdo(opt, false); }));
  write->callback(run([](const EthercatOptions& opt) { return run_sdo(opt, true); }));
  CLI::App* serve = cmd->add_subcommand(
      "serve", "A virtual EtherCAT slave (its registers, AL states, SII and a CiA 402 dictionary over CoE)");
  serve->add_option("--interface", o->interface, "Answer raw EtherCAT frames on this interface (CAP_NET_RAW)");
  serve->add_option("--udp-port", o->udp_port, "Answer EtherCAT over UDP on this port (0: any, printed)");
  serve->add_option("--seconds", o->seconds, "Stop after this long (default: at a stop signal)");
  serve->add_flag("--drive", o->drive,
                  "Behind the slave, the CiA 402 drive over the simulated motor (cyclic synchronous torque, one "
                  "period a process-data cycle in OP, the process-data watchdog)");
  serve->add_option("-c,--config", o->config, "--drive: the system file (default: the shipped one)");
  serve->add_option("--rig", o->rig,
                    "--drive: the rig file whose scaling (rated force, increments per metre) the drive takes "
                    "(default: the shipped configs/canopen/drive.yaml, as the CANopen drive)");
  serve->add_option("--sii", o->sii, "An SII EEPROM image to answer with (raw words, as a drive's dump)")
      ->check(CLI::ExistingFile);
  serve->callback(run(&run_serve));
  CLI::App* pcap = cmd->add_subcommand(
      "pcap", "Decode a pcapng capture with our parsers: its frames, datagrams, and the CoE SDO messages (--sdo)");
  pcap->add_option("file", o->file, "The capture (pcapng, as Wireshark, tshark or --capture write it)")
      ->required()
      ->check(CLI::ExistingFile);
  pcap->add_flag("--sdo", o->sdo_list, "List each CoE SDO message: frame, station, what it asks or answers");
  pcap->callback(run(&run_pcap));
}

}  // namespace pmlsm::tools
