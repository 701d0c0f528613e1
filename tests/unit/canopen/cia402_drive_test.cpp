// Cia402Drive (the master backend) against a small in-test CiA 402 slave on an in-memory,
// single-threaded CAN bus with a fake clock: every exchange is deterministic.
#include "pmlsm/canopen/cia402_drive.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "memory_bus.hpp"
#include "pmlsm/canopen/bytes.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/sdo.hpp"
#include "pmlsm/canopen/sync.hpp"
#include "pmlsm/drive/power_state.hpp"

namespace {

using namespace pmlsm;
using namespace pmlsm::canopen;
using can::CanFrame;
using canopen::test::FakeClock;
using canopen::test::MemoryBus;

/// A CiA 402 slave after the bus contract (lockstep), with knobs to misbehave: aborts, lost
/// frames, a silent boot, ignored controlwords. The real slave (Cia402Slave) never does these;
/// it meets the master in cia402_slave_test.cpp.
class TestSlave {
 public:
  TestSlave(MemoryBus& bus, FakeClock& clock) : bus_(bus), clock_(clock), nmt_(NodeId(1)) {
    bus_.on_send = [this](const CanFrame& f) { on_frame(f); };
    bus_.on_idle = [this] { poll(); };
  }
  void boot() {
    power.step();  // not ready to switch on -> switch on disabled
    if (auto f = nmt_.boot()) bus_.inbox.push_back(*f);
    last_heartbeat_ms_ = now_ms();
  }
  void emcy(std::uint16_t code) {
    EmcyMessage m;
    m.error_code = code;
    m.error_register = kErrorRegisterGeneric;
    bus_.inbox.push_back(encode_emcy(NodeId(1), m));
  }

  drive::PowerStateMachine power;
  std::uint16_t abort_index = 0;
  std::uint32_t abort_code = 0;
  bool ignore_controlwords = false;
  bool heartbeat_on = true;
  bool answer_sync = true;
  bool silent_boot = false;  // no boot-up after a reset (a drive that is not there)
  int nmt_commands = 0;
  int drop_tpdo1 = 0;
  int drop_rpdo = 0;
  std::int8_t mode = 0;
  std::uint16_t producer_heartbeat_ms = 0;
  std::uint32_t consumer_heartbeat = 0;
  std::int8_t interpolation_index = 0;
  std::uint8_t interpolation_value = 0;
  std::uint32_t periods = 0;
  std::int32_t position = 0;
  std::vector<std::int16_t> stepped_torques;  // the torque each stepped period applied
  std::vector<std::uint16_t> controlwords;    // every RPDO1's controlword
  std::vector<std::uint32_t> command_ticks;   // every RPDO1's command tick
  NmtState nmt_state() const { return nmt_.state(); }

