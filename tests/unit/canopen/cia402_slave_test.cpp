// The slave (Cia402Slave, with the shipped configs/canopen files) against the master
// (Cia402Drive) on the in-memory bus with a fake clock: boot, start, the enable walk, lockstep
// periods, an injected fault, the realtime SYNC watch, an NMT reset, malformed frames.
#include "pmlsm/canopen/cia402_slave.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "memory_bus.hpp"
#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/cia402_drive.hpp"
#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/config/canopen_config.hpp"

namespace {

using namespace pmlsm;
using namespace pmlsm::canopen;
using can::CanFrame;
using canopen::test::FakeClock;
using canopen::test::MemoryBus;

std::string source(const std::string& relative) { return std::string(PMLSM_SOURCE_DIR) + "/" + relative; }

/// A drive backend as simple as can be checked by hand: a free mass, x'' = F / m, integrated
/// exactly over each period, behind the CiA 402 power state machine.
class FreeMass final : public drive::Drive {
 public:
  static constexpr double kMassKg = 10.0, kPeriodS = 1e-3;
  FreeMass() { power_.step(); }  // initialisation done: switch on disabled
  drive::Measurement sample() override {
    power_.step();
    drive::Measurement m;
    m.position_m = position_m;
    m.velocity_mps = velocity_mps;
    m.thrust_force_n = force_n;
    m.load_position_m = load_position_m;
    m.load_acceleration_mps2 = load_acceleration_mps2;
    return m;
  }
  void apply(double force_n_in) override {
    force_n = power_.force_allowed() ? force_n_in : 0.0;
    const double a = force_n / kMassKg;
    position_m += velocity_mps * kPeriodS + 0.5 * a * kPeriodS * kPeriodS;
    velocity_mps += a * kPeriodS;
    forces.push_back(force_n);
  }
  drive::TransitionResult request(drive::DriveCommand c) override { return power_.request(c); }
  void fault(std::uint16_t code) override { power_.fault(code); }
  drive::PowerState power_state() const override { return power_.state(); }
  std::uint16_t error_code() const override { return power_.error_code(); }
  std::uint64_t fault_count() const override { return power_.fault_count(); }
  bool simulated() const override { return true; }

  double position_m = 0, velocity_mps = 0, force_n = 0;
  /// A sensor on a load (NaN: none): what the drive measured of it.
  double load_position_m = std::numeric_limits<double>::quiet_NaN();
  double load_acceleration_mps2 = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> forces;  // what each applied period held

 private:
  drive::PowerStateMachine power_;
};

/// The slave's sends go to the master's inbox.
class ToMaster final : public can::CanBus {
 public:
  explicit ToMaster(MemoryBus& bus) : bus_(bus) {}
  bool send(const CanFrame& f) noexcept override {
    if (f.id == tpdo_cob_id(3, NodeId(1))) ++tpdo3_frames;
    bus_.inbox.push_back(f);
    return true;
  }
  int tpdo3_frames = 0;
  bool receive(CanFrame&, std::chrono::nanoseconds) noexcept override { return false; }

 private:
  MemoryBus& bus_;
};

struct Events final : Cia402SlaveEvents {
  void run_tick(std::uint64_t tick, double) override { ticks.push_back(tick); }
  void log(bool, const std::string& line, std::int64_t) override { lines.push_back(line); }
  bool logged(const std::string& part) const {
    for (const auto& l : lines) {
      if (l.find(part) != std::string::npos) return true;
    }
    return false;
  }
  std::vector<std::uint64_t> ticks;
  std::vector<std::string> lines;
};

struct Rig {
  explicit Rig(bool lockstep = true, std::optional<std::uint64_t> fault_at = std::nullopt)
      : rig(load_canopen_config(source("configs/canopen/drive.yaml"))),
        device(load_device_dictionary(source("configs/canopen/virtual_drive_od.yaml"))),
        slave(
            params(lockstep, fault_at), [this] { return build_device_dictionary(rig, device, 1e-3); }, mass, to_master,
            events) {
    bus.on_send = [this](const CanFrame& f) { slave.on_frame(f, clock.ns); };
    bus.on_idle = [this] { slave.poll(clock.ns); };
    slave.start(clock.ns);
  }
  Cia402SlaveParams params(bool lockstep, std::optional<std::uint64_t> fault_at) const {
    Cia402SlaveParams p;
    p.node = NodeId(rig.master.node_id);
    p.scaling = rig.master.scaling;
    p.lockstep = lockstep;
    p.sync_timeout_ms = 50;
    p.inject_fault_at_period = fault_at;
    return p;
  }
  /// The master through boot, start and the enable walk.
  Cia402Drive& enabled() {
    master = std::make_unique<Cia402Drive>(rig.master, bus, [this] { return clock.ns; });
    master->boot();
    master->start();
    master->enable_and_wait();
    return *master;
  }

