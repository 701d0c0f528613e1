// The IDL parser and the CDR decoder on their own (no DDS): hand-made samples in both byte
// orders, the IDL features beyond the project's own files, malformed samples, bad IDL, and the
// YAML/text forms.

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#include "pmlsm/introspect/cdr_schema.hpp"

namespace {

using pmlsm::introspect::Decoded;
using pmlsm::introspect::Field;
using pmlsm::introspect::MessageSchema;
using pmlsm::introspect::SchemaError;
using Bytes = std::vector<std::uint8_t>;

/// Plain CDR the test way: header, then each value aligned to its size from after the header.
class CdrWriter {
 public:
  explicit CdrWriter(bool little_endian)
      : little_endian_(little_endian), bytes_{0, little_endian ? std::uint8_t{1} : std::uint8_t{0}, 0, 0} {}

  template <class T>
  CdrWriter& put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    std::uint64_t bits = 0;
    if constexpr (std::is_floating_point_v<T>) {
      std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t> raw = 0;
      std::memcpy(&raw, &value, sizeof value);
      bits = raw;
    } else {
      bits = static_cast<std::uint64_t>(value);
    }
    while ((bytes_.size() - 4) % sizeof(T) != 0) bytes_.push_back(0);
    for (std::size_t i = 0; i < sizeof(T); ++i) {
      const std::size_t shift = 8 * (little_endian_ ? i : sizeof(T) - 1 - i);
      bytes_.push_back(static_cast<std::uint8_t>(bits >> shift));
    }
    return *this;
  }
  CdrWriter& text(const std::string& value) {
    put(static_cast<std::uint32_t>(value.size() + 1));
    bytes_.insert(bytes_.end(), value.begin(), value.end());
    bytes_.push_back(0);
    return *this;
  }
  const Bytes& bytes() const { return bytes_; }

 private:
  bool little_endian_;
  Bytes bytes_;
};

constexpr const char* kSmallIdl = R"(
module t {
  struct Small {
    uint16 a;
    double b;
    string<8> name;
    sequence<int32, 4> values;
    boolean flag;
  };
};
)";

void expect_small_fields(const Decoded& decoded) {
  ASSERT_TRUE(decoded.ok()) << decoded.error;
  ASSERT_EQ(decoded.fields.size(), 6U);
  EXPECT_EQ(decoded.fields[0].path, "a");
  EXPECT_EQ(std::get<std::uint64_t>(decoded.fields[0].value), 0x0102U);
  EXPECT_EQ(decoded.fields[1].path, "b");
  EXPECT_EQ(std::get<double>(decoded.fields[1].value), 1.5);
  EXPECT_EQ(decoded.fields[2].path, "name");
  EXPECT_EQ(std::get<std::string>(decoded.fields[2].value), "abc");
  EXPECT_EQ(decoded.fields[3].path, "values[0]");
  EXPECT_EQ(std::get<std::int64_t>(decoded.fields[3].value), -7);
  EXPECT_EQ(decoded.fields[4].path, "values[1]");
  EXPECT_EQ(std::get<std::int64_t>(decoded.fields[4].value), 300);
  EXPECT_EQ(decoded.fields[5].path, "flag");
  EXPECT_EQ(std::get<bool>(decoded.fields[5].value), true);
}

TEST(Decode, HandMadeBigEndianSample) {
  const Bytes bytes = {
      0x00, 0x00, 0x00, 0x00,                          // CDR_BE, options
      0x01, 0x02, 0,    0,    0,    0,    0,    0,     // a = 0x0102, padding to 8
      0x3f, 0xf8, 0,    0,    0,    0,    0,    0,     // b = 1.5
      0x00, 0x00, 0x00, 0x04, 'a',  'b',  'c',  0x00,  // name: length with the NUL
      0x00, 0x00, 0x00, 0x02,                          // values: count
      0xff, 0xff, 0xff, 0xf9, 0x00, 0x00, 0x01, 0x2c,  // -7, 300
      0x01,                                            // flag
  };
  expect_small_fields(MessageSchema::parse(kSmallIdl, "t::Small").decode(bytes.data(), bytes.size()));
}

