// The SDO server over an object dictionary; see sdo_server.hpp.
#include "pmlsm/canopen/sdo_server.hpp"

#include "pmlsm/canopen/bytes.hpp"

namespace pmlsm::canopen {

SdoServerResult SdoServer::handle(const CanFrame& frame) noexcept {
  SdoServerResult out;
  if (frame.extended || frame.rtr || frame.id != sdo_rx_cob_id(node_)) {
    const Result<SdoRequest> parsed = parse_sdo_request(frame);
    out.status = parsed.ok() ? fail(Error::kWrongCobId, "SDO server: request for another node")
                             : static_cast<const Status&>(parsed);
    return out;
  }
  const Result<SdoRequest> parsed = parse_sdo_request(frame);
  out.request = parsed.value;
  if (!parsed) {
    // Malformed, segmented, block or unknown: abort (0x05040001), naming the multiplexer when the
    // frame has it.
    out.status = parsed;
    out.respond = true;
    out.response = sdo_abort_response(node_, parsed.value.index, parsed.value.subindex,
                                      parsed.abort_code != 0 ? parsed.abort_code : kAbortCommandSpecifier);
    return out;
  }
  const SdoRequest& request = parsed.value;
  switch (request.kind) {
    case SdoRequestKind::kAbort:
      // The client ends its transfer; an expedited server holds no state, nothing to answer.
      return out;
    case SdoRequestKind::kUpload: {
      const Result<SdoData> value = dictionary_->read(request.index, request.subindex);
      out.respond = true;
      if (!value) {
        out.status = value;
        out.response = sdo_abort_response(node_, request.index, request.subindex, value.abort_code);
        return out;
      }
      out.response =
          sdo_upload_response(node_, request.index, request.subindex, value.value.data, value.value.size).value;
      return out;
    }
    case SdoRequestKind::kDownload: {
      const Status written = dictionary_->write(request.index, request.subindex, request.data);
      out.respond = true;
      if (!written) {
        out.status = written;
        out.response = sdo_abort_response(node_, request.index, request.subindex, written.abort_code);
        return out;
      }
      out.response = sdo_download_response(node_, request.index, request.subindex);
      return out;
    }
  }
  out.status = fail(Error::kUnknownCommand, "SDO server: unknown request kind");
  return out;
}

}  // namespace pmlsm::canopen
