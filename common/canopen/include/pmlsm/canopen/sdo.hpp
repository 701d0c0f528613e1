// Expedited SDO (CiA 301 service data objects): values of 1 to 4 bytes read (upload) or written
// (download) in one request and one response, DLC 8, on COB-IDs 0x600 + node (client ->
// server) and 0x580 + node (server -> client).
//
// Byte 0 is the command: bits 7-5 the command specifier (ccs from the client, scs from the
// server); for initiate frames bits 3-2 n (unused bytes of 4 when s = 1), bit 1 e (expedited),
// bit 0 s (size indicated). Bytes 1-2 the index (LE), byte 3 the sub-index (together the
// multiplexer), bytes 4-7 the data (LE, unused bytes 0) or the abort code (LE).
//
//   upload request           ccs 2                        0x40
//   upload response          scs 2, e = 1, s = 1          0x4F / 0x4B / 0x47 / 0x43 (1/2/3/4 bytes)
//   download request         ccs 1, e = 1, s = 1          0x2F / 0x2B / 0x27 / 0x23 (1/2/3/4 bytes)
//   download response        scs 3                        0x60
//   abort transfer           cs 4                         0x80 (either direction)
//
// Segmented and block transfer are not supported: the server answers such requests with abort
// 0x05040001, the client reports kSegmentedNotSupported ("segmented transfer not supported")
// when a server starts a segmented upload (e = 0) and aborts it with 0x05040001.
#pragma once

#include <cstdint>
#include <type_traits>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/frame.hpp"
#include "pmlsm/canopen/result.hpp"

