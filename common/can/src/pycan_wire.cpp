// python-can's udp_multicast wire format: encoding with msgpack-c's packer into a fixed
// buffer, decoding with a small bounded reader (msgpack-c's unpacker allocates zones and
// parse stacks and reports malformed input by throwing; a receive path must do neither).
#include "pmlsm/can/pycan_wire.hpp"

#include <array>
#include <cstring>

#ifndef MSGPACK_NO_BOOST
#define MSGPACK_NO_BOOST
#endif
#include <msgpack.hpp>

#include "pmlsm/can/can_bus.hpp"

namespace pmlsm::can::pycan_wire {
namespace {

// msgpack-c stream over a caller's buffer; an overflow is remembered, never thrown.
class FixedStream {
 public:
  FixedStream(std::uint8_t* out, std::size_t capacity) noexcept : out_(out), capacity_(capacity) {}
  void write(const char* bytes, std::size_t n) noexcept {
    if (overflow_ || n > capacity_ - size_) {
      overflow_ = true;
      return;
    }
    std::memcpy(out_ + size_, bytes, n);
    size_ += n;
  }
  std::size_t size() const noexcept { return overflow_ ? 0 : size_; }

 private:
  std::uint8_t* out_;
  std::size_t capacity_;
  std::size_t size_ = 0;
  bool overflow_ = false;
};

template <typename Packer>
void pack_key(Packer& pk, const char* key) {
  const auto n = static_cast<std::uint32_t>(std::strlen(key));
  pk.pack_str(n);
  pk.pack_str_body(key, n);
}

// A MessagePack float 64, as Python packs its floats. (msgpack-c 4's pack_double() packs
// integral values such as 0.0 as integers.)
void write_float64(FixedStream& stream, double value) noexcept {
  std::uint64_t bits = 0;
  static_assert(sizeof bits == sizeof value, "IEEE 754 binary64 double");
  std::memcpy(&bits, &value, sizeof bits);
  char bytes[9] = {static_cast<char>(0xCB)};
  for (int i = 0; i < 8; ++i) bytes[1 + i] = static_cast<char>(bits >> (56 - 8 * i));
  stream.write(bytes, sizeof bytes);
}

template <typename Packer>
void pack_bool(Packer& pk, bool value) {
  if (value) {
    pk.pack_true();
  } else {
    pk.pack_false();
  }
}

// ---- decoding -------------------------------------------------------------------------

enum class Kind { nil, boolean, uint, nint, real, str, bin, array, map, ext };

struct Value {
  Kind kind = Kind::nil;
  bool boolean = false;
  std::uint64_t uint = 0;               // Kind::uint
  const std::uint8_t* bytes = nullptr;  // Kind::str, Kind::bin: the body
  std::uint32_t length = 0;             // str/bin: bytes; array: elements; map: pairs
};

class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size) noexcept : p_(data), end_(data + size) {}

  bool at_end() const noexcept { return p_ == end_; }