 private:
  std::uint64_t now_ms() const { return static_cast<std::uint64_t>(clock_.ns / 1000000); }
  void poll() {
    if (!heartbeat_on || nmt_.state() == NmtState::kInitialising) return;
    const std::uint64_t period = producer_heartbeat_ms ? producer_heartbeat_ms : 100;
    if (now_ms() >= last_heartbeat_ms_ + period) {
      bus_.inbox.push_back(encode_heartbeat(NodeId(1), nmt_.state()));
      last_heartbeat_ms_ = now_ms();
    }
  }
  void on_frame(const CanFrame& f) {
    if (f.id == 0x000) {
      const Result<NmtTransition> t = nmt_.on_frame(f);
      if (t && t.value.accepted && nmt_.state() == NmtState::kInitialising && !silent_boot) {
        if (auto boot_up = nmt_.boot()) bus_.inbox.push_back(*boot_up);
        last_heartbeat_ms_ = now_ms();
      }
      ++nmt_commands;
      return;
    }
    if (f.id == 0x601) {
      const Result<SdoRequest> r = parse_sdo_request(f);
      ASSERT_TRUE(r.ok());
      const SdoRequest& q = r.value;
      if (q.kind == SdoRequestKind::kDownload) {
        if (q.index == abort_index) {
          bus_.inbox.push_back(sdo_abort_response(NodeId(1), q.index, q.subindex, abort_code));
          return;
        }
        if (q.index == 0x6060) mode = static_cast<std::int8_t>(q.data.data);
        if (q.index == 0x60C2 && q.subindex == 1) interpolation_value = static_cast<std::uint8_t>(q.data.data);
        if (q.index == 0x60C2 && q.subindex == 2) interpolation_index = static_cast<std::int8_t>(q.data.data);
        if (q.index == 0x1017) producer_heartbeat_ms = static_cast<std::uint16_t>(q.data.data);
        if (q.index == 0x1016) consumer_heartbeat = q.data.data;
        bus_.inbox.push_back(sdo_download_response(NodeId(1), q.index, q.subindex));
      } else if (q.kind == SdoRequestKind::kUpload && q.index == 0x6061) {
        bus_.inbox.push_back(
            sdo_upload_response(NodeId(1), q.index, q.subindex, static_cast<std::uint8_t>(mode), 1).value);
      } else if (q.kind == SdoRequestKind::kUpload) {
        bus_.inbox.push_back(sdo_abort_response(NodeId(1), q.index, q.subindex, kAbortObjectMissing));
      }
      return;
    }
    if (!nmt_.pdo_allowed()) return;
    if (f.id == 0x201) {
      if (drop_rpdo > 0) {
        --drop_rpdo;
        return;
      }
      const std::uint16_t cw = get_u16_le(f.data, 0);
      controlwords.push_back(cw);
      if (!ignore_controlwords) {
        if (const auto command = drive::decode_controlword(cw, previous_cw_)) power.request(*command);
      }
      previous_cw_ = cw;
      torque_ = static_cast<std::int16_t>(get_u16_le(f.data, 2));
      command_tick_ = get_u32_le(f.data, 4);
      command_ticks.push_back(command_tick_);
      have_rpdo_ = true;
      return;
    }
    if (f.id == 0x080) {
      if (!answer_sync) return;
      if (have_rpdo_ && command_tick_ == periods) {
        const std::int16_t applied = power.force_allowed() ? torque_ : 0;
        stepped_torques.push_back(applied);
        position += applied;
        ++periods;
        power.step();
      }
      CanFrame t1 = make_frame(0x181, 8);
      put_u16_le(t1.data, 0, power.statusword());
      put_u16_le(t1.data, 2, static_cast<std::uint16_t>(power.force_allowed() ? torque_ : 0));
      put_u32_le(t1.data, 4, static_cast<std::uint32_t>(position * 10));
      CanFrame t2 = make_frame(0x281, 8);
      put_u32_le(t2.data, 0, static_cast<std::uint32_t>(position));
      put_u32_le(t2.data, 4, periods);
      if (drop_tpdo1 > 0) {
        --drop_tpdo1;
      } else {
        bus_.inbox.push_back(t1);
      }
      bus_.inbox.push_back(t2);
    }
  }

