// Names of the error categories; see result.hpp.
#include "pmlsm/canopen/result.hpp"

namespace pmlsm::canopen {

const char* to_string(Error error) noexcept {
  switch (error) {
    case Error::kNone: return "no error";
    case Error::kWrongCobId: return "wrong COB-ID";
    case Error::kWrongDlc: return "wrong DLC";
    case Error::kRemoteFrame: return "remote frame";
    case Error::kExtendedFrame: return "extended frame";
    case Error::kInvalidNodeId: return "invalid node id";
    case Error::kUnknownCommand: return "unknown command";
    case Error::kInvalidValue: return "invalid value";
    case Error::kSegmentedNotSupported: return "segmented transfer not supported";
    case Error::kBlockNotSupported: return "block transfer not supported";
    case Error::kUnexpectedResponse: return "unexpected response";
    case Error::kSdoAborted: return "SDO transfer aborted";
    case Error::kBusy: return "busy";
    case Error::kTimeout: return "timeout";
    case Error::kAccessRefused: return "access refused";
    case Error::kPdoMapping: return "invalid PDO mapping";
  }
  return "unknown";
}

}  // namespace pmlsm::canopen