TEST(Decode, HandMadeLittleEndianSample) {
  const Bytes bytes = {
      0x00, 0x01, 0x00, 0x00,  // CDR_LE
      0x02, 0x01, 0,    0,    0,    0,    0,    0,    0,    0,    0,    0,    0,    0,
      0xf8, 0x3f, 0x04, 0x00, 0x00, 0x00, 'a',  'b',  'c',  0x00, 0x02, 0x00, 0x00, 0x00,
      0xf9, 0xff, 0xff, 0xff, 0x2c, 0x01, 0x00, 0x00, 0x01, 0xaa, 0xbb,  // trailing bytes (padding some writers add)
                                                                         // are ignored
  };
  expect_small_fields(MessageSchema::parse(kSmallIdl, "t::Small").decode(bytes.data(), bytes.size()));
}

TEST(Decode, MalformedStringsSequencesAndBooleans) {
  const MessageSchema schema = MessageSchema::parse(kSmallIdl, "t::Small");
  const auto decode = [&](const std::string& name_bytes, std::uint32_t length, std::uint32_t count, std::uint8_t flag) {
    CdrWriter writer(true);
    writer.put(std::uint16_t{1}).put(2.5).put(length);
    Bytes bytes = writer.bytes();
    bytes.insert(bytes.end(), name_bytes.begin(), name_bytes.end());
    CdrWriter tail(true);  // header-relative alignment continues: name ends 4-aligned here
    Bytes rest = tail.put(count).put(std::int32_t{5}).bytes();
    bytes.insert(bytes.end(), rest.begin() + 4, rest.end());
    bytes.push_back(flag);
    return schema.decode(bytes.data(), bytes.size());
  };
  EXPECT_TRUE(decode(std::string("abc\0", 4), 4, 1, 1).ok());
  // String length 4 at byte 4 + 16 = 20; its bytes start at 24.
  EXPECT_EQ(decode("abcd", 4, 1, 1).error, "at byte 20, field 'name': string of 4 bytes does not end in NUL");
  EXPECT_EQ(decode(std::string("abc\0", 4), 400, 1, 1).error,
            "at byte 20, field 'name': string length 400 exceeds the 13 bytes left");
  EXPECT_EQ(decode(std::string("abcdefghijk\0", 12), 12, 1, 1).error,
            "at byte 20, field 'name': string of 11 characters exceeds its bound 8");
  EXPECT_EQ(decode(std::string("abc\0", 4), 4, 5, 1).error,
            "at byte 28, field 'values': sequence count 5 exceeds its bound 4");
  EXPECT_EQ(decode(std::string("abc\0", 4), 4, 3, 1).error,
            "at byte 28, field 'values': sequence count 3 needs at least 12 bytes, 5 left");
  const Decoded bad_flag = decode(std::string("abc\0", 4), 4, 1, 2);
  EXPECT_EQ(bad_flag.error, "at byte 36, field 'flag': invalid boolean value 2");
  EXPECT_EQ(bad_flag.fields.size(), 4U);  // a, b, name, values[0]
  // An empty string may come as length 0 (Fast CDR reads it as "").
  const Decoded empty = decode("", 0, 1, 0);
  EXPECT_TRUE(empty.ok()) << empty.error;
  EXPECT_EQ(std::get<std::string>(empty.find("name")->value), "");
}

constexpr const char* kFeaturesIdl = R"(// Everything the parser supports beyond the project's own files.
#pragma once
#include "Other.idl"
/* A block comment
   over lines, with a } and a { inside */
module geo {
  const long N = 2;
  const unsigned long LEN = N * 4 + (3 - 2);  // 9
  const string NAME = "geo; not a } bound";
  const double SCALE = 1.5e-3;
  typedef double Vec[N + 1];
  typedef sequence<Vec, LEN> VecSeq;
  enum Mode { OFF, @value(5) ON, AUTO };
  module inner {
    @appendable struct Base { octet id; };
  };
  @final
  struct Pose : inner::Base {
    @key unsigned long long serial;
    int8 small; char letter;
    short s16; unsigned short u16;
    long s32;
    float ratio;
    Mode mode;
    Vec position;
    int16 grid[2][3];
    VecSeq path;
    ::geo::inner::Base bases[2];
    sequence<string<5>> names;
    long long s64; unsigned long u32;
    boolean ok;
  };
};
)";

