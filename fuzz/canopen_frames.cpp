// The other CANopen frames from the bus: NMT commands, SYNC, EMCY and heartbeats (their
// decoders, a slave's NmtSlave, a master's HeartbeatConsumer) and RPDOs unpacked into the
// CiA 402 dictionary through its own mappings and through mappings the input builds (flags
// bit 2: the frame's data are two mapping entries for a fifth RPDO map, validated first).
// Frames: canopen_input.hpp.
#include <cstdlib>
#include <vector>

#include "canopen_input.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/emcy.hpp"
#include "pmlsm/canopen/nmt.hpp"
#include "pmlsm/canopen/pdo.hpp"
#include "pmlsm/canopen/sync.hpp"

namespace pmlsm::fuzz::canopen_frames {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::canopen;
  const NodeId node(5);
  ObjectDictionary dictionary = make_cia402_dictionary(node);
  NmtSlave slave(node);
  slave.boot();
  HeartbeatConsumer consumer(node, 50);
  std::vector<PdoMap> maps;
  for (std::uint16_t index = kRpdoMappingFirst; index < kRpdoMappingFirst + 4; ++index) {
    const Result<PdoMap> map = read_pdo_map(dictionary, index);
    if (map) maps.push_back(map.value);
  }
  PdoMap built;
  std::uint64_t now_ms = 0;
  ByteReader in(data, size);
  while (!in.empty()) {
    const FuzzFrame f = next_frame(in);
    const CanFrame& frame = f.frame;
    now_ms += f.elapsed_ms;

    if (const Result<NmtCommandMessage> nmt = decode_nmt(frame)) to_string(nmt.value.command);
    if (const Result<HeartbeatMessage> heartbeat = decode_heartbeat(frame)) to_string(heartbeat.value.state);
    decode_sync(frame);
    if (const Result<EmcyMessage> emcy = decode_emcy(frame)) describe_emcy(emcy.value.error_code);
    decode_consumer_heartbeat_entry(
        static_cast<std::uint32_t>(frame.data[0] | (frame.data[1] << 8) | (frame.data[2] << 16)) |
        (static_cast<std::uint32_t>(frame.data[3]) << 24));

    slave.on_frame(frame);
    if (slave.state() == NmtState::kInitialising) slave.boot();
    slave.poll_heartbeat(100, now_ms);
    to_string(consumer.on_frame(frame, now_ms));
    consumer.poll(now_ms);

    if ((f.target_bits & 1U) != 0) {
      built.clear();
      for (std::size_t k = 0; k < 2; ++k) {
        const std::uint32_t entry = static_cast<std::uint32_t>(frame.data[4 * k]) |
                                    (static_cast<std::uint32_t>(frame.data[4 * k + 1]) << 8) |
                                    (static_cast<std::uint32_t>(frame.data[4 * k + 2]) << 16) |
                                    (static_cast<std::uint32_t>(frame.data[4 * k + 3]) << 24);
        built.add(decode_pdo_mapping(entry));
      }
      if (validate_pdo_map(built, dictionary, PdoDirection::kReceive)) maps.push_back(built);
      if (maps.size() > 5) maps.pop_back();
      continue;
    }
    for (const PdoMap& map : maps) unpack_pdo(map, dictionary, frame);
  }
  for (std::uint16_t index = kTpdoMappingFirst; index < kTpdoMappingFirst + 4; ++index) {
    const Result<PdoMap> map = read_pdo_map(dictionary, index);
    if (map) pack_pdo(map.value, dictionary, 0x185);
  }
  return 0;
}

}  // namespace pmlsm::fuzz::canopen_frames
