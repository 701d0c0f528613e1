// The SDO server of a slave: answers expedited upload and download requests (sdo.hpp) from its
// object dictionary, with CiA 301's abort codes. noexcept and allocation-free.
//
// Call it only while the NMT state allows SDO (pre-operational, operational: NmtSlave::
// sdo_allowed()); in stopped a node does not answer SDO requests.
#pragma once

#include <cstdint>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/object_dictionary.hpp"
#include "pmlsm/canopen/result.hpp"
#include "pmlsm/canopen/sdo.hpp"

namespace pmlsm::canopen {

struct SdoServerResult {
  /// A response is to be sent (`response`, to 0x580 + node).
  bool respond = false;
  CanFrame response{};
  /// The request as far as it was understood (multiplexer, kind, data).
  SdoRequest request;
  /// ok when the request was carried out (or was the client's abort); else why not: the parse
  /// error, or kAccessRefused with the abort code sent.
  Status status;
};

class SdoServer {
 public:
  SdoServer(ObjectDictionary& dictionary, NodeId node) noexcept : dictionary_(&dictionary), node_(node) {}

  /// One received frame:
  ///   - not this node's 0x600 + node, RTR or extended: ignored (respond false, status says why);
  ///   - upload: the value (0x4F/0x4B/0x47/0x43) or an abort;
  ///   - download: 0x60 after the value is written, or an abort;
  ///   - the client's abort: nothing to send (status ok, request.abort_code the client's code);
  ///   - a DLC other than 8, a segmented or block request, an unknown command specifier: abort
  ///     0x05040001 (with the multiplexer of the request when the frame has bytes 1-3).
  SdoServerResult handle(const CanFrame& frame) noexcept;

  NodeId node() const noexcept { return node_; }

 private:
  ObjectDictionary* dictionary_;
  NodeId node_;
};

}  // namespace pmlsm::canopen