  MemoryBus& bus_;
  FakeClock& clock_;
  NmtSlave nmt_;
  std::uint64_t last_heartbeat_ms_ = 0;
  std::uint16_t previous_cw_ = 0;
  std::int16_t torque_ = 0;
  std::uint32_t command_tick_ = 0;
  bool have_rpdo_ = false;
};

struct Rig {
  FakeClock clock;
  MemoryBus bus{clock};
  TestSlave slave{bus, clock};
  Cia402DriveConfig config;
  std::unique_ptr<Cia402Drive> drive;
  Rig() { config.sync_retries = 3; }
  Cia402Drive& make() {
    drive = std::make_unique<Cia402Drive>(config, bus, [this] { return clock.ns; });
    return *drive;
  }
  std::vector<CanFrame> sent_without_heartbeats() const {
    std::vector<CanFrame> out;
    for (const CanFrame& f : bus.sent) {
      if (f.id != 0x77F) out.push_back(f);
    }
    return out;
  }
  /// Boot, start and enable: the drive in operation enabled, no period stepped.
  Cia402Drive& enabled() {
    Cia402Drive& d = make();
    slave.boot();
    d.boot();
    d.start();
    d.enable_and_wait();
    return d;
  }
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Cia402DriveError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Cia402Drive, BootSequenceFramesAndOrder) {
  Rig rig;
  Cia402Drive& d = rig.make();
  rig.slave.boot();
  d.boot();
  std::vector<CanFrame> sent = rig.sent_without_heartbeats();
  ASSERT_EQ(sent.size(), 8U);
  // First NMT reset communication to node 1: the drive answers with its boot-up.
  EXPECT_EQ(sent[0].id, 0x000U);
  EXPECT_EQ(sent[0].data[0], 0x82);
  EXPECT_EQ(sent[0].data[1], 1);
  sent.erase(sent.begin());
  const auto expect_sdo = [&](std::size_t i, std::uint8_t command, std::uint16_t index, std::uint8_t sub,
                              std::uint32_t data) {
    SCOPED_TRACE(i);
    EXPECT_EQ(sent[i].id, 0x601U);
    EXPECT_EQ(sent[i].data[0], command);
    EXPECT_EQ(get_u16_le(sent[i].data, 1), index);
    EXPECT_EQ(sent[i].data[3], sub);
    EXPECT_EQ(get_u32_le(sent[i].data, 4), data);
  };
  expect_sdo(0, 0x2F, 0x6060, 0, 10);
  expect_sdo(1, 0x2F, 0x60C2, 1, 1);
  expect_sdo(2, 0x2F, 0x60C2, 2, 0xFD);
  expect_sdo(3, 0x2B, 0x1017, 0, 100);
  expect_sdo(4, 0x23, 0x1016, 1, (127U << 16) | 350U);
  expect_sdo(5, 0x40, 0x6061, 0, 0);
  EXPECT_EQ(sent[6].id, 0x000U);
  EXPECT_EQ(sent[6].dlc, 2);
  EXPECT_EQ(sent[6].data[0], 0x01);  // start remote node
  EXPECT_EQ(sent[6].data[1], 1);
  EXPECT_EQ(rig.slave.nmt_state(), NmtState::kOperational);
  EXPECT_EQ(rig.slave.interpolation_index, -3);
  // The master's heartbeat: 0x77F, operational, from the start.
  const auto heartbeat =
      std::find_if(rig.bus.sent.begin(), rig.bus.sent.end(), [](const CanFrame& f) { return f.id == 0x77F; });
  ASSERT_NE(heartbeat, rig.bus.sent.end());
  EXPECT_EQ(heartbeat->dlc, 1);
  EXPECT_EQ(heartbeat->data[0], 0x05);
  EXPECT_LE(heartbeat - rig.bus.sent.begin(), 1);  // right after the reset, before any SDO
  EXPECT_FALSE(d.simulated());
}

TEST(Cia402Drive, MasterHeartbeatIsPeriodic) {
  Rig rig;
  rig.config.reset_communication = false;
  Cia402Drive& d = rig.make();
  // No drive on the bus: boot waits 5 s, producing the heartbeat every 100 ms meanwhile.
  const std::string error = error_of([&] { d.boot(); });
  EXPECT_NE(error.find("no boot-up or heartbeat"), std::string::npos) << error;
  EXPECT_NE(error.find("0x701"), std::string::npos) << error;
  std::size_t heartbeats = 0;
  for (const CanFrame& f : rig.bus.sent) heartbeats += f.id == 0x77F;
  EXPECT_GE(heartbeats, 50U);
  EXPECT_LE(heartbeats, 52U);
}

TEST(Cia402Drive, AlreadyBootedDriveIsFoundByTheReset) {
  Rig rig;
  rig.slave.boot();
  rig.bus.inbox.clear();  // its boot-up went out before the master was there
  Cia402Drive& d = rig.make();
  d.boot();
  EXPECT_EQ(rig.slave.nmt_state(), NmtState::kOperational);
}

TEST(Cia402Drive, SdoAbortDuringBootIsNamed) {
  Rig rig;
  rig.slave.abort_index = 0x6060;
  rig.slave.abort_code = kAbortValueRange;
  Cia402Drive& d = rig.make();
  rig.slave.boot();
  const std::string error = error_of([&] { d.boot(); });
  EXPECT_NE(error.find("0x6060"), std::string::npos) << error;
  EXPECT_NE(error.find("0x06090030"), std::string::npos) << error;
  EXPECT_NE(error.find("aborted"), std::string::npos) << error;
}

TEST(Cia402Drive, WrongModeDisplayIsAnError) {
  Rig rig;
  rig.slave.abort_index = 0x1234;  // nothing aborted
  Cia402Drive& d = rig.make();
  rig.slave.boot();
  // A drive that keeps its mode: 0x6060 accepted but 0x6061 shows the old one.
  rig.bus.on_send = [&, inner = rig.bus.on_send](const CanFrame& f) {
    inner(f);
    rig.slave.mode = 0;
  };
  const std::string error = error_of([&] { d.boot(); });
  EXPECT_NE(error.find("0x6061"), std::string::npos) << error;
}

TEST(Cia402Drive, EnableWalkControlwordsWithoutStepping) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  EXPECT_EQ(d.power_state(), drive::PowerState::kOperationEnabled);
  std::vector<std::uint16_t> distinct;
  for (std::uint16_t cw : rig.slave.controlwords) {
    if (distinct.empty() || distinct.back() != cw) distinct.push_back(cw);
  }
  EXPECT_EQ(distinct, (std::vector<std::uint16_t>{0x0000, 0x0006, 0x0007, 0x000F}));
  EXPECT_EQ(rig.slave.periods, 0U);  // the walk moved no plant period
  EXPECT_TRUE(rig.slave.stepped_torques.empty());
}