Bytes features_sample(bool little_endian) {
  CdrWriter writer(little_endian);
  writer.put(std::uint8_t{7}).put(std::uint64_t{0xfedcba9876543210ULL}).put(std::int8_t{-3});
  writer.put(static_cast<std::uint8_t>('x')).put(std::int16_t{-300}).put(std::uint16_t{60000});
  writer.put(std::int32_t{-70000}).put(0.25F).put(std::uint32_t{6});
  writer.put(1.0).put(2.0).put(3.0);
  for (std::int16_t i = 0; i < 6; ++i) writer.put(static_cast<std::int16_t>(10 * i - 20));
  writer.put(std::uint32_t{2});
  for (int i = 0; i < 6; ++i) writer.put(0.5 * i);
  writer.put(std::uint8_t{8}).put(std::uint8_t{9});
  writer.put(std::uint32_t{2}).text("ab").text("");
  writer.put(std::int64_t{-5'000'000'000}).put(std::uint32_t{4'000'000'000U});
  writer.put(std::uint8_t{0});
  return writer.bytes();
}

TEST(Schema, IdlFeaturesDecodeInBothByteOrders) {
  const MessageSchema schema = MessageSchema::parse(kFeaturesIdl, "geo::Pose");
  for (const bool little_endian : {true, false}) {
    const Bytes bytes = features_sample(little_endian);
    const Decoded decoded = schema.decode(bytes.data(), bytes.size());
    ASSERT_TRUE(decoded.ok()) << decoded.error;
    const auto value = [&](const std::string& path) {
      const Field* field = decoded.find(path);
      return field == nullptr ? std::string("(missing)") : field->to_string();
    };
    EXPECT_EQ(value("id"), "7");
    EXPECT_EQ(value("serial"), "18364758544493064720");
    EXPECT_EQ(value("small"), "-3");
    EXPECT_EQ(value("letter"), "'x'");
    EXPECT_EQ(value("s16"), "-300");
    EXPECT_EQ(value("u16"), "60000");
    EXPECT_EQ(value("s32"), "-70000");
    EXPECT_EQ(value("ratio"), "0.25");
    EXPECT_EQ(value("mode"), "6");  // AUTO, after @value(5) ON
    EXPECT_EQ(value("position[2]"), "3.0");
    EXPECT_EQ(value("grid[0][0]"), "-20");
    EXPECT_EQ(value("grid[1][2]"), "30");
    EXPECT_EQ(value("path[1][2]"), "2.5");
    EXPECT_EQ(value("bases[1].id"), "9");
    EXPECT_EQ(value("names[0]"), "'ab'");
    EXPECT_EQ(value("names[1]"), "''");
    EXPECT_EQ(value("s64"), "-5000000000");
    EXPECT_EQ(value("u32"), "4000000000");
    EXPECT_EQ(value("ok"), "false");
    EXPECT_EQ(decoded.fields.size(), 31U);
  }
  const std::vector<std::string> paths = {
      "id",          "serial",      "small",       "letter",      "s16",         "u16",        "s32",
      "ratio",       "mode",        "position[0]", "position[1]", "position[2]", "grid[0][0]", "grid[0][1]",
      "grid[0][2]",  "grid[1][0]",  "grid[1][1]",  "grid[1][2]",  "path[][0]",   "path[][1]",  "path[][2]",
      "bases[0].id", "bases[1].id", "names[]",     "s64",         "u32",         "ok"};
  EXPECT_EQ(schema.field_paths(), paths);
  EXPECT_EQ(MessageSchema::parse(kFeaturesIdl, "geo/inner/Base").field_paths(), std::vector<std::string>{"id"});
}

