// How the parsers, builders and dictionary accesses of pmlsm::canopen report failure: never by
// throwing (they run in the 1 kHz loop), always by a Status naming what is wrong.
//
//   error       the category (Error), kNone on success
//   detail      a static text naming the offending field, e.g. "SDO frame: DLC must be 8";
//               never null, "" on success
//   abort_code  the CiA 301 SDO abort code that goes with the failure when there is one (object
//               dictionary and PDO mapping errors, SDO aborts received), 0 otherwise
#pragma once

#include <cstdint>

namespace pmlsm::canopen {

enum class Error : std::uint8_t {
  kNone,
  kWrongCobId,             // the frame's id is not the one this message uses
  kWrongDlc,               // the data length code does not fit the message
  kRemoteFrame,            // an RTR frame where a data frame is expected
  kExtendedFrame,          // a 29-bit identifier where CANopen uses 11-bit ones
  kInvalidNodeId,          // a node id outside 1..127 (or 0..127 where 0 means "all")
  kUnknownCommand,         // a command byte / command specifier the protocol does not define
  kInvalidValue,           // a field holds a value the protocol does not allow
  kSegmentedNotSupported,  // SDO segmented transfer (values over 4 bytes): not implemented
  kBlockNotSupported,      // SDO block transfer: not implemented
  kUnexpectedResponse,     // an SDO response that does not answer the outstanding request
  kSdoAborted,             // the peer aborted the SDO transfer (abort_code says why)
  kBusy,                   // an SDO client already has a transfer outstanding
  kTimeout,                // no answer in time
  kAccessRefused,          // the object dictionary refused the access (abort_code says why)
  kPdoMapping,             // the PDO mapping is not valid (abort_code says why)
};

/// A short lower-case name: "no error", "wrong COB-ID", "wrong DLC", "remote frame",
/// "extended frame", "invalid node id", "unknown command", "invalid value",
/// "segmented transfer not supported", "block transfer not supported", "unexpected response",
/// "SDO transfer aborted", "busy", "timeout", "access refused", "invalid PDO mapping"
/// ("unknown" outside the enum).
const char* to_string(Error error) noexcept;

struct Status {
  Error error = Error::kNone;
  const char* detail = "";
  std::uint32_t abort_code = 0;

  constexpr bool ok() const noexcept { return error == Error::kNone; }
  constexpr explicit operator bool() const noexcept { return ok(); }
};

/// A Status with a value. On failure `value` is default-constructed unless the function says
/// it fills part of it (e.g. the SDO multiplexer of a refused request).
template <typename T>
struct Result : Status {
  T value{};
};

constexpr Status fail(Error error, const char* detail, std::uint32_t abort_code = 0) noexcept {
  return Status{error, detail, abort_code};
}

template <typename T>
constexpr Result<T> fail_with(Error error, const char* detail, std::uint32_t abort_code = 0) noexcept {
  Result<T> result;
  result.error = error;
  result.detail = detail;
  result.abort_code = abort_code;
  return result;
}

template <typename T>
constexpr Result<T> success(const T& value) noexcept {
  Result<T> result;
  result.value = value;
  return result;
}

}  // namespace pmlsm::canopen
