// Expedited SDO: abort codes, request/response coding, the client transaction; see sdo.hpp.
#include "pmlsm/canopen/sdo.hpp"

#include <stdexcept>

#include "frame_checks.hpp"
#include "pmlsm/canopen/bytes.hpp"

namespace pmlsm::canopen {
namespace {

constexpr std::uint8_t kCsDownloadSegment = 0;   // ccs: download segment; scs: upload segment
constexpr std::uint8_t kCsInitiateDownload = 1;  // ccs; scs 1: download segment response
constexpr std::uint8_t kCsInitiateUpload = 2;    // ccs and scs
constexpr std::uint8_t kCsUploadSegment = 3;     // ccs; scs 3: initiate download response
constexpr std::uint8_t kCsAbort = 4;
constexpr std::uint8_t kCsBlock5 = 5;
constexpr std::uint8_t kCsBlock6 = 6;

constexpr std::uint8_t kBitExpedited = 1U << 1;
constexpr std::uint8_t kBitSizeIndicated = 1U << 0;

constexpr std::uint32_t size_mask(std::uint8_t size) noexcept {
  return size >= 4 ? 0xFFFFFFFFU : ((1U << (8U * size)) - 1U);
}

bool fits(std::uint32_t data, std::uint8_t size) noexcept { return (data & ~size_mask(size)) == 0; }

CanFrame sdo_frame(std::uint32_t id, std::uint8_t command, std::uint16_t index, std::uint8_t subindex) noexcept {
  CanFrame frame = make_frame(id, 8);
  frame.data[0] = command;
  put_u16_le(frame.data, 1, index);
  frame.data[3] = subindex;
  return frame;
}

// The data of an expedited initiate frame (e = 1): size from s and n, unused bytes masked off.
SdoData expedited_data(const CanFrame& frame) noexcept {
  SdoData data;
  const std::uint8_t command = frame.data[0];
  data.size = (command & kBitSizeIndicated) != 0 ? static_cast<std::uint8_t>(4U - ((command >> 2) & 0x3U)) : 0;
  data.data = get_u32_le(frame.data, 4) & size_mask(data.size == 0 ? 4 : data.size);
  return data;
}

template <typename T>
void fill_multiplexer(T& value, const CanFrame& frame) noexcept {
  value.index = get_u16_le(frame.data, 1);
  value.subindex = frame.data[3];
}

/// What both SDO parsers check first: a standard data frame on the SDO COB-ID of `function`,
/// with DLC 8; the node id and (from 4 bytes on) the multiplexer are filled either way. False,
/// with the error in `r`, when the frame is not one.
template <typename T>
bool parse_sdo_envelope(const CanFrame& frame, FunctionCode function, const char* wrong_cob_id, const char* wrong_dlc,
                        Result<T>& r) noexcept {
  if (const Status s = detail::check_standard_data_frame(frame); !s) {
    r = detail::as_result<T>(s);
    return false;
  }
  const CobIdInfo info = classify(frame.id);
  if (info.function != function) {
    r = fail_with<T>(Error::kWrongCobId, wrong_cob_id);
    return false;
  }
  if (frame.dlc != 8) r = fail_with<T>(Error::kWrongDlc, wrong_dlc, kAbortCommandSpecifier);
  r.value.node_id = info.node_id;
  if (frame.dlc >= 4) fill_multiplexer(r.value, frame);
  return frame.dlc == 8;
}

/// `r` turned into the refusal of a command specifier this library does not serve (segmented,
/// block, undefined): the error, its text and the abort code a server answers with.
template <typename T>
Result<T> refused(Result<T>& r, Error error, const char* detail) noexcept {
  r.error = error;
  r.detail = detail;
  r.abort_code = kAbortCommandSpecifier;
  return r;
}

}  // namespace

const char* describe(std::uint32_t abort_code) noexcept {
  switch (abort_code) {
    case kAbortNone: return "no error";
    case kAbortToggleBit: return "toggle bit not alternated";
    case kAbortTimeout: return "SDO protocol timed out";
    case kAbortCommandSpecifier: return "client/server command specifier not valid or unknown";
    case kAbortBlockSize: return "invalid block size (block mode only)";
    case kAbortSequenceNumber: return "invalid sequence number (block mode only)";
    case kAbortCrc: return "CRC error (block mode only)";
    case kAbortOutOfMemory: return "out of memory";
    case kAbortUnsupportedAccess: return "unsupported access to an object";
    case kAbortReadWriteOnly: return "attempt to read a write only object";
    case kAbortWriteReadOnly: return "attempt to write a read only object";
    case kAbortObjectMissing: return "object does not exist in the object dictionary";
    case kAbortNotMappable: return "object cannot be mapped to the PDO";
    case kAbortPdoLength: return "the number and length of the objects to be mapped would exceed PDO length";
    case kAbortParameterIncompatible: return "general parameter incompatibility reason";
    case kAbortInternalIncompatible: return "general internal incompatibility in the device";
    case kAbortHardware: return "access failed due to a hardware error";
    case kAbortLengthMismatch: return "data type does not match, length of service parameter does not match";
    case kAbortLengthTooHigh: return "data type does not match, length of service parameter too high";
    case kAbortLengthTooLow: return "data type does not match, length of service parameter too low";
    case kAbortSubindexMissing: return "sub-index does not exist";
    case kAbortValueRange: return "invalid value for parameter (download only)";
    case kAbortValueTooHigh: return "value of parameter written too high (download only)";
    case kAbortValueTooLow: return "value of parameter written too low (download only)";
    case kAbortMaxBelowMin: return "maximum value is less than minimum value";
    case kAbortNoSdoConnection: return "resource not available: SDO connection";
    case kAbortGeneral: return "general error";
    case kAbortDataNotStored: return "data cannot be transferred or stored to the application";
    case kAbortLocalControl: return "data cannot be transferred or stored to the application because of local control";
    case kAbortDeviceState:
      return "data cannot be transferred or stored to the application because of the present device state";
    case kAbortNoDictionary: return "object dictionary dynamic generation fails or no object dictionary is present";
    case kAbortNoData: return "no data available";
    default: break;
  }
  return "unknown abort code";
}

// ---- client side ------------------------------------------------------------------------------

CanFrame sdo_upload_request(NodeId server, std::uint16_t index, std::uint8_t subindex) noexcept {
  return sdo_frame(sdo_rx_cob_id(server), kSdoUploadRequest, index, subindex);
}

Result<CanFrame> sdo_download_request(NodeId server, std::uint16_t index, std::uint8_t subindex, std::uint32_t data,
                                      std::uint8_t size) noexcept {
  if (size < 1 || size > 4) return fail_with<CanFrame>(Error::kInvalidValue, "SDO download: size must be 1..4 bytes");
  if (!fits(data, size))
    return fail_with<CanFrame>(Error::kInvalidValue, "SDO download: data does not fit in size bytes");
  CanFrame frame = sdo_frame(sdo_rx_cob_id(server), sdo_download_command(size), index, subindex);
  put_u32_le(frame.data, 4, data);
  return success(frame);
}

CanFrame sdo_abort_request(NodeId server, std::uint16_t index, std::uint8_t subindex,
                           std::uint32_t abort_code) noexcept {
  CanFrame frame = sdo_frame(sdo_rx_cob_id(server), kSdoAbort, index, subindex);
  put_u32_le(frame.data, 4, abort_code);
  return frame;
}

Result<SdoResponse> parse_sdo_response(const CanFrame& frame) noexcept {
  Result<SdoResponse> r;
  if (!parse_sdo_envelope(frame, FunctionCode::kSdoTx, "SDO response: COB-ID must be 0x581..0x5FF",
                          "SDO response: DLC must be 8", r)) {
    return r;
  }
  const auto refuse = [&r](Error error, const char* detail) { return refused(r, error, detail); };
  const std::uint8_t command = frame.data[0];
  switch (command >> 5) {
    case kCsInitiateUpload:
      if ((command & kBitExpedited) == 0) {
        return refuse(Error::kSegmentedNotSupported,
                      "segmented transfer not supported: the server started a segmented upload (value over 4 bytes)");
      }
      r.value.kind = SdoResponseKind::kUpload;
      r.value.data = expedited_data(frame);
      return r;
    case kCsUploadSegment:  // scs 3: initiate download response
      r.value.kind = SdoResponseKind::kDownload;
      return r;
    case kCsAbort:
      r.value.kind = SdoResponseKind::kAbort;
      r.value.abort_code = get_u32_le(frame.data, 4);
      return r;
    case kCsDownloadSegment:  // scs 0: upload segment response
      return refuse(Error::kSegmentedNotSupported, "segmented transfer not supported: upload segment response");
    case kCsInitiateDownload:  // scs 1: download segment response
      return refuse(Error::kSegmentedNotSupported, "segmented transfer not supported: download segment response");
    case kCsBlock5:
    case kCsBlock6: return refuse(Error::kBlockNotSupported, "block transfer not supported: block response");
    default: break;
  }
  return refuse(Error::kUnknownCommand, "SDO response: server command specifier 7 is not defined");
}

// ---- server side ------------------------------------------------------------------------------

Result<SdoRequest> parse_sdo_request(const CanFrame& frame) noexcept {
  Result<SdoRequest> r;
  if (!parse_sdo_envelope(frame, FunctionCode::kSdoRx, "SDO request: COB-ID must be 0x601..0x67F",
                          "SDO request: DLC must be 8", r)) {
    return r;
  }
  const auto refuse = [&r](Error error, const char* detail) { return refused(r, error, detail); };
  const std::uint8_t command = frame.data[0];
  switch (command >> 5) {
    case kCsInitiateDownload:
      if ((command & kBitExpedited) == 0) {
        return refuse(Error::kSegmentedNotSupported,
                      "segmented transfer not supported: segmented download (e = 0) requested");
      }
      r.value.kind = SdoRequestKind::kDownload;
      r.value.data = expedited_data(frame);
      return r;
    case kCsInitiateUpload: r.value.kind = SdoRequestKind::kUpload; return r;
    case kCsAbort:
      r.value.kind = SdoRequestKind::kAbort;
      r.value.abort_code = get_u32_le(frame.data, 4);
      return r;
    case kCsDownloadSegment:
      return refuse(Error::kSegmentedNotSupported, "segmented transfer not supported: download segment request");
    case kCsUploadSegment:
      return refuse(Error::kSegmentedNotSupported, "segmented transfer not supported: upload segment request");
    case kCsBlock5:
    case kCsBlock6: return refuse(Error::kBlockNotSupported, "block transfer not supported: block request");
    default: break;
  }
  return refuse(Error::kUnknownCommand, "SDO request: client command specifier 7 is not defined");
}

Result<CanFrame> sdo_upload_response(NodeId server, std::uint16_t index, std::uint8_t subindex, std::uint32_t data,
                                     std::uint8_t size) noexcept {
  if (size < 1 || size > 4)
    return fail_with<CanFrame>(Error::kInvalidValue, "SDO upload response: size must be 1..4 bytes");
  if (!fits(data, size)) {
    return fail_with<CanFrame>(Error::kInvalidValue, "SDO upload response: data does not fit in size bytes");
  }
  CanFrame frame = sdo_frame(sdo_tx_cob_id(server), sdo_upload_response_command(size), index, subindex);
  put_u32_le(frame.data, 4, data);
  return success(frame);
}

CanFrame sdo_download_response(NodeId server, std::uint16_t index, std::uint8_t subindex) noexcept {
  return sdo_frame(sdo_tx_cob_id(server), kSdoDownloadResponse, index, subindex);
}

CanFrame sdo_abort_response(NodeId server, std::uint16_t index, std::uint8_t subindex,
                            std::uint32_t abort_code) noexcept {
  CanFrame frame = sdo_frame(sdo_tx_cob_id(server), kSdoAbort, index, subindex);
  put_u32_le(frame.data, 4, abort_code);
  return frame;
}

// ---- SdoClient --------------------------------------------------------------------------------

SdoClient::SdoClient(NodeId server, std::uint32_t timeout_ms) : server_(server), timeout_ms_(timeout_ms) {
  if (timeout_ms == 0) throw std::invalid_argument("SDO client timeout_ms: must be >= 1, got 0");
}

Result<CanFrame> SdoClient::upload(std::uint16_t index, std::uint8_t subindex, std::uint64_t now_ms) noexcept {
  if (busy_) return fail_with<CanFrame>(Error::kBusy, "SDO client: a transfer is outstanding");
  busy_ = true;
  uploading_ = true;
  index_ = index;
  subindex_ = subindex;
  started_ms_ = now_ms;
  return success(sdo_upload_request(server_, index, subindex));
}

Result<CanFrame> SdoClient::download(std::uint16_t index, std::uint8_t subindex, SdoData data,
                                     std::uint64_t now_ms) noexcept {
  if (busy_) return fail_with<CanFrame>(Error::kBusy, "SDO client: a transfer is outstanding");
  Result<CanFrame> request = sdo_download_request(server_, index, subindex, data.data, data.size);
  if (!request) return request;
  busy_ = true;
  uploading_ = false;
  index_ = index;
  subindex_ = subindex;
  started_ms_ = now_ms;
  return request;
}

SdoClientEvent SdoClient::finish(SdoClientEventKind kind) noexcept {
  busy_ = false;
  SdoClientEvent event;
  event.kind = kind;
  event.index = index_;
  event.subindex = subindex_;
  return event;
}

SdoClientEvent SdoClient::on_frame(const CanFrame& frame) noexcept {
  if (!busy_ || frame.extended || frame.rtr || frame.id != sdo_tx_cob_id(server_)) return {};
  const Result<SdoResponse> response = parse_sdo_response(frame);
  if (!response) {
    SdoClientEvent event = finish(SdoClientEventKind::kFailed);
    event.error = response.error;
    event.detail = response.detail;
    event.send_abort = true;
    event.abort_code = kAbortCommandSpecifier;
    event.abort_frame = sdo_abort_request(server_, index_, subindex_, kAbortCommandSpecifier);
    return event;
  }
  const SdoResponse& r = response.value;
  if (r.kind == SdoResponseKind::kAbort) {
    SdoClientEvent event = finish(SdoClientEventKind::kAborted);
    event.abort_code = r.abort_code;
    event.error = Error::kSdoAborted;
    event.detail = describe(r.abort_code);
    return event;
  }
  if (r.index != index_ || r.subindex != subindex_) {
    SdoClientEvent event = finish(SdoClientEventKind::kFailed);
    event.error = Error::kUnexpectedResponse;
    event.detail = "SDO client: the response names another object than the request";
    return event;
  }
  if (uploading_ != (r.kind == SdoResponseKind::kUpload)) {
    SdoClientEvent event = finish(SdoClientEventKind::kFailed);
    event.error = Error::kUnexpectedResponse;
    event.detail = uploading_ ? "SDO client: download response to an upload request"
                              : "SDO client: upload response to a download request";
    return event;
  }
  if (uploading_) {
    SdoClientEvent event = finish(SdoClientEventKind::kUploaded);
    event.data = r.data;
    return event;
  }
  return finish(SdoClientEventKind::kDownloaded);
}

SdoClientEvent SdoClient::poll(std::uint64_t now_ms) noexcept {
  if (!busy_ || now_ms <= started_ms_ + timeout_ms_) return {};
  SdoClientEvent event = finish(SdoClientEventKind::kTimedOut);
  event.error = Error::kTimeout;
  event.detail = "SDO client: no response in time";
  event.abort_code = kAbortTimeout;
  event.send_abort = true;
  event.abort_frame = sdo_abort_request(server_, index_, subindex_, kAbortTimeout);
  return event;
}

}  // namespace pmlsm::canopen
