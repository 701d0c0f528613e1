#include "pmlsm/dds/raw_type.hpp"

#include <cstring>
#include <stdexcept>

namespace pmlsm::dds {

RawPubSubType::RawPubSubType(const std::string& type_name, std::uint32_t max_serialized_size) {
  if (type_name.empty()) throw std::invalid_argument("RawPubSubType: empty type name");
  if (max_serialized_size < 4) {
    throw std::invalid_argument("RawPubSubType: max size " + std::to_string(max_serialized_size) +
                                " is smaller than the 4-byte encapsulation header");
  }
  setName(type_name.c_str());
  m_typeSize = max_serialized_size;
  m_isGetKeyDefined = false;
}

bool RawPubSubType::serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) {
  const auto& bytes = static_cast<RawSample*>(data)->bytes;
  if (bytes.size() < 4 || bytes.size() > payload->max_size) return false;
  std::memcpy(payload->data, bytes.data(), bytes.size());
  payload->length = static_cast<std::uint32_t>(bytes.size());
  // Byte 1 of the header is the representation: odd = little-endian (CDR_LE, PL_CDR_LE).
  payload->encapsulation = (bytes[1] & 1U) != 0 ? CDR_LE : CDR_BE;
  return true;
}

bool RawPubSubType::deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) {
  auto& bytes = static_cast<RawSample*>(data)->bytes;
  if (payload->length < 4) return false;
  bytes.assign(payload->data, payload->data + payload->length);
  return true;
}

std::function<std::uint32_t()> RawPubSubType::getSerializedSizeProvider(void* data) {
  return [data]() { return static_cast<std::uint32_t>(static_cast<RawSample*>(data)->bytes.size()); };
}

void* RawPubSubType::createData() { return new RawSample(); }  // NOLINT: Fast DDS's ownership API

void RawPubSubType::deleteData(void* data) { delete static_cast<RawSample*>(data); }  // NOLINT

bool RawPubSubType::getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) { return false; }

}  // namespace pmlsm::dds