TEST(Schema, BoundsFromConstantsAreEnforced) {
  const MessageSchema schema = MessageSchema::parse(kFeaturesIdl, "geo::Pose");
  Bytes bytes = features_sample(true);
  // path's count (LEN = 9 bound) sits after the 6 int16 of grid: find it by its value 2 at the
  // offset the layout gives: id 1, serial at 8, small 16, letter 17, s16 18, u16 20, s32 24,
  // ratio 28, mode 32, position 40..64, grid 64..76, count at 76 (+4 header).
  ASSERT_EQ(bytes[80], 2U);
  bytes[80] = 10;
  EXPECT_EQ(schema.decode(bytes.data(), bytes.size()).error,
            "at byte 80, field 'path': sequence count 10 exceeds its bound 9");
}

struct BadIdl {
  const char* idl;
  const char* type_name;
  const char* message;  // expected what() (a prefix when it ends in "...")
};

const BadIdl kBadIdl[] = {
    {"module m { struct A { double x; };", "m::A",
     "IDL line 1, at 'end of input': missing '}' closing module 'm' (opened at line 1)"},
    {"module m {\n  struct A {\n    double x;\n  struct B { double y; };\n};\n};", "m::A",
     "IDL line 4, at 'struct': missing '}' closing struct 'A' (opened at line 2)"},
    {"struct A { double x; };\n};", "A", "IDL line 2, at '}': unbalanced '}'"},
    {"module m {\n  struct A {\n    Foo x;\n  };\n};", "m::A", "IDL line 3, at 'Foo': unknown type 'Foo'"},
    {"/* a\n b\n*/\n#include <x.idl>\nstruct A {\n  geo::Foo x;\n};", "A",
     "IDL line 6, at 'geo': unknown type 'geo::Foo'"},
    {"struct A { double x; }; /* oops", "A", "IDL line 1, at '/*': unterminated comment"},
    {"struct A { double $x; };", "A", "IDL line 1, at '$': unexpected character"},
    {"struct A { double x; }; \x01", "A", "IDL line 1, at '\\x01': unexpected character"},
    {"const string S = \"abc;\nstruct A { double x; };", "A", "IDL line 1, at '\"': unterminated literal"},
    {"struct A { string<0> s; };", "A", "IDL line 1, at '0': a bound must be a positive integer constant below 2^32"},
    {"struct A { sequence<double, -1> s; };", "A",
     "IDL line 1, at '-': a bound must be a positive integer constant below 2^32"},
    {"const double D = 1.5;\nstruct A { sequence<double, D> s; };", "A",
     "IDL line 2, at 'D': a bound must be a positive integer constant below 2^32"},
    {"const long Z = 0;\nstruct A { double s[4 / Z]; };", "A",
     "IDL line 2, at '4': a bound must be a positive integer constant below 2^32"},
    {"struct A { long double x; };", "A", "IDL line 1, at 'double': long double is not supported"},
    {"struct A { wstring x; };", "A", "IDL line 1, at 'wstring': unsupported type"},
    {"union U switch (long) { case 1: long a; };", "U", "IDL line 1, at 'union': unsupported IDL construct"},
    {"struct A { double x; long x; };", "A", "IDL line 1, at 'x': duplicate member 'x'"},
    {"struct A { double x; };\nstruct A { double y; };", "A", "IDL line 2, at 'A': redefinition of 'A'"},
    {"struct A {\n  @optional double x;\n};", "A", "IDL line 2, at 'double': @optional members are not supported"},
    {"struct A { double x[100000][100000]; };", "A", "IDL line 1, at 'x': array of more than 1048576 elements"},
    {"struct A { double x }", "A", "IDL line 1, at '}': expected ';' after a member"},
    {"const long N = 3;\nstruct A { N x; };", "A", "IDL line 2, at 'N': 'N' is a constant, not a type"},
    {"struct A { unsigned double x; };", "A", "IDL line 1, at 'double': expected 'short' or 'long' after 'unsigned'"},
    {"module { };", "A", "IDL line 1, at '{': expected a module name"},
    {"struct B : A { double x; };", "B", "IDL line 1, at 'A': unknown type 'A'"},
    {"@final", "A", "IDL line 1, at 'end of input': annotation without a definition"},
    {"struct A { double x; };\nfoo", "A",
     "IDL line 2, at 'foo': expected a definition (module, struct, enum, typedef or const)"},
    {"", "A", "unknown type 'A': the IDL defines the structs (none)"},
    {"enum E { X, Y };\nmodule m { struct S { E e; }; };", "E", "unknown type 'E': the IDL defines the structs m::S"},
};

