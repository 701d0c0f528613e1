// The IDL-subset parser (MessageSchema::parse). Input: the type name on the first line, the IDL
// text after it. A schema that parses then decodes fixed samples (little and big endian, short
// and long) and prints them, which walks every type it built.
#include <vector>

#include "fuzz_support.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"

namespace pmlsm::fuzz::idl_schema {

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  const std::string text = as_text(data, size);
  const std::size_t newline = text.find('\n');
  const std::string type_name = text.substr(0, newline);
  const std::string idl = newline == std::string::npos ? std::string() : text.substr(newline + 1);
  try {
    const introspect::MessageSchema schema = introspect::MessageSchema::parse(idl, type_name);
    schema.field_paths();
    std::vector<std::uint8_t> sample(256);
    for (std::size_t i = 4; i < sample.size(); ++i) sample[i] = static_cast<std::uint8_t>(i % 7);
    for (const std::uint8_t encapsulation : {std::uint8_t{1}, std::uint8_t{0}}) {
      sample[1] = encapsulation;
      for (const std::size_t bytes : {std::size_t{4}, std::size_t{24}, sample.size()}) {
        const introspect::Decoded decoded = schema.decode(sample.data(), bytes);
        introspect::MessageSchema::to_yaml(decoded);
      }
    }
  } catch (const introspect::SchemaError&) {
  }
  return 0;
}

}  // namespace pmlsm::fuzz::idl_schema