  // One value's header; the body of str, bin and ext is consumed (bounds checked), the
  // elements of array and map are not.
  bool header(Value& v) noexcept {
    std::uint8_t tag = 0;
    if (!u8(tag)) return false;
    if (tag <= 0x7F) return set_uint(v, tag);
    if (tag >= 0xE0) return set_nint(v);
    if (tag >= 0x80 && tag <= 0x8F) return set_container(v, Kind::map, tag & 0x0Fu);
    if (tag >= 0x90 && tag <= 0x9F) return set_container(v, Kind::array, tag & 0x0Fu);
    if (tag >= 0xA0 && tag <= 0xBF) return set_bytes(v, Kind::str, tag & 0x1Fu);
    std::uint64_t n = 0;
    switch (tag) {
      case 0xC0: v.kind = Kind::nil; return true;
      case 0xC2:
      case 0xC3:
        v.kind = Kind::boolean;
        v.boolean = tag == 0xC3;
        return true;
      case 0xC4: return be(1, n) && set_bytes(v, Kind::bin, n);
      case 0xC5: return be(2, n) && set_bytes(v, Kind::bin, n);
      case 0xC6: return be(4, n) && set_bytes(v, Kind::bin, n);
      case 0xC7: return be(1, n) && skip(1 + n) && set_kind(v, Kind::ext);
      case 0xC8: return be(2, n) && skip(1 + n) && set_kind(v, Kind::ext);
      case 0xC9: return be(4, n) && skip(1 + n) && set_kind(v, Kind::ext);
      case 0xCA: return skip(4) && set_kind(v, Kind::real);
      case 0xCB: return skip(8) && set_kind(v, Kind::real);
      case 0xCC: return be(1, n) && set_uint(v, n);
      case 0xCD: return be(2, n) && set_uint(v, n);
      case 0xCE: return be(4, n) && set_uint(v, n);
      case 0xCF: return be(8, n) && set_uint(v, n);
      case 0xD0: return be(1, n) && set_signed(v, n, 8);
      case 0xD1: return be(2, n) && set_signed(v, n, 16);
      case 0xD2: return be(4, n) && set_signed(v, n, 32);
      case 0xD3: return be(8, n) && set_signed(v, n, 64);
      case 0xD4: return skip(1 + 1) && set_kind(v, Kind::ext);
      case 0xD5: return skip(1 + 2) && set_kind(v, Kind::ext);
      case 0xD6: return skip(1 + 4) && set_kind(v, Kind::ext);
      case 0xD7: return skip(1 + 8) && set_kind(v, Kind::ext);
      case 0xD8: return skip(1 + 16) && set_kind(v, Kind::ext);
      case 0xD9: return be(1, n) && set_bytes(v, Kind::str, n);
      case 0xDA: return be(2, n) && set_bytes(v, Kind::str, n);
      case 0xDB: return be(4, n) && set_bytes(v, Kind::str, n);
      case 0xDC: return be(2, n) && set_container(v, Kind::array, n);
      case 0xDD: return be(4, n) && set_container(v, Kind::array, n);
      case 0xDE: return be(2, n) && set_container(v, Kind::map, n);
      case 0xDF: return be(4, n) && set_container(v, Kind::map, n);
      default: return false;  // 0xC1: never used
    }
  }

  // Skips one complete value, nested ones included. Every element takes at least one
  // byte, so this ends within size() steps whatever the declared counts.
  bool skip_value() noexcept {
    std::uint64_t pending = 1;
    while (pending > 0) {
      --pending;
      Value v;
      if (!header(v)) return false;
      if (v.kind == Kind::array) pending += v.length;
      if (v.kind == Kind::map) pending += 2ull * v.length;
    }
    return true;
  }

 private:
  std::size_t left() const noexcept { return static_cast<std::size_t>(end_ - p_); }
  bool u8(std::uint8_t& out) noexcept {
    if (p_ == end_) return false;
    out = *p_++;
    return true;
  }
  bool be(std::size_t bytes, std::uint64_t& out) noexcept {
    if (left() < bytes) return false;
    out = 0;
    for (std::size_t i = 0; i < bytes; ++i) out = (out << 8) | *p_++;
    return true;
  }
  bool skip(std::uint64_t n) noexcept {
    if (left() < n) return false;
    p_ += n;
    return true;
  }
  static bool set_kind(Value& v, Kind kind) noexcept {
    v.kind = kind;
    return true;
  }
  static bool set_uint(Value& v, std::uint64_t n) noexcept {
    v.kind = Kind::uint;
    v.uint = n;
    return true;
  }
  static bool set_nint(Value& v) noexcept { return set_kind(v, Kind::nint); }
  static bool set_signed(Value& v, std::uint64_t raw, int bits) noexcept {
    const bool negative = (raw >> (bits - 1)) & 1u;
    return negative ? set_nint(v) : set_uint(v, raw);
  }
  bool set_bytes(Value& v, Kind kind, std::uint64_t n) noexcept {
    if (left() < n) return false;
    v.kind = kind;
    v.bytes = p_;
    v.length = static_cast<std::uint32_t>(n);
    p_ += n;
    return true;
  }
  static bool set_container(Value& v, Kind kind, std::uint64_t n) noexcept {
    v.kind = kind;
    v.length = static_cast<std::uint32_t>(n);
    return true;
  }

