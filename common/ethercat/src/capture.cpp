#include "pmlsm/ethercat/capture.hpp"

#include <cstdio>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/canopen/sdo.hpp"
#include "pmlsm/ethercat/esc.hpp"
#include "pmlsm/util/little_endian.hpp"

namespace pmlsm::ethercat {

namespace {

/// The 8 bytes as the CANopen frame they are: a request to node 1, a response from it.
canopen::CanFrame as_can_frame(const SeenSdo& sdo) {
  canopen::CanFrame frame{};
  frame.id = sdo.service == kCoeServiceSdoRequest ? canopen::sdo_rx_cob_id(canopen::NodeId(1))
                                                  : canopen::sdo_tx_cob_id(canopen::NodeId(1));
  frame.dlc = 8;
  std::copy(sdo.sdo.begin(), sdo.sdo.end(), frame.data.begin());
  return frame;
}

std::string multiplexer(std::uint16_t index, std::uint8_t subindex) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%04X:%02X", index, subindex);
  return text;
}

/// " = 0xA (1 byte)"
std::string value_text(const canopen::SdoData& data) {
  char text[48];
  std::snprintf(text, sizeof text, " = 0x%X (%u byte%s)", data.data, data.size, data.size == 1 ? "" : "s");
  return text;
}

/// ": 0x06020000 (object does not exist)"
std::string abort_text(std::uint32_t abort_code) {
  char code[16];
  std::snprintf(code, sizeof code, "0x%08X", abort_code);
  return std::string(": ") + code + " (" + canopen::describe(abort_code) + ")";
}

/// EtherCAT over UDP (ETG.1000.4, 5.3.3): an untagged IPv4 frame to UDP port 34980; its payload,
/// or none.
Bytes udp_payload(Bytes ethernet) {
  constexpr std::size_t kIpAt = 14;
  if (ethernet.size < kIpAt + 20 || ethernet.data[12] != 0x08 || ethernet.data[13] != 0x00) return {};
  const std::uint8_t* ip = ethernet.data + kIpAt;
  const std::size_t ip_header = static_cast<std::size_t>(ip[0] & 0x0FU) * 4;
  if ((ip[0] >> 4) != 4 || ip_header < 20 || ip[9] != 17) return {};
  const std::size_t ip_length = static_cast<std::size_t>(ip[2]) << 8 | ip[3];
  if (ip_length < ip_header + 8 || kIpAt + ip_length > ethernet.size) return {};
  const std::uint8_t* udp = ip + ip_header;
  if ((static_cast<std::uint16_t>(udp[2] << 8) | udp[3]) != kUdpPort) return {};
  const std::size_t udp_length = static_cast<std::size_t>(udp[4]) << 8 | udp[5];
  if (udp_length < 8 || udp_length > ip_length - ip_header) return {};
  return {udp + 8, udp_length - 8};
}

}  // namespace

bool find_coe_sdo(const DatagramView& datagram, SeenSdo& out) {
  const Command command = datagram.header.command;
  if ((command != Command::kFpwr && command != Command::kFprd) || datagram.working_counter != 1) return false;
  if (datagram.header.ado() < reg::kProcessRam || datagram.data == nullptr) return false;
  std::uint8_t service = 0;
  if (parse_coe_sdo(datagram.data, datagram.header.length, out.header, service, out.sdo) != MailboxError::kNone) {
    return false;
  }
  // A request goes into the receive mailbox, a response comes from the send mailbox.
  if ((command == Command::kFpwr) != (service == kCoeServiceSdoRequest)) return false;
  out.service = service;
  out.station = datagram.header.adp();
  out.mailbox_address = datagram.header.ado();
  return true;
}

bool upload_value(const SeenSdo& sdo, std::uint16_t& index, std::uint8_t& subindex, std::uint32_t& value,
                  std::uint8_t& size) {
  if (sdo.service != kCoeServiceSdoResponse) return false;
  const canopen::Result<canopen::SdoResponse> parsed = canopen::parse_sdo_response(as_can_frame(sdo));
  if (!parsed || parsed.value.kind != canopen::SdoResponseKind::kUpload) return false;
  index = parsed.value.index;
  subindex = parsed.value.subindex;
  value = parsed.value.data.data;
  size = parsed.value.data.size;
  return true;
}