TEST(Schema, BadIdlIsReportedWithLineAndToken) {
  for (const auto& bad : kBadIdl) {
    try {
      MessageSchema::parse(bad.idl, bad.type_name);
      ADD_FAILURE() << "no SchemaError for: " << bad.idl;
    } catch (const SchemaError& error) {
      EXPECT_EQ(std::string(error.what()), bad.message) << "for: " << bad.idl;
    }
  }
}

TEST(Schema, DeepNestingIsRefusedNotOverflowed) {
  std::string nested = "struct A { ";
  for (int i = 0; i < 5000; ++i) nested += "sequence<";
  nested += "double";
  for (int i = 0; i < 5000; ++i) nested += ">";
  nested += " x; };";
  EXPECT_THROW(MessageSchema::parse(nested, "A"), SchemaError);

  std::string modules;
  for (int i = 0; i < 5000; ++i) modules += "module m {";
  EXPECT_THROW(MessageSchema::parse(modules, "A"), SchemaError);

  std::string typedefs = "typedef double T0;\n";
  for (int i = 1; i < 200; ++i) {
    typedefs += "typedef sequence<T" + std::to_string(i - 1) + "> T" + std::to_string(i) + ";\n";
  }
  try {
    MessageSchema::parse(typedefs, "A");
    ADD_FAILURE() << "no SchemaError";
  } catch (const SchemaError& error) {
    EXPECT_NE(std::string(error.what()).find("types nested too deeply"), std::string::npos) << error.what();
  }

  std::string parentheses = "const long N = ";
  for (int i = 0; i < 5000; ++i) parentheses += "(";
  parentheses += "1";
  for (int i = 0; i < 5000; ++i) parentheses += ")";
  parentheses += ";\nstruct A { double x[N]; };";
  EXPECT_THROW(MessageSchema::parse(parentheses, "A"), SchemaError);
}

constexpr const char* kFlattenedIdl = R"(module pmlsm_msgs {
  module msg {
    @final
    struct Stamp {
      uint64 tick;            // tick
      int64 sim_time_ns;      // [ns]
      int64 source_time_ns;   // [ns]
    };
  };
};
// A weight set.

module pmlsm_msgs {
  module msg {
    @final
    struct NetworkWeights {
      Stamp stamp;
      uint64 version;
      sequence<uint16, 8> layer_sizes;
      sequence<double, 1024> weights;
      double input_scale;
      string<64> source;
      double grid[2][2];
    };
  };
};
)";

TEST(Schema, RandomlyMangledIdlOnlyThrowsSchemaError) {
  std::mt19937 random(2024);
  const std::string alphabet = "{}<>[];:,@#/*\"'() abcx019-+\n";
  int parsed = 0;
  for (int round = 0; round < 3000; ++round) {
    std::string idl = kFlattenedIdl;
    const int edits = 1 + static_cast<int>(random() % 3);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = random() % idl.size();
      switch (random() % 3) {
        case 0: idl.erase(at, 1 + random() % 6); break;
        case 1: idl.insert(at, 1, alphabet[random() % alphabet.size()]); break;
        default: idl.insert(at, idl.substr(random() % idl.size(), 1 + random() % 12)); break;
      }
    }
    try {
      const MessageSchema schema = MessageSchema::parse(idl, "pmlsm_msgs::msg::NetworkWeights");
      ++parsed;
      Bytes bytes(4 + random() % 200);
      for (auto& byte : bytes) byte = static_cast<std::uint8_t>(random() % 4 == 0 ? random() : 0);
      bytes[0] = 0;
      bytes[1] = static_cast<std::uint8_t>(random() % 2);
      const Decoded decoded = schema.decode(bytes.data(), bytes.size());
      EXPECT_LE(decoded.fields.size(), bytes.size());
      (void)MessageSchema::to_yaml(decoded);
      (void)schema.field_paths();
    } catch (const SchemaError&) {
      // expected for most manglings
    }
  }
  EXPECT_GT(parsed, 0);  // some edits (inside comments, say) leave valid IDL
}