TEST(Cia402Drive, StuckStateTimesOutNamingIt) {
  Rig rig;
  rig.config.enable_timeout_cycles = 20;
  rig.slave.ignore_controlwords = true;
  Cia402Drive& d = rig.make();
  rig.slave.boot();
  d.boot();
  const std::string error = error_of([&] { d.enable_and_wait(); });
  EXPECT_NE(error.find("stuck in switch on disabled"), std::string::npos) << error;
}

TEST(Cia402Drive, LockstepSampleApplySteps) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  for (int k = 0; k < 10; ++k) {
    const drive::Measurement m = d.sample();
    EXPECT_EQ(rig.slave.periods, static_cast<std::uint32_t>(k));
    EXPECT_DOUBLE_EQ(m.position_m, rig.slave.position * 1e-6);
    d.apply(100.0);  // 100 N of 675 N: 148 per mille
    EXPECT_EQ(rig.slave.command_ticks.back(), static_cast<std::uint32_t>(k));
  }
  d.sample();
  EXPECT_EQ(rig.slave.periods, 10U);
  EXPECT_EQ(rig.slave.stepped_torques, std::vector<std::int16_t>(10, 148));
  EXPECT_EQ(d.counters().sync_resends, 0U);
  EXPECT_FALSE(d.lost());
}

TEST(Cia402Drive, LostTpdoIsRecoveredWithoutDoubleStep) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  for (int k = 0; k < 6; ++k) {
    if (k == 3) rig.slave.drop_tpdo1 = 1;  // the answer to tick 3's SYNC loses its TPDO1
    d.sample();
    EXPECT_EQ(rig.slave.periods, static_cast<std::uint32_t>(k)) << "tick " << k;
    d.apply(50.0);
  }
  EXPECT_EQ(d.counters().sync_resends, 1U);
  EXPECT_EQ(rig.slave.stepped_torques.size(), 5U);
  EXPECT_FALSE(d.lost());
}

TEST(Cia402Drive, LostRpdoIsResentBeforeTheSync) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  for (int k = 0; k < 6; ++k) {
    d.sample();
    EXPECT_EQ(rig.slave.periods, static_cast<std::uint32_t>(k)) << "tick " << k;
    if (k == 2) rig.slave.drop_rpdo = 1;  // tick 2's command never reaches the drive
    d.apply(50.0);
  }
  EXPECT_EQ(d.counters().rpdo_resends, 1U);
  EXPECT_EQ(d.counters().sync_resends, 1U);
  EXPECT_EQ(rig.slave.stepped_torques.size(), 5U);
}

TEST(Cia402Drive, SilentDriveIsLostNotAHang) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(10.0);
  rig.slave.answer_sync = false;
  d.sample();
  EXPECT_TRUE(d.lost());
  EXPECT_EQ(d.error_code(), 0x8130);
  EXPECT_EQ(d.power_state(), drive::PowerState::kFault);
  EXPECT_EQ(d.counters().sync_resends, 3U);
  EXPECT_EQ(d.counters().rpdo_resends, 0U);  // nothing answered: no sign the RPDO1 was lost
  d.apply(10.0);                             // force off: zero torque, quick stop
  EXPECT_EQ(rig.slave.controlwords.back(), 0x0002);
}

TEST(Cia402Drive, DriveHeartbeatLossFaults0x8130) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(10.0);
  EXPECT_FALSE(d.lost());
  rig.slave.heartbeat_on = false;
  rig.clock.ns += 1000000000;  // a second of silence
  d.sample();
  EXPECT_TRUE(d.lost());
  EXPECT_EQ(d.error_code(), 0x8130);
  EXPECT_EQ(d.power_state(), drive::PowerState::kFault);
  EXPECT_NE(std::string(d.last_problem()).find("heartbeat"), std::string::npos) << d.last_problem();
}