  FakeClock clock;
  MemoryBus bus{clock};
  ToMaster to_master{bus};
  CanopenRigConfig rig;
  DeviceDictionary device;
  FreeMass mass;
  Events events;
  Cia402Slave slave;
  std::unique_ptr<Cia402Drive> master;
};

TEST(Cia402Slave, TheMasterBootsStartsAndEnablesIt) {
  Rig r;
  Cia402Drive& d = r.enabled();
  EXPECT_EQ(d.power_state(), drive::PowerState::kOperationEnabled);
  EXPECT_EQ(r.mass.power_state(), drive::PowerState::kOperationEnabled);
  EXPECT_EQ(r.slave.nmt_state(), NmtState::kOperational);
  EXPECT_TRUE(r.events.logged("-> operation enabled"));
  EXPECT_EQ(r.slave.run_periods(), 0U) << "the enable walk must not step";
  EXPECT_EQ(r.events.ticks, std::vector<std::uint64_t>{0}) << "tick 0 at the first SYNC after NMT start";
  EXPECT_EQ(r.slave.counters().malformed, 0U);
}

// A sensor on the load: the virtual drive's TPDO3 maps 0x60E4:1 and 0x2003 and is not valid until
// the master, told drive.load_sensor, checks its mapping and makes it valid; then every tick's
// answer carries the reading. Without one TPDO3 stays off the bus.
TEST(Cia402Slave, ALoadSensorIsReadInTpdo3WhenTheMasterAsksForIt) {
  {
    Rig r;
    r.mass.load_position_m = 0.0123;
    Cia402Drive& d = r.enabled();
    const drive::Measurement m = d.sample();
    EXPECT_TRUE(std::isnan(m.load_position_m)) << "none asked for";
    EXPECT_EQ(r.to_master.tpdo3_frames, 0);
  }
  for (const LoadSensorKind kind : {LoadSensorKind::kEncoder, LoadSensorKind::kAccelerometer}) {
    SCOPED_TRACE(to_string(kind));
    Rig r;
    r.rig.master.load_sensor = kind;
    Cia402Drive& d = r.enabled();
    d.sample();  // tick 0: the drive as it was at its start
    for (int k = 1; k <= 20; ++k) {
      // What the drive measures at the SYNC of tick k, where it steps the period and answers.
      r.mass.load_position_m = 0.0123 + 1e-5 * k;  // a load creeping 10 um a period
      r.mass.load_acceleration_mps2 = -3.25 + 0.5 * k;
      d.apply(0.0);
      const drive::Measurement m = d.sample();
      if (kind == LoadSensorKind::kEncoder) {
        EXPECT_NEAR(m.load_position_m, r.mass.load_position_m, 1e-6) << k;  // one increment
        EXPECT_TRUE(std::isnan(m.load_acceleration_mps2));
      } else {
        EXPECT_NEAR(m.load_acceleration_mps2, r.mass.load_acceleration_mps2, 1e-6) << k;  // 1 um/s^2
        EXPECT_TRUE(std::isnan(m.load_position_m));
      }
    }
    EXPECT_GE(r.to_master.tpdo3_frames, 20);
    EXPECT_EQ(d.counters().malformed, 0U);
  }
}

// A drive whose TPDO3 does not map what the rig file says it has: the boot says what it maps.
TEST(Cia402Slave, ALoadSensorTheDrivesTpdo3DoesNotMapIsRefusedAtBoot) {
  Rig r;
  r.rig.master.load_sensor = LoadSensorKind::kEncoder;
  // The master's boot resets the drive's communication: the dictionary is built again without it.
  auto& pdos = r.device.pdos;
  pdos.erase(std::remove_if(pdos.begin(), pdos.end(), [](const PdoDefault& p) { return p.channel == "tpdo3"; }),
             pdos.end());
  try {
    r.enabled();
    ADD_FAILURE() << "booted";
  } catch (const Cia402DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("drive.load_sensor encoder: the drive's TPDO3 (0x1A02) does not map "
                                         "0x60E4:1:32 (it maps nothing)"),
              std::string::npos)
        << e.what();
  }
}

TEST(Cia402Slave, EachLockstepTickStepsOnePeriodWithTheCommandedForce) {
  Rig r;
  Cia402Drive& d = r.enabled();
  const std::uint64_t walk_syncs = r.slave.counters().unstepped_syncs;  // the enable walk's: none steps
  for (int k = 0; k < 10; ++k) {
    const drive::Measurement m = d.sample();
    EXPECT_EQ(r.slave.run_periods(), static_cast<std::uint64_t>(k));
    // The master reads the mass's position through 0x6064 (1e6 increments per metre here).
    EXPECT_NEAR(m.position_m, r.mass.position_m, 1e-6);
    d.apply(100.0);
  }
  d.sample();
  EXPECT_EQ(r.slave.run_periods(), 10U);
  ASSERT_EQ(r.mass.forces.size(), 10U);
  // 100 N -> 148 per mille of the rated 675 N -> 99.9 N.
  for (double f : r.mass.forces) EXPECT_DOUBLE_EQ(f, 148 * 675.0 / 1000.0);
  EXPECT_EQ(r.events.ticks.size(), 11U);
  EXPECT_EQ(r.events.ticks.back(), 10U);
  // Every tick's SYNC stepped exactly once, but the first: no command was sent before it.
  EXPECT_EQ(r.slave.counters().unstepped_syncs, walk_syncs + 1);
  EXPECT_FALSE(d.lost());
}