TEST(Schema, FieldPathsOfNestedAndSequenceMembers) {
  EXPECT_EQ(MessageSchema::parse(kFlattenedIdl, "pmlsm_msgs::msg::NetworkWeights").field_paths(),
            (std::vector<std::string>{"stamp.tick", "stamp.sim_time_ns", "stamp.source_time_ns", "version",
                                      "layer_sizes[]", "weights[]", "input_scale", "source", "grid[0][0]", "grid[0][1]",
                                      "grid[1][0]", "grid[1][1]"}));
}

template <class T>
Field make_field(const std::string& path, T value) {
  Field result;
  result.path = path;
  result.value = value;
  return result;
}

TEST(Text, ValuesAsEchoPrintsThem) {
  EXPECT_EQ(make_field("x", std::int64_t{-5}).to_string(), "-5");
  EXPECT_EQ(make_field("x", std::numeric_limits<std::uint64_t>::max()).to_string(), "18446744073709551615");
  EXPECT_EQ(make_field("x", 0.1).to_string(), "0.1");
  EXPECT_EQ(make_field("x", 2.0).to_string(), "2.0");
  EXPECT_EQ(make_field("x", -1e-7).to_string(), "-1.0e-07");
  EXPECT_EQ(make_field("x", 0.1 + 0.2).to_string(), "0.30000000000000004");
  EXPECT_EQ(make_field("x", std::numeric_limits<double>::quiet_NaN()).to_string(), ".nan");
  EXPECT_EQ(make_field("x", -std::numeric_limits<double>::infinity()).to_string(), "-.inf");
  EXPECT_EQ(make_field("x", true).to_string(), "true");
  EXPECT_EQ(make_field("x", std::string("it's")).to_string(), "'it''s'");
  EXPECT_EQ(make_field("x", std::string("a\"b\n")).to_string(), "\"a\\\"b\\n\"");
  EXPECT_FALSE(make_field("x", std::string("s")).as_double().has_value());
  EXPECT_EQ(make_field("x", false).as_double(), 0.0);
  EXPECT_EQ(make_field("x", std::uint64_t{7}).as_double(), 7.0);
  EXPECT_EQ(make_field("x", std::int64_t{-7}).as_double(), -7.0);
}

TEST(Text, YamlOfNestedSequencesAndArrays) {
  Decoded decoded;
  decoded.fields = {
      make_field("scenarios[0].yaml", std::string("a: 1\n")),
      make_field("scenarios[0].weight", 0.5),
      make_field("scenarios[1].yaml", std::string("b")),
      make_field("scenarios[1].weight", 1.0),
      make_field("grid[0][0]", std::int64_t{1}),
      make_field("grid[0][1]", std::int64_t{-2}),
      make_field("grid[1][0]", std::uint64_t{3}),
      make_field("grid[1][1]", std::uint64_t{4}),
      make_field("inner.values[0]", true),
      make_field("inner.values[1]", false),
      make_field("inner.name", std::string("tab\there")),
      make_field("tracks[0][0].x", 1.0),
      make_field("tracks[0][0].y", 2.0),
      make_field("tracks[0][1].x", 3.0),
      make_field("last", std::numeric_limits<double>::infinity()),
  };
  EXPECT_EQ(MessageSchema::to_yaml(decoded),
            "scenarios:\n"
            "- yaml: \"a: 1\\n\"\n"
            "  weight: 0.5\n"
            "- yaml: 'b'\n"
            "  weight: 1.0\n"
            "grid:\n"
            "- - 1\n"
            "  - -2\n"
            "- - 3\n"
            "  - 4\n"
            "inner:\n"
            "  values:\n"
            "  - true\n"
            "  - false\n"
            "  name: \"tab\\there\"\n"
            "tracks:\n"
            "- - x: 1.0\n"
            "    y: 2.0\n"
            "  - x: 3.0\n"
            "last: .inf\n");
  EXPECT_EQ(MessageSchema::to_yaml(Decoded{}), "");
}

}  // namespace