namespace pmlsm::canopen {

// ---- abort codes (CiA 301) -----------------------------------------------------------------

inline constexpr std::uint32_t kAbortNone = 0;
inline constexpr std::uint32_t kAbortToggleBit = 0x05030000;
inline constexpr std::uint32_t kAbortTimeout = 0x05040000;
inline constexpr std::uint32_t kAbortCommandSpecifier = 0x05040001;
inline constexpr std::uint32_t kAbortBlockSize = 0x05040002;
inline constexpr std::uint32_t kAbortSequenceNumber = 0x05040003;
inline constexpr std::uint32_t kAbortCrc = 0x05040004;
inline constexpr std::uint32_t kAbortOutOfMemory = 0x05040005;
inline constexpr std::uint32_t kAbortUnsupportedAccess = 0x06010000;
inline constexpr std::uint32_t kAbortReadWriteOnly = 0x06010001;
inline constexpr std::uint32_t kAbortWriteReadOnly = 0x06010002;
inline constexpr std::uint32_t kAbortObjectMissing = 0x06020000;
inline constexpr std::uint32_t kAbortNotMappable = 0x06040041;
inline constexpr std::uint32_t kAbortPdoLength = 0x06040042;
inline constexpr std::uint32_t kAbortParameterIncompatible = 0x06040043;
inline constexpr std::uint32_t kAbortInternalIncompatible = 0x06040047;
inline constexpr std::uint32_t kAbortHardware = 0x06060000;
inline constexpr std::uint32_t kAbortLengthMismatch = 0x06070010;
inline constexpr std::uint32_t kAbortLengthTooHigh = 0x06070012;
inline constexpr std::uint32_t kAbortLengthTooLow = 0x06070013;
inline constexpr std::uint32_t kAbortSubindexMissing = 0x06090011;
inline constexpr std::uint32_t kAbortValueRange = 0x06090030;
inline constexpr std::uint32_t kAbortValueTooHigh = 0x06090031;
inline constexpr std::uint32_t kAbortValueTooLow = 0x06090032;
inline constexpr std::uint32_t kAbortMaxBelowMin = 0x06090036;
inline constexpr std::uint32_t kAbortNoSdoConnection = 0x060A0023;
inline constexpr std::uint32_t kAbortGeneral = 0x08000000;
inline constexpr std::uint32_t kAbortDataNotStored = 0x08000020;
inline constexpr std::uint32_t kAbortLocalControl = 0x08000021;
inline constexpr std::uint32_t kAbortDeviceState = 0x08000022;
inline constexpr std::uint32_t kAbortNoDictionary = 0x08000023;
inline constexpr std::uint32_t kAbortNoData = 0x08000024;

/// The standard's text of an abort code, e.g. describe(0x06020000) = "object does not exist in
/// the object dictionary"; "no error" for 0, "unknown abort code" for a code the standard does
/// not list.
const char* describe(std::uint32_t abort_code) noexcept;

// ---- command bytes ---------------------------------------------------------------------------

inline constexpr std::uint8_t kSdoUploadRequest = 0x40;
inline constexpr std::uint8_t kSdoDownloadResponse = 0x60;
inline constexpr std::uint8_t kSdoAbort = 0x80;

/// Download request (ccs 1, e = 1, s = 1) for 1..4 bytes: 0x2F, 0x2B, 0x27, 0x23; 0 for other
/// sizes.
constexpr std::uint8_t sdo_download_command(std::uint8_t size) noexcept {
  return (size >= 1 && size <= 4) ? static_cast<std::uint8_t>(0x23U | ((4U - size) << 2)) : 0U;
}
/// Upload response (scs 2, e = 1, s = 1) for 1..4 bytes: 0x4F, 0x4B, 0x47, 0x43; 0 otherwise.
constexpr std::uint8_t sdo_upload_response_command(std::uint8_t size) noexcept {
  return (size >= 1 && size <= 4) ? static_cast<std::uint8_t>(0x43U | ((4U - size) << 2)) : 0U;
}

/// Expedited data: up to 4 bytes, little endian in `data` (bits over size * 8 are 0).
struct SdoData {
  std::uint32_t data = 0;
  /// 1..4; 0 = not indicated (s = 0): the receiver takes the object's own size.
  std::uint8_t size = 0;
};

// ---- client side: requests and the server's responses -----------------------------------------

/// Upload (read) request: 0x40, multiplexer, zero data.
CanFrame sdo_upload_request(NodeId server, std::uint16_t index, std::uint8_t subindex) noexcept;
/// Expedited download (write) of `size` (1..4) bytes of `data` (LE; bits above size * 8 must
/// be 0). Error kInvalidValue for a size outside 1..4 or data that does not fit.
Result<CanFrame> sdo_download_request(NodeId server, std::uint16_t index, std::uint8_t subindex, std::uint32_t data,
                                      std::uint8_t size) noexcept;

/// Typed download: the value's own size (int8/uint8 1 byte, int16/uint16 2, int32/uint32 4),
/// two's complement for the signed types.
template <typename T>
CanFrame sdo_download(NodeId server, std::uint16_t index, std::uint8_t subindex, T value) noexcept {
  static_assert(
      std::is_integral_v<T> && !std::is_same_v<T, bool> && (sizeof(T) == 1 || sizeof(T) == 2 || sizeof(T) == 4),
      "sdo_download: an 8, 16 or 32-bit integer");
  using U = std::make_unsigned_t<T>;
  return sdo_download_request(server, index, subindex, static_cast<std::uint32_t>(static_cast<U>(value)),
                              static_cast<std::uint8_t>(sizeof(T)))
      .value;
}

/// Abort of a transfer by the client (to 0x600 + node).
CanFrame sdo_abort_request(NodeId server, std::uint16_t index, std::uint8_t subindex,
                           std::uint32_t abort_code) noexcept;

enum class SdoResponseKind : std::uint8_t { kUpload, kDownload, kAbort };

struct SdoResponse {
  SdoResponseKind kind = SdoResponseKind::kAbort;
  std::uint8_t node_id = 0;  // the server's
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  /// kUpload: the value (size 0 when the server did not indicate it: 4 bytes given).
  SdoData data;
  /// kAbort: the server's abort code.
  std::uint32_t abort_code = 0;
};

/// A server's response (0x581..0x5FF). An abort is a valid response (kind kAbort), not an
/// error. Errors: wrong id, RTR / extended frame, DLC not 8 (kWrongDlc); an upload response
/// with e = 0 (the server starts a segmented upload: kSegmentedNotSupported, "segmented
/// transfer not supported"); segment responses (scs 0, 1: kSegmentedNotSupported); block
/// responses (scs 5, 6: kBlockNotSupported); scs 7 (kUnknownCommand). The multiplexer is filled
/// whenever the DLC is 8, so a client can abort the server's transfer.
Result<SdoResponse> parse_sdo_response(const CanFrame& frame) noexcept;

// ---- server side: the client's requests and the responses --------------------------------------

enum class SdoRequestKind : std::uint8_t { kUpload, kDownload, kAbort };

struct SdoRequest {
  SdoRequestKind kind = SdoRequestKind::kAbort;
  std::uint8_t node_id = 0;  // the server addressed
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  /// kDownload: the value to write (size 0: e = 1, s = 0, the object's size applies).
  SdoData data;
  /// kAbort: the client's abort code.
  std::uint32_t abort_code = 0;
};

/// A client's request (0x601..0x67F). Errors: wrong id, RTR / extended frame, DLC not 8
/// (kWrongDlc); a download with e = 0 or a segment request (ccs 0, 3: kSegmentedNotSupported);
/// block requests (ccs 5, 6: kBlockNotSupported); ccs 7 (kUnknownCommand). Each error carries
/// abort_code 0x05040001 (what the server answers) and, when the DLC is 8, the multiplexer
/// in `value`.
Result<SdoRequest> parse_sdo_request(const CanFrame& frame) noexcept;

/// Expedited upload response with `size` (1..4) bytes. Error kInvalidValue for another size or
/// data that does not fit.
Result<CanFrame> sdo_upload_response(NodeId server, std::uint16_t index, std::uint8_t subindex, std::uint32_t data,
                                     std::uint8_t size) noexcept;
/// Download response: 0x60, multiplexer, zero data.
CanFrame sdo_download_response(NodeId server, std::uint16_t index, std::uint8_t subindex) noexcept;
/// Abort by the server (to 0x580 + node).
CanFrame sdo_abort_response(NodeId server, std::uint16_t index, std::uint8_t subindex,
                            std::uint32_t abort_code) noexcept;

// ---- a client transaction ----------------------------------------------------------------------

enum class SdoClientEventKind : std::uint8_t {
  kNone,        // nothing happened (not this server's frame, no transfer outstanding, no timeout)
  kUploaded,    // the read completed: data
  kDownloaded,  // the write was confirmed
  kAborted,     // the server aborted: abort_code
  kFailed,      // a response the client cannot take (error, detail); abort_frame to send
  kTimedOut,    // no response in time; abort_frame (0x05040000) to send
};

struct SdoClientEvent {
  SdoClientEventKind kind = SdoClientEventKind::kNone;
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  SdoData data;
  std::uint32_t abort_code = 0;
  Error error = Error::kNone;
  const char* detail = "";
  /// kFailed / kTimedOut: the abort the client sends to end the server's side.
  bool send_abort = false;
  CanFrame abort_frame{};
};

/// One outstanding expedited transfer at a time to one server, with a time-out. Pure: the
/// caller sends the frames it returns and passes in the frames it receives.
class SdoClient {
 public:
  /// @throws std::invalid_argument when timeout_ms is 0.
  SdoClient(NodeId server, std::uint32_t timeout_ms);

