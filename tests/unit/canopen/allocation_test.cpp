// The per-cycle work of pmlsm::canopen makes no heap allocation: frames encoded and decoded,
// SDO served, PDOs packed and unpacked, the NMT slave and the CiA 402 master stepped.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <vector>

#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/cia402_master.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/canopen/scaling.hpp"
#include "pmlsm/canopen/sdo_server.hpp"
#include "pmlsm/canopen/sync.hpp"
#include "../allocation_counter.hpp"

namespace {

using namespace pmlsm::canopen;

TEST(CanopenAllocationTest, CounterSeesAllocations) {
  const std::size_t before = pmlsm::test::allocations();
  std::vector<int> v;
  v.reserve(16);
  EXPECT_GT(pmlsm::test::allocations(), before);
}

TEST(CanopenAllocationTest, ACycleAllocatesNothing) {
  const NodeId node(3);
  ObjectDictionary od = make_cia402_dictionary(node);
  ObjectDictionary master_od = make_cia402_dictionary(node);
  SdoServer server(od, node);
  NmtSlave slave(node);
  Cia402Master master;
  pmlsm::drive::PowerStateMachine drive;
  const UnitScaling scaling(ScalingConfig{200.0, 1e6});
  const PdoMap rpdo = read_pdo_map(od, 0x1600).value;
  const PdoMap tpdo = read_pdo_map(od, 0x1A00).value;
  SyncProducer sync(240);
  SdoClient client(node, 100);

  const std::size_t before = pmlsm::test::allocations();
  slave.boot();
  slave.on_frame(encode_nmt(NmtCommand::kStart, node));
  std::uint16_t previous = 0;
  std::size_t ok = 0;
  for (std::uint64_t t = 0; t < 200; ++t) {
    drive.step();
    const CanFrame s = sync.next();
    ok += decode_sync(s).ok();
    ok += od.set(0x6041, 0, drive.statusword()).ok();
    ok += od.set(0x6077, 0, scaling.force_to_per_mille(12.5).value).ok();
    ok += od.set(0x6064, 0, scaling.metres_to_increments(0.001 * static_cast<double>(t)).value).ok();
    const auto tx = pack_pdo(tpdo, od, tpdo_cob_id(1, node));
    ok += tx.ok();
    const auto out = master.update(static_cast<std::uint16_t>(tx.value.data[0] | (tx.value.data[1] << 8)), true);
    ok += master_od.set(0x6040, 0, out.controlword).ok();
    ok += master_od.set(0x6071, 0, scaling.force_to_per_mille(-30.0).value).ok();
    const auto rx = pack_pdo(rpdo, master_od, rpdo_cob_id(1, node));
    ok += unpack_pdo(rpdo, od, rx.value).ok();
    const auto command =
        pmlsm::drive::decode_controlword(static_cast<std::uint16_t>(od.get_or(0x6040, 0, 0)), previous);
    if (command) drive.request(*command);
    previous = static_cast<std::uint16_t>(od.get_or(0x6040, 0, 0));
    const auto request = client.upload(0x6041, 0, t);
    const SdoServerResult answer = server.handle(request.value);
    ok += client.on_frame(answer.response).kind == SdoClientEventKind::kUploaded;
    ok += server.handle(sdo_download_request(node, 0x6060, 0, 9, 1).value).respond;  // refused: abort
    ok += decode_emcy(encode_emcy(node, EmcyMessage{})).ok();
    ok += slave.poll_heartbeat(10, t).has_value();
    ok += decode_heartbeat(encode_heartbeat(node, slave.state())).ok();
  }
  EXPECT_EQ(pmlsm::test::allocations(), before);
  EXPECT_GT(ok, 200u * 12);
  EXPECT_EQ(drive.state(), pmlsm::drive::PowerState::kOperationEnabled);
}

}  // namespace