  const std::uint8_t* p_;
  const std::uint8_t* end_;
};

bool key_is(const Value& key, const char* name) noexcept {
  const std::size_t n = std::strlen(name);
  return key.length == n && std::memcmp(key.bytes, name, n) == 0;
}

constexpr std::uint32_t kMaxKeys = 64;

DecodeResult malformed(const char* reason) noexcept { return {DecodeStatus::malformed, reason}; }

// Reads a bool field's value: nullptr when fine, else why not.
const char* bool_field(Reader& r, bool& out, const char* not_bool) noexcept {
  Value v;
  if (!r.header(v)) return "truncated value";
  if (v.kind != Kind::boolean) return not_bool;
  out = v.boolean;
  return nullptr;
}

// Reads a non-negative integer field's value: nullptr when fine, else why not.
const char* uint_field(Reader& r, std::uint64_t& out, const char* negative, const char* not_integer) noexcept {
  Value v;
  if (!r.header(v)) return "truncated value";
  if (v.kind == Kind::nint) return negative;
  if (v.kind != Kind::uint) return not_integer;
  out = v.uint;
  return nullptr;
}

}  // namespace

std::size_t encode(const CanFrame& frame, double timestamp_s, std::uint8_t* out, std::size_t capacity) noexcept {
  if (!is_valid_frame(frame) || out == nullptr) return 0;
  FixedStream stream(out, capacity);
  msgpack::packer<FixedStream> pk(stream);
  const std::uint32_t payload = frame.rtr ? 0u : frame.dlc;
  // The keys and their order of python-can 4.1's pack_message().
  pk.pack_map(11);
  pack_key(pk, "timestamp");
  write_float64(stream, timestamp_s);  // the packer writes through, unbuffered
  pack_key(pk, "arbitration_id");
  pk.pack_uint32(frame.id);
  pack_key(pk, "is_extended_id");
  pack_bool(pk, frame.extended);
  pack_key(pk, "is_remote_frame");
  pack_bool(pk, frame.rtr);
  pack_key(pk, "is_error_frame");
  pk.pack_false();
  pack_key(pk, "channel");
  pk.pack_nil();
  pack_key(pk, "dlc");
  pk.pack_uint8(frame.dlc);
  pack_key(pk, "data");
  pk.pack_bin(payload);
  pk.pack_bin_body(reinterpret_cast<const char*>(frame.data.data()), payload);
  pack_key(pk, "is_fd");
  pk.pack_false();
  pack_key(pk, "bitrate_switch");
  pk.pack_false();
  pack_key(pk, "error_state_indicator");
  pk.pack_false();
  return stream.size();
}