  /// The request to send; error kBusy while a transfer is outstanding.
  Result<CanFrame> upload(std::uint16_t index, std::uint8_t subindex, std::uint64_t now_ms) noexcept;
  Result<CanFrame> download(std::uint16_t index, std::uint8_t subindex, SdoData data, std::uint64_t now_ms) noexcept;

  /// A received frame. Frames not from this server's 0x580 + node are kNone. A response while
  /// nothing is outstanding is kNone. A response to another multiplexer or of the wrong kind
  /// is kFailed (kUnexpectedResponse) and ends the transfer; an abort is kAborted whatever its
  /// multiplexer.
  SdoClientEvent on_frame(const CanFrame& frame) noexcept;
  /// kTimedOut once when the outstanding transfer is older than timeout_ms.
  SdoClientEvent poll(std::uint64_t now_ms) noexcept;

  bool busy() const noexcept { return busy_; }
  NodeId server() const noexcept { return server_; }

 private:
  SdoClientEvent finish(SdoClientEventKind kind) noexcept;

  NodeId server_;
  std::uint32_t timeout_ms_;
  bool busy_ = false;
  bool uploading_ = false;
  std::uint16_t index_ = 0;
  std::uint8_t subindex_ = 0;
  std::uint64_t started_ms_ = 0;
};

}  // namespace pmlsm::canopen