TEST(Cia402Drive, HeartbeatsQueuedWhileTheLoopWaitedAreNotALoss) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(10.0);
  // A lockstep tick that waited a second on the controller: the drive's heartbeats queued meanwhile.
  rig.slave.heartbeat_on = false;
  rig.bus.inbox.push_back(encode_heartbeat(NodeId(1), NmtState::kOperational));
  rig.clock.ns += 1000000000;
  d.sample();
  EXPECT_FALSE(d.lost()) << d.last_problem();
}

TEST(Cia402Drive, ADriveStoppedByAnotherMasterIsLost) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(10.0);
  EXPECT_FALSE(d.lost());
  rig.bus.inbox.push_back(encode_heartbeat(NodeId(1), NmtState::kStopped));  // after an NMT stop from elsewhere
  d.sample();
  EXPECT_TRUE(d.lost());
  EXPECT_EQ(d.error_code(), 0x8130);
  EXPECT_NE(std::string(d.last_problem()).find("left NMT operational (heartbeat: stopped)"), std::string::npos)
      << d.last_problem();
}

TEST(Cia402Drive, RealtimeMissingAnswersLoseTheDriveAfterTheLimitInARow) {
  Rig rig;
  rig.config.realtime = true;
  rig.config.max_missed_answers = 4;
  Cia402Drive& d = rig.enabled();
  rig.slave.answer_sync = false;
  for (int i = 0; i < 3; ++i) {
    d.sample();
    d.apply(0.0);
  }
  EXPECT_FALSE(d.lost()) << "three missed answers are counted, not yet a loss";
  rig.slave.answer_sync = true;
  d.sample();  // answered: the run of misses starts again
  d.apply(0.0);
  rig.slave.answer_sync = false;
  for (int i = 0; i < 3; ++i) {
    d.sample();
    d.apply(0.0);
  }
  EXPECT_FALSE(d.lost());
  d.sample();
  EXPECT_TRUE(d.lost());
  EXPECT_EQ(d.counters().tpdo_missing, 7U);
  EXPECT_NE(std::string(d.last_problem()).find("no TPDOs for 4 ticks in a row"), std::string::npos) << d.last_problem();
}

TEST(Cia402Drive, ForeignSyncNmtRpdoAndWrongLengthFramesAreCountedAndIgnored) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(0.0);
  // A second master commanding our drive (node 1): RPDO1 and RPDO3; node 2's RPDO is not ours.
  rig.bus.inbox.push_back(make_frame(0x201, 8));
  rig.bus.inbox.push_back(make_frame(0x401, 8));
  rig.bus.inbox.push_back(make_frame(0x202, 8));
  rig.bus.inbox.push_back(encode_sync());
  rig.bus.inbox.push_back(encode_nmt(NmtCommand::kEnterPreOperational, NodeId(2)));
  CanFrame short_tpdo = make_frame(0x181, 2);
  rig.bus.inbox.push_back(short_tpdo);
  d.sample();
  EXPECT_FALSE(d.lost());
  EXPECT_EQ(d.counters().foreign_syncs, 1U);
  EXPECT_EQ(d.counters().foreign_nmt, 1U);
  EXPECT_EQ(d.counters().foreign_rpdos, 2U);
  EXPECT_EQ(d.counters().malformed, 1U);
  EXPECT_EQ(d.power_state(), drive::PowerState::kOperationEnabled);
}

TEST(Cia402Drive, EmcySetsTheErrorCode) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(0.0);
  rig.slave.emcy(kEmcyContinuousOverCurrent);
  d.sample();
  EXPECT_EQ(d.error_code(), 0x2310);
  EXPECT_EQ(d.counters().emcys, 1U);
  EXPECT_NE(std::string(d.last_problem()).find("0x2310"), std::string::npos) << d.last_problem();
}