namespace {

/// The normal and segmented transfers' messages (mailbox.hpp), which the CANopen codec, expedited
/// only, does not read; "" for any other.
std::string describe_normal_or_segment(const SeenSdo& sdo) {
  const std::uint8_t command = sdo.sdo[0];
  const std::uint8_t specifier = command >> 5;
  const bool request = sdo.service == kCoeServiceSdoRequest;
  const std::string toggle = std::to_string((command >> 4) & 1U);
  const auto total = [&] { return std::to_string(get_le32(sdo.sdo.data() + 4)); };
  const std::string at = multiplexer(static_cast<std::uint16_t>(sdo.sdo[1] | (sdo.sdo[2] << 8)), sdo.sdo[3]);
  const std::size_t more = coe_sdo_more_bytes(sdo.header);
  if (request && specifier == 3) return "upload segment request (toggle " + toggle + ")";
  if (!request && specifier == 0) {
    const std::size_t bytes = more > 0 ? 7 + more : 7 - ((command >> 1) & 7U);
    return "upload segment response (toggle " + toggle + ", " + std::to_string(bytes) + " bytes" +
           ((command & 1U) != 0 ? ", last)" : ")");
  }
  if (request && specifier == 0) {
    const std::size_t bytes = more > 0 ? 7 + more : 7 - ((command >> 1) & 7U);
    return "download segment request (toggle " + toggle + ", " + std::to_string(bytes) + " bytes" +
           ((command & 1U) != 0 ? ", last)" : ")");
  }
  if (!request && specifier == 1) return "download segment response (toggle " + toggle + ")";
  if ((command & 0x03U) != 0x01) return "";  // expedited, or no size: not a normal transfer
  if (!request && specifier == 2) {
    return "upload response " + at + ", normal: " + total() + " bytes, " + std::to_string(more) + " here";
  }
  if (request && specifier == 1) {
    return "download request " + at + ", normal: " + total() + " bytes, " + std::to_string(more) + " here";
  }
  return "";
}

}  // namespace

std::string describe(const SeenSdo& sdo) {
  if (std::string text = describe_normal_or_segment(sdo); !text.empty()) return text;
  const canopen::CanFrame frame = as_can_frame(sdo);
  if (sdo.service == kCoeServiceSdoRequest) {
    const canopen::Result<canopen::SdoRequest> r = canopen::parse_sdo_request(frame);
    if (!r) return std::string("request not decoded: ") + r.detail;
    const std::string at = multiplexer(r.value.index, r.value.subindex);
    switch (r.value.kind) {
      case canopen::SdoRequestKind::kUpload: return "upload request " + at;
      case canopen::SdoRequestKind::kDownload: return "download request " + at + value_text(r.value.data);
      case canopen::SdoRequestKind::kAbort: break;
    }
    return "abort by the master " + at + abort_text(r.value.abort_code);
  }
  const canopen::Result<canopen::SdoResponse> r = canopen::parse_sdo_response(frame);
  if (!r) return std::string("response not decoded: ") + r.detail;
  const std::string at = multiplexer(r.value.index, r.value.subindex);
  switch (r.value.kind) {
    case canopen::SdoResponseKind::kUpload: return "upload response " + at + value_text(r.value.data);
    case canopen::SdoResponseKind::kDownload: return "download response " + at;
    case canopen::SdoResponseKind::kAbort: break;
  }
  return "abort " + at + abort_text(r.value.abort_code);
}

CaptureDecode decode_capture(PcapngReader& reader) {
  CaptureDecode d;
  CapturedFrame frame;
  ParsedFrame parsed;
  while (reader.next(frame)) {
    ++d.frames;
    if (frame.link_type != kLinkTypeEthernet) {
      ++d.other_frames;
      continue;
    }
    FrameError error = parse_ethernet_frame(frame.data.data, frame.data.size, parsed);
    if (error == FrameError::kNotEtherCat) {
      const Bytes payload = udp_payload(frame.data);
      if (payload.data == nullptr) {
        ++d.other_frames;
        continue;
      }
      ++d.over_udp;
      error = parse_ethercat_frame(payload.data, payload.size, parsed);
    }
    ++d.ethercat_frames;
    if (error == FrameError::kNotDatagrams) {
      ++d.other_types;
      continue;
    }
    if (error != FrameError::kNone) {
      if (d.malformed_frames++ == 0) {
        d.first_malformed = frame.number;
        d.first_error = error;
      }
      continue;
    }
    for (std::size_t i = 0; i < parsed.count; ++i) {
      const DatagramView& datagram = parsed.datagrams[i];
      ++d.datagrams[static_cast<std::size_t>(datagram.header.command)];
      SeenSdo seen;
      if (find_coe_sdo(datagram, seen)) d.sdos.push_back({frame.number, seen});
    }
  }
  return d;
}

}  // namespace pmlsm::ethercat