TEST(Cia402Slave, AnInjectedFaultReachesTheMasterWithItsCodeAndZeroForce) {
  Rig r(true, 3);
  Cia402Drive& d = r.enabled();
  for (int k = 0; k < 6; ++k) {
    d.sample();
    d.apply(100.0);
  }
  d.sample();
  EXPECT_EQ(r.mass.power_state(), drive::PowerState::kFault);
  EXPECT_EQ(r.mass.error_code(), kEmcyDeviceHardware);
  EXPECT_EQ(d.error_code(), kEmcyDeviceHardware) << d.last_problem();
  EXPECT_EQ(r.slave.counters().emcys, 1U);
  EXPECT_TRUE(r.events.logged("FAULT 0x5000"));
  ASSERT_GE(r.mass.forces.size(), 4U);
  for (std::size_t k = 3; k < r.mass.forces.size(); ++k) EXPECT_EQ(r.mass.forces[k], 0.0) << "period " << k;
}

TEST(Cia402Slave, RealtimeWithoutSyncFaultsWith0x8700AfterTheTimeout) {
  Rig r(false);
  r.enabled();
  const std::int64_t last_sync = r.clock.ns;
  r.slave.on_frame(make_frame(kCobIdSync, 0), last_sync);  // the reference: a SYNC now
  r.clock.ns = last_sync + 49000000;
  r.slave.check_timeouts(r.clock.ns);
  EXPECT_EQ(r.mass.power_state(), drive::PowerState::kOperationEnabled)
      << "49 ms: inside the 50 ms; " << (r.events.lines.empty() ? "" : r.events.lines.back());
  r.clock.ns = last_sync + 51000000;
  r.bus.inbox.clear();
  r.slave.check_timeouts(r.clock.ns);
  EXPECT_EQ(r.mass.power_state(), drive::PowerState::kFaultReactionActive) << "fault at once, zero force";
  EXPECT_EQ(r.mass.fault_count(), 1U);
  EXPECT_EQ(r.mass.error_code(), kEmcySyncLost);
  r.slave.step_period(r.clock.ns);
  EXPECT_EQ(r.mass.power_state(), drive::PowerState::kFault) << "the reaction done at the next period";
  EXPECT_EQ(r.mass.forces.back(), 0.0);
  ASSERT_FALSE(r.bus.inbox.empty());
  EXPECT_EQ(r.bus.inbox.back().id, emcy_cob_id(NodeId(r.rig.master.node_id)));
  EXPECT_TRUE(r.events.logged("no SYNC for 50 ms"));
}

TEST(Cia402Slave, AResetNodeRestoresTheDictionaryAndBootsAgain) {
  Rig r;
  r.enabled();
  const std::uint16_t heartbeat_ms =
      static_cast<std::uint16_t>(r.slave.dictionary().get_or(kObjectProducerHeartbeatTime, 0, 0));
  r.bus.inbox.clear();
  r.slave.on_frame(encode_nmt(NmtCommand::kResetNode, NodeId(r.rig.master.node_id)), r.clock.ns);
  EXPECT_EQ(r.slave.nmt_state(), NmtState::kPreOperational);
  ASSERT_FALSE(r.bus.inbox.empty());
  EXPECT_EQ(r.bus.inbox.back().id, kCobIdHeartbeatBase + r.rig.master.node_id) << "the boot-up";
  EXPECT_EQ(r.bus.inbox.back().data[0], 0) << "boot-up byte";
  EXPECT_EQ(r.slave.dictionary().get_or(kObjectProducerHeartbeatTime, 0, 0), heartbeat_ms);
  EXPECT_TRUE(r.events.logged("reset node: dictionary reset, boot-up"));
}

TEST(Cia402Slave, MalformedFramesAreCountedAndIgnoredNeverThrown) {
  Rig r;
  r.enabled();
  const std::uint64_t before = r.slave.counters().malformed;
  CanFrame remote = make_frame(0x080, 0);
  remote.rtr = true;
  CanFrame short_rpdo = make_frame(rpdo_cob_id(1, NodeId(r.rig.master.node_id)), 2);
  CanFrame unknown = make_frame(0x7FF, 1);
  for (const CanFrame& f : {remote, short_rpdo, unknown}) r.slave.on_frame(f, r.clock.ns);
  EXPECT_EQ(r.slave.counters().malformed, before + 3);
  EXPECT_EQ(r.mass.power_state(), drive::PowerState::kOperationEnabled);
}

}  // namespace