TEST(Cia402Drive, LoopFaultQuickStopsUntilFaultReset) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(100.0);
  d.fault(drive::kErrorCommandTimeout);
  EXPECT_EQ(d.power_state(), drive::PowerState::kFault);
  EXPECT_EQ(d.error_code(), 0x8130);
  EXPECT_EQ(d.fault_count(), 1U);
  d.sample();
  d.apply(100.0);
  EXPECT_EQ(rig.slave.controlwords.back(), 0x0002);  // quick stop
  EXPECT_EQ(rig.slave.stepped_torques.back(), 148);  // tick 0's, before the fault
  d.sample();
  d.apply(100.0);
  EXPECT_EQ(rig.slave.stepped_torques.back(), 0);  // force off
  EXPECT_FALSE(d.request(drive::DriveCommand::kEnableOperation).accepted);
  EXPECT_TRUE(d.request(drive::DriveCommand::kFaultReset).accepted);
  EXPECT_TRUE(d.request(drive::DriveCommand::kEnableOperation).accepted);
  for (int i = 0; i < 8 && d.power_state() != drive::PowerState::kOperationEnabled; ++i) {
    d.sample();
    d.apply(0.0);
  }
  EXPECT_EQ(d.power_state(), drive::PowerState::kOperationEnabled);
}

TEST(Cia402Drive, DriveFaultNeedsTheResetEdge) {
  Rig rig;
  Cia402Drive& d = rig.enabled();
  d.sample();
  d.apply(0.0);
  rig.slave.power.fault(0x2310);
  rig.slave.emcy(0x2310);
  for (int i = 0; i < 3; ++i) {
    d.sample();
    d.apply(0.0);
  }
  EXPECT_EQ(d.power_state(), drive::PowerState::kFault);
  EXPECT_EQ(d.error_code(), 0x2310);
  EXPECT_EQ(d.fault_count(), 1U);
  EXPECT_TRUE(d.request(drive::DriveCommand::kFaultReset).accepted);
  d.sample();
  d.apply(0.0);
  EXPECT_EQ(rig.slave.controlwords.back() & 0x80, 0x80);  // the rising edge
  d.sample();
  EXPECT_EQ(d.power_state(), drive::PowerState::kSwitchOnDisabled);
}

TEST(Cia402Drive, OperatorWalkOneStateAtATime) {
  // `pmlsm drive enable` sends shutdown, switch on, enable operation, each when the last
  // state arrived; disable operation goes back to switched on.
  Rig rig;
  Cia402Drive& d = rig.make();
  rig.slave.boot();
  d.boot();
  d.start();
  const auto run_until = [&](drive::PowerState state) {
    for (int i = 0; i < 5 && d.power_state() != state; ++i) {
      d.sample();
      d.apply(0.0);
    }
    return d.power_state();
  };
  EXPECT_EQ(run_until(drive::PowerState::kSwitchOnDisabled), drive::PowerState::kSwitchOnDisabled);
  EXPECT_TRUE(d.request(drive::DriveCommand::kShutdown).accepted);
  EXPECT_EQ(run_until(drive::PowerState::kReadyToSwitchOn), drive::PowerState::kReadyToSwitchOn);
  d.sample();
  d.apply(0.0);
  EXPECT_EQ(d.power_state(), drive::PowerState::kReadyToSwitchOn);  // held there
  EXPECT_TRUE(d.request(drive::DriveCommand::kSwitchOn).accepted);
  EXPECT_EQ(run_until(drive::PowerState::kSwitchedOn), drive::PowerState::kSwitchedOn);
  EXPECT_TRUE(d.request(drive::DriveCommand::kEnableOperation).accepted);
  EXPECT_EQ(run_until(drive::PowerState::kOperationEnabled), drive::PowerState::kOperationEnabled);
  EXPECT_TRUE(d.request(drive::DriveCommand::kDisableOperation).accepted);
  EXPECT_EQ(run_until(drive::PowerState::kSwitchedOn), drive::PowerState::kSwitchedOn);
  EXPECT_TRUE(d.request(drive::DriveCommand::kQuickStop).accepted);
  EXPECT_EQ(run_until(drive::PowerState::kSwitchOnDisabled), drive::PowerState::kSwitchOnDisabled);
}

TEST(Cia402Drive, ConfigIsValidated) {
  FakeClock clock;
  MemoryBus bus(clock);
  Cia402DriveConfig config;
  config.node_id = 0;
  EXPECT_THROW(Cia402Drive(config, bus, [&] { return clock.ns; }), std::invalid_argument);
  config.node_id = 127;
  EXPECT_THROW(Cia402Drive(config, bus, [&] { return clock.ns; }), std::invalid_argument);
}

}  // namespace