// One walk over python-can's msgpack map, a branch per key it writes; kept whole so every key's
// check sits beside the key, as the wire format lists them.
// NOLINTNEXTLINE(readability-function-size)
DecodeResult decode(const std::uint8_t* data, std::size_t size, CanFrame& frame) noexcept {
  if (data == nullptr || size == 0) return malformed("empty datagram");
  Reader r(data, size);
  Value top;
  if (!r.header(top)) return malformed("not MessagePack");
  if (top.kind != Kind::map) return malformed("not a MessagePack map");
  if (top.length > kMaxKeys) return malformed("too many keys");

  bool have_id = false, have_extended = false, have_rtr = false, have_dlc = false, have_data = false;
  std::uint64_t id = 0, dlc = 0;
  bool extended = false, rtr = false, error_frame = false, fd = false, brs = false, esi = false;
  std::array<std::uint8_t, 8> bytes{};
  std::uint64_t data_length = 0;

  for (std::uint32_t i = 0; i < top.length; ++i) {
    Value key;
    if (!r.header(key)) return malformed("truncated map");
    if (key.kind != Kind::str) return malformed("map key is not a string");

    const char* bad = nullptr;
    if (key_is(key, "arbitration_id")) {
      bad = uint_field(r, id, "arbitration_id is negative", "arbitration_id is not an integer");
      have_id = true;
    } else if (key_is(key, "dlc")) {
      bad = uint_field(r, dlc, "dlc is negative", "dlc is not an integer");
      have_dlc = true;
    } else if (key_is(key, "is_extended_id")) {
      bad = bool_field(r, extended, "is_extended_id is not a bool");
      have_extended = true;
    } else if (key_is(key, "is_remote_frame")) {
      bad = bool_field(r, rtr, "is_remote_frame is not a bool");
      have_rtr = true;
    } else if (key_is(key, "is_error_frame")) {
      bad = bool_field(r, error_frame, "is_error_frame is not a bool");
    } else if (key_is(key, "is_fd")) {
      bad = bool_field(r, fd, "is_fd is not a bool");
    } else if (key_is(key, "bitrate_switch")) {
      bad = bool_field(r, brs, "bitrate_switch is not a bool");
    } else if (key_is(key, "error_state_indicator")) {
      bad = bool_field(r, esi, "error_state_indicator is not a bool");
    } else if (key_is(key, "data")) {
      Value v;
      if (!r.header(v)) return malformed("truncated data");
      bytes.fill(0);
      if (v.kind == Kind::nil) {
        data_length = 0;
      } else if (v.kind == Kind::bin) {
        data_length = v.length;
        if (data_length <= bytes.size()) std::memcpy(bytes.data(), v.bytes, v.length);
      } else if (v.kind == Kind::array) {
        data_length = v.length;
        for (std::uint32_t k = 0; k < v.length; ++k) {
          std::uint64_t byte = 0;
          if (const char* why =
                  uint_field(r, byte, "data array element is not a byte", "data array element is not a byte")) {
            return malformed(why);
          }
          if (byte > 0xFF) return malformed("data array element is not a byte");
          if (k < bytes.size()) bytes[k] = static_cast<std::uint8_t>(byte);
        }
      } else {
        return malformed("data is not bin, nil or an array");
      }
      have_data = true;
    } else {
      // timestamp (receivers take their own, as python-can does), channel, unknown keys.
      if (!r.skip_value()) return malformed("truncated value");
    }
    if (bad != nullptr) return malformed(bad);
  }
  if (!r.at_end()) return malformed("trailing bytes after the map");

  if (!have_id) return malformed("missing arbitration_id");
  if (!have_extended) return malformed("missing is_extended_id");
  if (!have_rtr) return malformed("missing is_remote_frame");
  if (!have_dlc) return malformed("missing dlc");
  if (!have_data) return malformed("missing data");

  if (error_frame) return {DecodeStatus::unsupported, "error frame"};
  if (fd) return {DecodeStatus::unsupported, "CAN FD frame"};
  if (brs || esi) return malformed("bitrate_switch/error_state_indicator set on a classic frame");
  if (extended && id > kMaxExtendedId) return malformed("extended arbitration_id exceeds 29 bits");
  if (!extended && id > kMaxStandardId) return malformed("standard arbitration_id exceeds 11 bits");
  if (dlc > kMaxClassicDlc) return malformed("dlc > 8");
  if (data_length > bytes.size()) return malformed("data longer than 8 bytes");
  if (!rtr && data_length != dlc) return malformed("data length differs from dlc");

  frame.id = static_cast<std::uint32_t>(id);
  frame.dlc = static_cast<std::uint8_t>(dlc);
  frame.extended = extended;
  frame.rtr = rtr;
  if (rtr) bytes.fill(0);
  frame.data = bytes;
  return {DecodeStatus::ok, ""};
}

}  // namespace pmlsm::can::pycan_wire
