// pycan_wire: python-can 4.1's udp_multicast datagram format. Byte-exact against datagrams
// python-can itself packed, every frame shape round trips, every malformed shape is rejected
// for its reason, and arbitrary bytes never crash the decoder.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "can_test_support.hpp"
#include "pmlsm/can/can_bus.hpp"
#include "pmlsm/can/pycan_wire.hpp"

namespace pmlsm::can {
namespace {

using namespace test;
using pycan_wire::DecodeStatus;

// Packed by python-can 4.1's can.interfaces.udp_multicast.utils.pack_message() with msgpack
// 1.0.3 (Debian bookworm):
//   Message(timestamp=0.0, arbitration_id=0x123, is_extended_id=False, data=[1, 2, 3])
const char* kPythonStd =
    "8ba974696d657374616d70cb0000000000000000ae6172626974726174696f6e5f6964cd0123ae69735f657874"
    "656e6465645f6964c2af69735f72656d6f74655f6672616d65c2ae69735f6572726f725f6672616d65c2a76368"
    "616e6e656cc0a3646c6303a464617461c403010203a569735f6664c2ae626974726174655f737769746368c2b5"
    "6572726f725f73746174655f696e64696361746f72c2";
//   Message(timestamp=0.0, arbitration_id=0x1ABCDEF, is_extended_id=True, is_remote_frame=True, dlc=5)
const char* kPythonExtRtr =
    "8ba974696d657374616d70cb0000000000000000ae6172626974726174696f6e5f6964ce01abcdefae69735f65"
    "7874656e6465645f6964c3af69735f72656d6f74655f6672616d65c3ae69735f6572726f725f6672616d65c2a7"
    "6368616e6e656cc0a3646c6305a464617461c400a569735f6664c2ae626974726174655f737769746368c2b565"
    "72726f725f73746174655f696e64696361746f72c2";
//   Message(timestamp=1.5, arbitration_id=0x1FFFFFFF, is_extended_id=True,
//           data=bytes([0, 0x7f, 0x80, 0xff, 1, 2, 3, 4]))
const char* kPythonExtFull =
    "8ba974696d657374616d70cb3ff8000000000000ae6172626974726174696f6e5f6964ce1fffffffae69735f65"
    "7874656e6465645f6964c3af69735f72656d6f74655f6672616d65c2ae69735f6572726f725f6672616d65c2a7"
    "6368616e6e656cc0a3646c6308a464617461c408007f80ff01020304a569735f6664c2ae626974726174655f73"
    "7769746368c2b56572726f725f73746174655f696e64696361746f72c2";

std::vector<std::uint8_t> encode(const CanFrame& f, double timestamp = 0.0) {
  std::array<std::uint8_t, pycan_wire::kMaxEncodedSize> buffer{};
  const std::size_t n = pycan_wire::encode(f, timestamp, buffer.data(), buffer.size());
  return {buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(n)};
}

void expect_frame(const CanFrame& got, std::uint32_t id, bool extended, bool rtr, std::uint8_t dlc,
                  std::vector<std::uint8_t> data) {
  EXPECT_EQ(got.id, id);
  EXPECT_EQ(got.extended, extended);
  EXPECT_EQ(got.rtr, rtr);
  EXPECT_EQ(got.dlc, dlc);
  data.resize(8, 0);
  for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(got.data[i], data[i]) << "data[" << i << "]";
}

TEST(PycanWire, EncodesByteForByteAsPythonCan) {
  EXPECT_EQ(encode(CanFrame{0x123, 3, {1, 2, 3, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE}, false, false}), from_hex(kPythonStd))
      << "bytes past dlc must not be sent";
  EXPECT_EQ(encode(CanFrame{0x1ABCDEF, 5, {9, 9, 9, 9, 9, 9, 9, 9}, true, true}), from_hex(kPythonExtRtr))
      << "a remote frame carries no data";
  EXPECT_EQ(encode(CanFrame{0x1FFFFFFF, 8, {0, 0x7F, 0x80, 0xFF, 1, 2, 3, 4}, false, true}, 1.5),
            from_hex(kPythonExtFull));
  EXPECT_EQ(from_hex(kPythonExtFull).size(), 164u) << "the largest classic frame";
  EXPECT_LE(164u, pycan_wire::kMaxEncodedSize);
}

TEST(PycanWire, DecodesPythonCanDatagrams) {
  CanFrame f{};
  auto d = from_hex(kPythonStd);
  ASSERT_EQ(pycan_wire::decode(d.data(), d.size(), f).status, DecodeStatus::ok);
  expect_frame(f, 0x123, false, false, 3, {1, 2, 3});
  d = from_hex(kPythonExtRtr);
  ASSERT_EQ(pycan_wire::decode(d.data(), d.size(), f).status, DecodeStatus::ok);
  expect_frame(f, 0x1ABCDEF, true, true, 5, {});
  d = from_hex(kPythonExtFull);
  ASSERT_EQ(pycan_wire::decode(d.data(), d.size(), f).status, DecodeStatus::ok);
  expect_frame(f, 0x1FFFFFFF, true, false, 8, {0, 0x7F, 0x80, 0xFF, 1, 2, 3, 4});
}

TEST(PycanWire, EveryFrameShapeRoundTrips) {
  const std::vector<std::pair<std::uint32_t, bool>> ids = {{0, false},     {1, false},        {0x123, false},
                                                           {0x7FF, false}, {0, true},         {0x7FF, true},
                                                           {0x800, true},  {0x1ABCDEF, true}, {0x1FFFFFFF, true}};
  int cases = 0;
  for (const auto& [id, extended] : ids) {
    for (std::uint8_t dlc = 0; dlc <= 8; ++dlc) {
      for (bool rtr : {false, true}) {
        const CanFrame sent = make_frame(id, extended, rtr, dlc, static_cast<std::uint8_t>(id + dlc));
        const auto bytes = encode(sent, 1234.5);
        ASSERT_FALSE(bytes.empty());
        CanFrame got{};
        got.data.fill(0xCC);
        const auto result = pycan_wire::decode(bytes.data(), bytes.size(), got);
        ASSERT_EQ(result.status, DecodeStatus::ok) << sent << ": " << result.reason;
        EXPECT_EQ(got.id, sent.id) << sent;
        EXPECT_EQ(got.extended, sent.extended) << sent;
        EXPECT_EQ(got.rtr, sent.rtr) << sent;
        EXPECT_EQ(got.dlc, sent.dlc) << sent;
        EXPECT_EQ(got.data, sent.data) << sent;
        ++cases;
      }
    }
  }
  EXPECT_EQ(cases, 9 * 9 * 2);
}

TEST(PycanWire, EncodeRefusesInvalidFramesAndSmallBuffers) {
  std::array<std::uint8_t, pycan_wire::kMaxEncodedSize> buffer{};
  EXPECT_EQ(pycan_wire::encode(CanFrame{0x800, 0, {}, false, false}, 0, buffer.data(), buffer.size()), 0u);
  EXPECT_EQ(pycan_wire::encode(CanFrame{0x20000000, 0, {}, false, true}, 0, buffer.data(), buffer.size()), 0u);
  EXPECT_EQ(pycan_wire::encode(CanFrame{1, 9, {}, false, false}, 0, buffer.data(), buffer.size()), 0u);
  EXPECT_EQ(pycan_wire::encode(CanFrame{1, 8, {}, false, false}, 0, buffer.data(), 100), 0u);
  EXPECT_EQ(pycan_wire::encode(CanFrame{1, 8, {}, false, false}, 0, nullptr, buffer.size()), 0u);
}

TEST(PycanWire, AcceptsOtherEncodersChoices) {
  CanFrame f{};
  // Key order, wider integer encodings, signed positive integers, data as an int array or
  // nil, unknown keys and nested values are all fine.
  auto fields = python_fields(0x42, false, false, 2, {7, 8});
  std::reverse(fields.begin(), fields.end());
  fields = with(fields, "arbitration_id", [](Packer& pk) { pk.pack_fix_uint32(0x42); });
  fields = with(fields, "dlc", [](Packer& pk) { pk.pack_fix_int8(2); });
  fields = with(fields, "channel", [](Packer& pk) {
    pk.pack_array(2);
    pk.pack_map(1);
    pk.pack_str(1);
    pk.pack_str_body("k", 1);
    float64_value(1.0)(pk);
    pk.pack_str(3);
    pk.pack_str_body("vcan", 3);
  });
  fields.push_back({"is_rx", bool_value(true)});
  fields.push_back({"something_new", [](Packer& pk) {
                      pk.pack_ext(2, 7);
                      pk.pack_ext_body("ab", 2);
                    }});
  auto d = pack(fields);
  auto r = pycan_wire::decode(d.data(), d.size(), f);
  ASSERT_EQ(r.status, DecodeStatus::ok) << r.reason;
  expect_frame(f, 0x42, false, false, 2, {7, 8});

  d = pack(with(python_fields(0x42, false, false, 3, {}), "data", [](Packer& pk) {
    pk.pack_array(3);
    pk.pack_uint8(0);
    pk.pack_uint8(128);
    pk.pack_uint8(255);
  }));
  r = pycan_wire::decode(d.data(), d.size(), f);
  ASSERT_EQ(r.status, DecodeStatus::ok) << r.reason;
  expect_frame(f, 0x42, false, false, 3, {0, 128, 255});

  d = pack(with(python_fields(0x42, false, false, 0, {}), "data", [](Packer& pk) { pk.pack_nil(); }));
  ASSERT_EQ(pycan_wire::decode(d.data(), d.size(), f).status, DecodeStatus::ok);
  expect_frame(f, 0x42, false, false, 0, {});

  // python-can's own (optional) fields may be missing.
  d = pack(without(without(python_fields(0x42, true, false, 1, {5}), "is_fd"), "timestamp"));
  ASSERT_EQ(pycan_wire::decode(d.data(), d.size(), f).status, DecodeStatus::ok);
  expect_frame(f, 0x42, true, false, 1, {5});

  // Remote frames: the data field is ignored (as python-can does), within 8 bytes.
  d = pack(python_fields(0x42, false, true, 4, {1, 2}));
  ASSERT_EQ(pycan_wire::decode(d.data(), d.size(), f).status, DecodeStatus::ok);
  expect_frame(f, 0x42, false, true, 4, {});
}

struct BadCase {
  const char* name;
  std::vector<std::uint8_t> bytes;
  DecodeStatus status;
  const char* reason;
};

std::vector<BadCase> bad_cases() {
  const auto ok = python_fields(0x123, false, false, 2, {1, 2});
  auto valid = pack(ok);
  auto trailing = valid;
  trailing.push_back(0xC0);
  auto truncated = std::vector<std::uint8_t>(valid.begin(), valid.begin() + 60);
  const std::string text = "hello, not msgpack";
  return {
      {"empty", {}, DecodeStatus::malformed, "empty datagram"},
      {"text", {text.begin(), text.end()}, DecodeStatus::malformed, "not a MessagePack map"},
      {"reserved byte 0xc1", {0xC1}, DecodeStatus::malformed, "not MessagePack"},
      {"array", from_hex("93010203"), DecodeStatus::malformed, "not a MessagePack map"},
      {"truncated", truncated, DecodeStatus::malformed, "truncated"},
      {"trailing bytes", trailing, DecodeStatus::malformed, "trailing bytes after the map"},
      {"huge map count", from_hex("dfffffffff"), DecodeStatus::malformed, "too many keys"},
      {"huge bin length", from_hex("81a464617461c6ffffffff00"), DecodeStatus::malformed, "truncated data"},
      {"huge nested array", from_hex("81a178ddffffffff"), DecodeStatus::malformed, "truncated value"},
      {"integer key", from_hex("8101c0"), DecodeStatus::malformed, "map key is not a string"},
      {"missing arbitration_id", pack(without(ok, "arbitration_id")), DecodeStatus::malformed,
       "missing arbitration_id"},
      {"missing is_extended_id", pack(without(ok, "is_extended_id")), DecodeStatus::malformed,
       "missing is_extended_id"},
      {"missing is_remote_frame", pack(without(ok, "is_remote_frame")), DecodeStatus::malformed,
       "missing is_remote_frame"},
      {"missing dlc", pack(without(ok, "dlc")), DecodeStatus::malformed, "missing dlc"},
      {"missing data", pack(without(ok, "data")), DecodeStatus::malformed, "missing data"},
      {"dlc 9", pack(python_fields(0x123, false, false, 9, {1, 2, 3, 4, 5, 6, 7, 8, 9})), DecodeStatus::malformed,
       "dlc > 8"},
      {"data 9 bytes", pack(python_fields(0x123, false, false, 8, {1, 2, 3, 4, 5, 6, 7, 8, 9})),
       DecodeStatus::malformed, "data longer than 8 bytes"},
      {"data 9-element array",
       pack(with(ok, "data",
                 [](Packer& pk) {
                   pk.pack_array(9);
                   for (int i = 0; i < 9; ++i) pk.pack_uint8(1);
                 })),
       DecodeStatus::malformed, "data longer than 8 bytes"},
      {"data array element 256",
       pack(with(ok, "data",
                 [](Packer& pk) {
                   pk.pack_array(2);
                   pk.pack_uint8(1);
                   pk.pack_uint16(256);
                 })),
       DecodeStatus::malformed, "data array element is not a byte"},
      {"data shorter than dlc", pack(python_fields(0x123, false, false, 3, {1, 2})), DecodeStatus::malformed,
       "data length differs from dlc"},
      {"data longer than dlc", pack(python_fields(0x123, false, false, 1, {1, 2})), DecodeStatus::malformed,
       "data length differs from dlc"},
      {"standard id 0x800", pack(python_fields(0x800, false, false, 0, {})), DecodeStatus::malformed,
       "standard arbitration_id exceeds 11 bits"},
      {"extended id 2^29", pack(python_fields(0x20000000, true, false, 0, {})), DecodeStatus::malformed,
       "extended arbitration_id exceeds 29 bits"},
      {"id 2^64-1", pack(with(ok, "arbitration_id", uint_value(~0ull))), DecodeStatus::malformed,
       "standard arbitration_id exceeds 11 bits"},
      {"negative id", pack(with(ok, "arbitration_id", int_value(-1))), DecodeStatus::malformed,
       "arbitration_id is negative"},
      {"negative dlc", pack(with(ok, "dlc", int_value(-2))), DecodeStatus::malformed, "dlc is negative"},
      {"id as string", pack(with(ok, "arbitration_id", str_value("291"))), DecodeStatus::malformed,
       "arbitration_id is not an integer"},
      {"id as float", pack(with(ok, "arbitration_id", float64_value(291.0))), DecodeStatus::malformed,
       "arbitration_id is not an integer"},
      {"is_extended_id as int", pack(with(ok, "is_extended_id", uint_value(1))), DecodeStatus::malformed,
       "is_extended_id is not a bool"},
      {"is_remote_frame nil", pack(with(ok, "is_remote_frame", [](Packer& pk) { pk.pack_nil(); })),
       DecodeStatus::malformed, "is_remote_frame is not a bool"},
      {"data as string", pack(with(ok, "data", str_value("ab"))), DecodeStatus::malformed,
       "data is not bin, nil or an array"},
      {"bitrate_switch on classic", pack(with(ok, "bitrate_switch", bool_value(true))), DecodeStatus::malformed,
       "bitrate_switch/error_state_indicator set on a classic frame"},
      {"remote frame with 9 data bytes", pack(python_fields(0x123, false, true, 2, {1, 2, 3, 4, 5, 6, 7, 8, 9})),
       DecodeStatus::malformed, "data longer than 8 bytes"},
      {"CAN FD frame",
       pack(with(python_fields(0x123, false, false, 12, std::vector<std::uint8_t>(12, 1)), "is_fd", bool_value(true))),
       DecodeStatus::unsupported, "CAN FD frame"},
      {"error frame", pack(with(ok, "is_error_frame", bool_value(true))), DecodeStatus::unsupported, "error frame"},
  };
}

TEST(PycanWire, RejectsEveryMalformedShapeForItsReason) {
  for (const BadCase& c : bad_cases()) {
    CanFrame f{};
    const auto r = pycan_wire::decode(c.bytes.data(), c.bytes.size(), f);
    EXPECT_EQ(r.status, c.status) << c.name;
    EXPECT_NE(std::string(r.reason).find(c.reason), std::string::npos)
        << c.name << ": got reason \"" << r.reason << "\", want \"" << c.reason << "\"";
  }
}

// Random bytes, and valid datagrams with bytes flipped, cut or inserted: the decoder must
// return (ok only with a valid frame), never read out of bounds (run under ASan/UBSan too).
TEST(PycanWire, SurvivesArbitraryBytes) {
  std::mt19937 rng(20240917);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<std::vector<std::uint8_t>> seeds;
  for (std::uint8_t dlc = 0; dlc <= 8; ++dlc) seeds.push_back(encode(make_frame(0x7F0 + dlc, false, false, dlc, dlc)));
  seeds.push_back(from_hex(kPythonExtRtr));
  int ok = 0;
  for (int i = 0; i < 200000; ++i) {
    std::vector<std::uint8_t> d;
    if (i % 4 == 0) {
      d.resize(static_cast<std::size_t>(byte(rng)) % 48);
      for (auto& b : d) b = static_cast<std::uint8_t>(byte(rng));
    } else {
      d = seeds[static_cast<std::size_t>(i) % seeds.size()];
      const int edits = 1 + byte(rng) % 4;
      for (int e = 0; e < edits && !d.empty(); ++e) {
        const std::size_t at = static_cast<std::size_t>(byte(rng) * 256 + byte(rng)) % d.size();
        switch (byte(rng) % 3) {
          case 0: d[at] = static_cast<std::uint8_t>(byte(rng)); break;
          case 1: d.resize(at); break;
          default: d.insert(d.begin() + static_cast<std::ptrdiff_t>(at), static_cast<std::uint8_t>(byte(rng)));
        }
      }
    }
    // Exactly-sized heap copy, so ASan catches any read past the end.
    std::unique_ptr<std::uint8_t[]> exact(new std::uint8_t[d.size() + (d.empty() ? 1 : 0)]);
    if (!d.empty()) std::memcpy(exact.get(), d.data(), d.size());
    CanFrame f{};
    const auto r = pycan_wire::decode(exact.get(), d.size(), f);
    ASSERT_NE(r.reason, nullptr);
    if (r.status == DecodeStatus::ok) {
      ++ok;
      EXPECT_TRUE(is_valid_frame(f));
      if (f.rtr) {
        for (std::uint8_t b : f.data) EXPECT_EQ(b, 0);
      }
      for (std::size_t k = f.dlc; k < 8; ++k) EXPECT_EQ(f.data[k], 0);
    }
  }
  EXPECT_GT(ok, 0) << "some mutations (e.g. a changed data byte) stay valid";
}

}  // namespace
}  // namespace pmlsm::can
