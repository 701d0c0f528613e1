// Expedited SDO from the bus: a slave's SdoServer over the CiA 402 dictionary (node 5), which
// writes what the frames ask into it, and a master's SdoClient (to node 5) taking the frames as
// responses. Frames: canopen_input.hpp; flags bit 2 starts an upload, bit 3 a download, of the
// frame's multiplexer (bytes 1-3) by the client when it is idle. Every answer the server gives
// must be a valid SDO response of node 5.
#include <cstdlib>

#include "canopen_input.hpp"
#include "pmlsm/canopen/cia402_dictionary.hpp"
#include "pmlsm/canopen/sdo.hpp"
#include "pmlsm/canopen/sdo_server.hpp"

namespace pmlsm::fuzz::canopen_sdo {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  using namespace pmlsm::canopen;
  const NodeId node(5);
  ObjectDictionary dictionary = make_cia402_dictionary(node);
  SdoServer server(dictionary, node);
  SdoClient client(node, 50);
  std::uint64_t now_ms = 0;
  ByteReader in(data, size);
  while (!in.empty()) {
    const FuzzFrame f = next_frame(in);
    const CanFrame& frame = f.frame;
    now_ms += f.elapsed_ms;

    parse_sdo_request(frame);
    parse_sdo_response(frame);

    const SdoServerResult served = server.handle(frame);
    if (served.respond) {
      const CanFrame& r = served.response;
      if (r.id != 0x585U || r.dlc != 8 || r.rtr || r.extended) std::abort();
      if (!parse_sdo_response(r)) std::abort();  // the server's own answer must parse
    }

    const auto index = static_cast<std::uint16_t>(frame.data[1] | (frame.data[2] << 8));
    const std::uint8_t subindex = frame.data[3];
    if (!client.busy() && (f.target_bits & 1U) != 0) client.upload(index, subindex, now_ms);
    if (!client.busy() && (f.target_bits & 2U) != 0) {
      client.download(index, subindex, SdoData{frame.data[4], static_cast<std::uint8_t>(frame.data[0] % 5)}, now_ms);
    }
    const SdoClientEvent event = client.on_frame(frame);
    if (event.send_abort && event.abort_frame.id != 0x605U) std::abort();
    client.poll(now_ms);
    describe(event.abort_code);
  }
  return 0;
}

}  // namespace pmlsm::fuzz::canopen_sdo
