// Decoding CDR samples of any type described by OMG IDL text, as MCAP 'omgidl' schemas carry
// it: what `pmlsm topic echo` prints and `pmlsm plot` draws, from a recording or the wire,
// without the generated C++ types. Pure C++, no DDS.
//
// IDL subset: modules, structs (annotations such as @final ignored), consts (kept for display),
// enums, typedefs; members of primitive types (boolean, char, octet, int8..uint64 and the
// short/long/long long spellings, float, double), string and string<N>, sequence<T> and
// sequence<T, N>, fixed arrays T name[N][M], and nested structs by scoped or relative name.
// Encoding: XCDR1 ("plain" CDR) after the 4-byte encapsulation header, either endianness
// (header byte 1 even = big, odd = little), alignment relative to the end of the header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace pmlsm::introspect {

class SchemaError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One leaf of a decoded sample: "stamp.tick", "layer_sizes[2]", "source".
struct Field {
  std::string path;
  std::variant<std::int64_t, std::uint64_t, double, bool, std::string> value;
  /// The value as a number (bool 0/1); nullopt for strings.
  std::optional<double> as_double() const;
  /// The value as text, as echo prints it (doubles with full precision, %.17g).
  std::string to_string() const;
};

struct Decoded {
  std::vector<Field> fields;  // in declaration order
  std::string error;          // empty when the whole sample decoded; else what and at which byte
  bool ok() const { return error.empty(); }
  /// The field at `path`, or nullptr.
  const Field* find(const std::string& path) const;
};

class MessageSchema {
 public:
  /// Parses `idl` and selects `type_name` ("pmlsm_msgs::msg::MotorFeedback"; a leading "::"
  /// and the "/" separators of ROS-style names "pmlsm_msgs/msg/MotorFeedback" are accepted).
  /// @throws SchemaError naming the line and the token for bad IDL or an unknown type.
  static MessageSchema parse(const std::string& idl, const std::string& type_name);

  const std::string& type_name() const;
  /// Leaf paths in declaration order; sequences appear as "name[]" (their length varies).
  std::vector<std::string> field_paths() const;

  /// Decodes one sample (encapsulation header first). Never throws: a sample that is too
  /// short, has an unknown encapsulation or an over-long sequence gives the fields decoded so
  /// far and an error.
  Decoded decode(const std::uint8_t* data, std::size_t size) const;

  /// ros2-topic-echo style YAML text of a decoded sample ("stamp:\n  tick: 12\n...").
  static std::string to_yaml(const Decoded& decoded);

  struct Impl;  // parsed type tree (shared, immutable)

 private:
  explicit MessageSchema(std::shared_ptr<const Impl> impl);
  std::shared_ptr<const Impl> impl_;
};

}  // namespace pmlsm::introspect
