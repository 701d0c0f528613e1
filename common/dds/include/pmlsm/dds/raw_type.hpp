// A type support that carries a sample as its serialized bytes (CDR with the 4-byte
// encapsulation header), under the name of one of our types. A reader of it receives exactly
// what the writer put on the wire, and a writer of it sends bytes read back from a recording:
// what the recorder, the player and the bridge need, without decoding.
//
// DDS matches readers and writers by topic and type name; the bytes are the same as those of
// the generated type support, so raw and typed endpoints interoperate.
#pragma once

#include <fastdds/dds/topic/TopicDataType.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace pmlsm::dds {

struct RawSample {
  std::vector<std::uint8_t> bytes;  // encapsulation header + CDR body
};

class RawPubSubType : public eprosima::fastdds::dds::TopicDataType {
 public:
  using type = RawSample;
  /// @throws std::invalid_argument when the name is empty or max_size < 4.
  RawPubSubType(const std::string& type_name, std::uint32_t max_serialized_size);

  /// Copies the bytes; refuses (false) a sample shorter than its header or longer than the bound.
  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override;
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override;
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override;
  // Fast DDS owns samples through these two (its API hands out void*).
  void* createData() override;
  void deleteData(void* data) override;
  /// Our types have no key.
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* handle, bool force_md5) override;
};

}  // namespace pmlsm::dds
