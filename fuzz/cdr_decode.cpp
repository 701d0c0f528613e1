// The CDR decoder (MessageSchema::decode) over the system's message types (idl/*.idl, flattened
// as the catalog does: Stamp.idl, then the type's own file without its #include lines) and one
// schema with every construct of the IDL subset. Input: byte 0 picks the schema, the rest is the
// sample (encapsulation header first). decode never throws; every field is then printed.
#include <sstream>
#include <vector>

#include "fuzz_support.hpp"
#include "pmlsm/introspect/cdr_schema.hpp"

namespace pmlsm::fuzz::cdr_decode {

namespace {

constexpr const char* kConstructs = R"(
module fz {
  const long N = 3;
  typedef float Triple[N];
  typedef sequence<Triple, 4> Triples;
  enum Colour { RED, @value(9) GREEN, BLUE };
  module in { struct Leaf { octet b; string tag; }; };
  @final struct All : in::Leaf {
    boolean flag; char c; int8 i8; uint8 u8; int16 i16; uint16 u16;
    int32 i32; uint32 u32; int64 i64; uint64 u64;
    short s; unsigned short us; long l; unsigned long ul; long long ll; unsigned long long ull;
    float f; double d; Colour colour;
    string<6> bounded; Triple t; Triples ts;
    sequence<in::Leaf> leaves; sequence<string<3>, 2> names;
    double grid[2][2]; in::Leaf pair[2];
  };
};
)";

std::vector<introspect::MessageSchema> make_schemas() {
  std::vector<introspect::MessageSchema> schemas;
  const std::string stamp = source_file("idl/Stamp.idl");
  for (const char* name :
       {"Stamp", "DriveState", "DriveControl", "MotorFeedback", "PlantTruth", "ForceCommand", "NetworkWeights",
        "TrainerProgress", "NodeStatus", "TrainingSetup", "EvaluationRequest", "EvaluationResult", "WorkerStatus"}) {
    std::istringstream lines(source_file(std::string("idl/") + name + ".idl"));
    std::string idl = std::string(name) == "Stamp" ? "" : stamp;
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("#include", 0) != 0) idl += line + "\n";
    }
    schemas.push_back(introspect::MessageSchema::parse(idl, std::string("pmlsm_msgs::msg::") + name));
  }
  schemas.push_back(introspect::MessageSchema::parse(kConstructs, "fz::All"));
  return schemas;
}

}  // namespace

int fuzz_one(const std::uint8_t* data, std::size_t size) {
  static const std::vector<introspect::MessageSchema> schemas = make_schemas();
  if (size == 0) return 0;
  const introspect::MessageSchema& schema = schemas[data[0] % schemas.size()];
  const introspect::Decoded decoded = schema.decode(data + 1, size - 1);
  for (const introspect::Field& field : decoded.fields) {
    field.to_string();
    field.as_double();
  }
  introspect::MessageSchema::to_yaml(decoded);
  return 0;
}

}  // namespace pmlsm::fuzz::cdr_decode
