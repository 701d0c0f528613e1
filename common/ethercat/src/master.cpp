#include "pmlsm/ethercat/master.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "pmlsm/canopen/sdo.hpp"
#include "pmlsm/ethercat/mailbox.hpp"
#include "pmlsm/util/little_endian.hpp"
#include "pmlsm/util/validate.hpp"

namespace pmlsm::ethercat {

namespace {

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string slave_name(std::uint16_t station) { return "slave " + format_hex(station, 4); }

}  // namespace

void MasterParams::validate() const {
  if (reply_timeout_ns <= 0)
    throw std::invalid_argument("reply_timeout_ns: must be > 0, got " + std::to_string(reply_timeout_ns));
  if (retries < 0 || retries > 100) throw std::invalid_argument("retries: 0 to 100, got " + std::to_string(retries));
  if (first_station_address == 0) throw std::invalid_argument("first_station_address: must not be 0 (no address)");
  if (state_timeout_ns <= 0)
    throw std::invalid_argument("state_timeout_ns: must be > 0, got " + std::to_string(state_timeout_ns));
}

std::string SdoResult::describe() const {
  if (done && (bytes.size() > 4 || !expedited)) {
    const bool text = std::all_of(bytes.begin(), bytes.end(), [](std::uint8_t b) { return b >= 0x20 && b < 0x7F; });
    std::string shown;
    if (text) {
      shown = "\"" + std::string(bytes.begin(), bytes.end()) + "\"";
    } else {
      char hex[4];
      for (const std::uint8_t b : bytes) {
        std::snprintf(hex, sizeof hex, "%02X ", b);
        shown += hex;
      }
      if (!shown.empty()) shown.pop_back();
    }
    return shown + " (" + std::to_string(bytes.size()) + " bytes)";
  }
  if (done) return format_hex(value, 2 * (size == 0 ? 4 : size));
  return "aborted: " + format_hex(abort_code, 8) + " " + canopen::describe(abort_code);
}

std::string StateResult::describe() const {
  std::string text = to_string(state);
  if (code != 0) text += ", refused: " + format_hex(code, 4) + " " + al_status_code_name(code);
  return text;
}

Master::Master(Link& link, MasterParams params) : link_(link), params_((params.validate(), params)) {}

void Master::record(Bytes frame) {
  if (capture_ == nullptr) return;
  try {
    capture_->write(frame, now_ns());
  } catch (const std::runtime_error&) {
    // exchange() never throws: a capture that cannot be written stops, and says so.
    capture_ = nullptr;
    capture_failed_ = true;
  }
}

Reply Master::exchange(Command command, std::uint32_t address, std::uint8_t* data, std::uint16_t length) {
  return exchange(command, address, data, length, params_.reply_timeout_ns, params_.retries);
}

Reply Master::exchange(Command command, std::uint32_t address, std::uint8_t* data, std::uint16_t length,
                       std::int64_t reply_timeout_ns, int retries) {
  const std::uint8_t index = next_index_++;
  frame_.clear();
  if (!frame_.add(command, index, address, data, length)) return {};
  for (int attempt = 0; attempt <= retries; ++attempt) {
    const Bytes sent = frame_.ethernet();
    ++frames_sent_;
    if (!link_.send(sent)) {
      ++frames_lost_;
      continue;
    }
    record(sent);
    const std::int64_t deadline = now_ns() + reply_timeout_ns;
    for (std::int64_t left = reply_timeout_ns; left > 0; left = deadline - now_ns()) {
      const std::size_t size = link_.receive(received_.data(), left);
      if (size == 0) break;
      ParsedFrame parsed;
      if (parse_ethernet_frame(received_.data(), size, parsed) != FrameError::kNone || parsed.count != 1) continue;
      const DatagramView& d = parsed.datagrams[0];
      // A frame of ours coming back: the same command, index and length (a slave counts an
      // auto-increment ADP on, so the address is not compared).
      if (d.header.command != command || d.header.index != index || d.header.length != length) continue;
      record({received_.data(), size});
      std::memcpy(data, d.data, length);
      return {true, d.working_counter};
    }
    ++frames_lost_;
  }
  return {};
}

std::uint16_t Master::count_slaves() {
  std::array<std::uint8_t, 2> type{};
  const Reply r = exchange(Command::kBrd, physical_address(0, reg::kType), type.data(), 2);
  return r.answered ? r.working_counter : 0;
}

std::vector<std::uint16_t> Master::assign_station_addresses(std::uint16_t slaves) {
  std::vector<std::uint16_t> addresses;
  for (std::uint16_t position = 0; position < slaves; ++position) {
    const auto station = static_cast<std::uint16_t>(params_.first_station_address + position);
    std::array<std::uint8_t, 2> value{};
    put_le16(value.data(), station);
    const Reply r =
        exchange(Command::kApwr, physical_address(auto_increment_adp(position), reg::kStationAddress), value.data(), 2);
    if (!r.answered || r.working_counter != 1) {
      throw std::runtime_error(
          "the slave at position " + std::to_string(position) + " did not take station address " +
          format_hex(station, 4) +
          (r.answered ? " (working counter " + std::to_string(r.working_counter) + ")" : " (no answer)"));
    }
    addresses.push_back(station);
  }
  return addresses;
}

void Master::write_register(std::uint16_t station, std::uint16_t address, const std::uint8_t* data,
                            std::uint16_t length, const char* what) {
  std::array<std::uint8_t, kMaxDatagramDataBytes> copy{};
  std::memcpy(copy.data(), data, length);
  const Reply r = exchange(Command::kFpwr, physical_address(station, address), copy.data(), length);
  if (!r.answered || r.working_counter != 1) {
    throw std::runtime_error(
        slave_name(station) + ": " + what + " (" + format_hex(address, 4) + ") not written: " +
        (r.answered ? "working counter " + std::to_string(r.working_counter) + ", expected 1" : "no answer"));
  }
}

void Master::read_register(std::uint16_t station, std::uint16_t address, std::uint8_t* data, std::uint16_t length,
                           const char* what) {
  const Reply r = exchange(Command::kFprd, physical_address(station, address), data, length);
  if (!r.answered || r.working_counter != 1) {
    throw std::runtime_error(
        slave_name(station) + ": " + what + " (" + format_hex(address, 4) + ") not read: " +
        (r.answered ? "working counter " + std::to_string(r.working_counter) + ", expected 1" : "no answer"));
  }
}

std::vector<std::uint16_t> Master::read_sii(std::uint16_t station, std::uint16_t word_address, std::uint16_t words) {
  std::vector<std::uint16_t> out;
  out.reserve(words);
  while (out.size() < words) {
    // The command and the word address in one write (0x0502-0x0507), then the data when not busy.
    std::array<std::uint8_t, 6> command{};
    put_le16(command.data(), kSiiReadCommand);
    put_le32(command.data() + 2, static_cast<std::uint32_t>(word_address + out.size()));
    write_register(station, reg::kSiiControl, command.data(), 6, "SII read command");
    std::array<std::uint8_t, 2> status{};
    const std::int64_t deadline = now_ns() + params_.state_timeout_ns;
    do {
      read_register(station, reg::kSiiControl, status.data(), 2, "SII status");
    } while ((status[1] & 0x87) != 0 && now_ns() < deadline);  // busy or a command pending
    if ((status[1] & 0x87) != 0) throw std::runtime_error(slave_name(station) + ": SII read stays busy");
    const std::uint16_t chunk = (status[0] & kSiiRead8Bytes) != 0 ? 4 : 2;
    std::array<std::uint8_t, 8> data{};
    read_register(station, reg::kSiiData, data.data(), static_cast<std::uint16_t>(2 * chunk), "SII data");
    for (std::uint16_t i = 0; i < chunk && out.size() < words; ++i) {
      out.push_back(static_cast<std::uint16_t>(data[2 * i] | (data[2 * i + 1] << 8)));
    }
  }
  return out;
}

SlaveInfo Master::read_slave_info(std::uint16_t station) {
  std::vector<std::uint16_t> words = read_sii(station, 0, sii::kFirstCategory);
  for (std::size_t at = sii::kFirstCategory; at + 2 <= kSiiMaxWords;) {
    const std::vector<std::uint16_t> header = read_sii(station, static_cast<std::uint16_t>(at), 2);
    words.insert(words.end(), header.begin(), header.end());
    if (header[0] == sii_category::kEnd) break;
    const std::size_t size = header[1];
    if (at + 2 + size > kSiiMaxWords) {
      throw std::runtime_error(slave_name(station) + ": SII category " + std::to_string(header[0]) + " at word " +
                               format_hex(static_cast<std::uint32_t>(at), 4) + " runs past " +
                               std::to_string(kSiiMaxWords) + " words");
    }
    const std::vector<std::uint16_t> data =
        read_sii(station, static_cast<std::uint16_t>(at + 2), static_cast<std::uint16_t>(size));
    words.insert(words.end(), data.begin(), data.end());
    at += 2 + size;
  }
  SlaveInfo info;
  try {
    static_cast<SiiInfo&>(info) = parse_sii(words);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(slave_name(station) + ": " + e.what());
  }
  info.station_address = station;
  return info;
}

void Master::configure_sync_manager(std::uint16_t station, std::uint8_t index, std::uint16_t start,
                                    std::uint16_t length, std::uint8_t control) {
  std::array<std::uint8_t, kSyncManagerBytes> sm{};
  put_le16(sm.data(), start);
  put_le16(sm.data() + 2, length);
  sm[4] = control;
  sm[6] = 0x01;  // enabled
  write_register(station, static_cast<std::uint16_t>(reg::kSyncManager0 + index * kSyncManagerBytes), sm.data(),
                 kSyncManagerBytes, "sync manager");
}

void Master::configure_mailbox(const SlaveInfo& slave) {
  const std::uint16_t station = slave.station_address;
  if (slave.mailbox_receive_size == 0 || slave.mailbox_send_size == 0) {
    throw std::runtime_error(slave_name(station) + ": its SII declares no mailbox");
  }
  SiiSyncManager receive{slave.mailbox_receive_offset, slave.mailbox_receive_size, kSmControlMailboxWrite, 1, 1};
  SiiSyncManager send{slave.mailbox_send_offset, slave.mailbox_send_size, kSmControlMailboxRead, 1, 2};
  for (const SiiSyncManager& sm : slave.sync_managers) {
    if (sm.type == receive.type && sm.start == receive.start) receive.control = sm.control;
    if (sm.type == send.type && sm.start == send.start) send.control = sm.control;
  }
  configure_sync_manager(station, 0, receive.start, receive.length, receive.control);
  configure_sync_manager(station, 1, send.start, send.length, send.control);
}

void Master::configure_fmmu(std::uint16_t station, std::uint8_t index, std::uint32_t logical, std::uint16_t length,
                            std::uint16_t physical, bool write) {
  std::array<std::uint8_t, kFmmuBytes> fmmu{};
  put_le32(fmmu.data(), logical);
  put_le16(fmmu.data() + 4, length);
  fmmu[7] = 7;  // the logical end bit: whole bytes
  put_le16(fmmu.data() + 8, physical);
  fmmu[11] = write ? 0x02 : 0x01;
  fmmu[12] = 0x01;  // active
  write_register(station, static_cast<std::uint16_t>(reg::kFmmu0 + index * kFmmuBytes), fmmu.data(), kFmmuBytes,
                 "FMMU");
}

void Master::configure_process_data_watchdog(std::uint16_t station, std::int64_t timeout_ns) {
  std::array<std::uint8_t, 2> divider{};
  read_register(station, reg::kWatchdogDivider, divider.data(), 2, "watchdog divider");
  const std::int64_t unit_ns = (static_cast<std::int64_t>(divider[0] | (divider[1] << 8)) + 2) * 40;
  const std::int64_t units = timeout_ns <= 0 ? 0 : (timeout_ns + unit_ns - 1) / unit_ns;
  if (timeout_ns < 0 || units > 0xFFFF) {
    throw std::invalid_argument(slave_name(station) + ": a process-data watchdog of " + std::to_string(timeout_ns) +
                                " ns needs " + std::to_string(units) + " units of " + std::to_string(unit_ns) +
                                " ns; 0x0420 holds 0 to 65535");
  }
  const std::array<std::uint8_t, 2> time{static_cast<std::uint8_t>(units & 0xFF),
                                         static_cast<std::uint8_t>(units >> 8)};
  write_register(station, reg::kWatchdogTimeProcessData, time.data(), 2, "process-data watchdog time");
}

StateResult Master::read_state(std::uint16_t station) {
  std::array<std::uint8_t, 6> status{};  // AL status, reserved, AL status code
  read_register(station, reg::kAlStatus, status.data(), 6, "AL status");
  StateResult r;
  r.state = static_cast<AlState>(status[0] & 0x0F);
  r.code = (status[0] & kAlErrorIndicator) != 0 ? static_cast<std::uint16_t>(status[4] | (status[5] << 8)) : 0;
  return r;
}

StateResult Master::request_state(std::uint16_t station, AlState state) {
  std::array<std::uint8_t, 2> control{static_cast<std::uint8_t>(state), 0};
  write_register(station, reg::kAlControl, control.data(), 2, "AL control");
  const std::int64_t deadline = now_ns() + params_.state_timeout_ns;
  for (;;) {
    StateResult r = read_state(station);
    if (r.code != 0) {
      // Refused: acknowledge the error in the state it stayed in, so the next request is heard.
      std::array<std::uint8_t, 2> ack{static_cast<std::uint8_t>(static_cast<std::uint8_t>(r.state) | kAlErrorIndicator),
                                      0};
      write_register(station, reg::kAlControl, ack.data(), 2, "AL control (acknowledge)");
      return r;
    }
    if (r.state == state) {
      r.reached = true;
      return r;
    }
    if (now_ns() >= deadline) return r;
  }
}

Master::CoeAnswer Master::coe_request(const SlaveInfo& slave, const SdoBytes& request, const std::uint8_t* more,
                                      std::size_t more_bytes) {
  const std::uint16_t station = slave.station_address;
  if (slave.mailbox_receive_size < kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes ||
      slave.mailbox_receive_size > kMaxDatagramDataBytes || slave.mailbox_send_size > kMaxDatagramDataBytes) {
    throw std::runtime_error(slave_name(station) + ": no mailbox for CoE (receive " +
                             std::to_string(slave.mailbox_receive_size) + " bytes, send " +
                             std::to_string(slave.mailbox_send_size) + ")");
  }
  std::array<std::uint8_t, kMaxDatagramDataBytes> mailbox{};
  mailbox_counter_ = static_cast<std::uint8_t>(mailbox_counter_ % 7 + 1);
  write_coe_sdo(mailbox.data(), mailbox_counter_, kCoeServiceSdoRequest, request, more, more_bytes);
  // The whole receive mailbox: the slave takes a message when its last byte is written.
  write_register(station, slave.mailbox_receive_offset, mailbox.data(), slave.mailbox_receive_size, "receive mailbox");
  // The answer: SM1's status says when the send mailbox is full; then the whole of it is read. A
  // CoE emergency the slave posted before it comes first: taken, counted, and the answer waited for.
  const auto sm1_status = static_cast<std::uint16_t>(reg::kSyncManager0 + kSyncManagerBytes + 5);
  const std::int64_t deadline = now_ns() + params_.state_timeout_ns;
  CoeAnswer answer;
  for (;;) {
    for (std::array<std::uint8_t, 1> status{};;) {
      read_register(station, sm1_status, status.data(), 1, "send mailbox status");
      if ((status[0] & 0x08) != 0) break;
      if (now_ns() >= deadline) throw std::runtime_error(slave_name(station) + ": no answer in the send mailbox");
    }
    read_register(station, slave.mailbox_send_offset, mailbox.data(), slave.mailbox_send_size, "send mailbox");
    MailboxHeader header;
    std::uint8_t service = 0;
    const MailboxError error = parse_coe_sdo(mailbox.data(), slave.mailbox_send_size, header, service, answer.sdo);
    if (error == MailboxError::kNotSdo && service == kCoeServiceEmergency) {
      // Its error code follows the CoE header (then the error register and 5 bytes of the maker's).
      ++emergencies_;
      last_emergency_code_ = get_le16(mailbox.data() + kMailboxHeaderBytes + kCoeHeaderBytes);
      if (now_ns() >= deadline) throw std::runtime_error(slave_name(station) + ": emergencies, no SDO answer");
      continue;
    }
    if (error != MailboxError::kNone || service != kCoeServiceSdoResponse) {
      throw std::runtime_error(slave_name(station) + ": the send mailbox held no SDO response (" +
                               (error != MailboxError::kNone ? to_string(error) : "another service") + ")");
    }
    const auto* more = mailbox.data() + kCoeSdoMoreAt;
    answer.more.assign(more, more + coe_sdo_more_bytes(header));
    return answer;
  }
}

bool Master::poll_emergency(const SlaveInfo& slave, std::int64_t reply_timeout_ns, int retries) {
  if (slave.mailbox_send_size < kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes ||
      slave.mailbox_send_size > kMaxDatagramDataBytes) {
    return false;
  }
  const std::uint16_t station = slave.station_address;
  const auto sm1_status = static_cast<std::uint16_t>(reg::kSyncManager0 + kSyncManagerBytes + 5);
  std::array<std::uint8_t, 1> status{};
  Reply r =
      exchange(Command::kFprd, physical_address(station, sm1_status), status.data(), 1, reply_timeout_ns, retries);
  if (!r.answered || r.working_counter != 1 || (status[0] & 0x08) == 0) return false;
  std::array<std::uint8_t, kMaxDatagramDataBytes> mailbox{};
  r = exchange(Command::kFprd, physical_address(station, slave.mailbox_send_offset), mailbox.data(),
               slave.mailbox_send_size, reply_timeout_ns, retries);
  if (!r.answered || r.working_counter != 1) return false;
  MailboxHeader header;
  std::uint8_t service = 0;
  SdoBytes body{};
  if (parse_coe_sdo(mailbox.data(), slave.mailbox_send_size, header, service, body) == MailboxError::kNotSdo &&
      service == kCoeServiceEmergency) {
    ++emergencies_;
    last_emergency_code_ = get_le16(mailbox.data() + kMailboxHeaderBytes + kCoeHeaderBytes);
    return true;
  }
  ++mailbox_unexpected_;
  return false;
}

SdoResult Master::sdo_transfer(const SlaveInfo& slave, const SdoBytes& request) {
  return expedited_answer(slave, coe_request(slave, request));
}

SdoResult Master::expedited_answer(const SlaveInfo& slave, const CoeAnswer& answer) {
  canopen::CanFrame frame{};
  frame.id = canopen::sdo_tx_cob_id(canopen::NodeId(1));
  frame.dlc = 8;
  std::copy(answer.sdo.begin(), answer.sdo.end(), frame.data.begin());
  const canopen::Result<canopen::SdoResponse> parsed = canopen::parse_sdo_response(frame);
  if (!parsed) {
    throw std::runtime_error(slave_name(slave.station_address) + ": an SDO response not understood: " +
                             canopen::to_string(parsed.error) + " (" + parsed.detail + ")");
  }
  SdoResult r;
  const canopen::SdoResponse& response = parsed.value;
  r.done = response.kind != canopen::SdoResponseKind::kAbort;
  r.abort_code = response.abort_code;
  r.value = response.data.data;
  r.size = response.data.size;
  if (response.kind == canopen::SdoResponseKind::kUpload) {
    for (std::uint8_t i = 0; i < (r.size == 0 ? 4 : r.size); ++i) r.bytes.push_back(answer.sdo[4 + i]);
  }
  return r;
}

SdoResult Master::sdo_upload(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex, bool complete_access) {
  const canopen::CanFrame request = canopen::sdo_upload_request(canopen::NodeId(1), index, subindex);
  SdoBytes bytes{};
  std::copy(request.data.begin(), request.data.end(), bytes.begin());
  if (complete_access) bytes[0] = static_cast<std::uint8_t>(bytes[0] | 0x10U);  // CoE's complete access
  const CoeAnswer first = coe_request(slave, bytes);
  // 0x41: a normal upload (CoE): the complete size, then the data; segments for the rest.
  constexpr std::uint8_t kNormalUpload = 0x41;
  if ((first.sdo[0] & 0xE3U) != kNormalUpload) {
    // Expedited, or an abort: what the CANopen codec reads.
    return expedited_answer(slave, first);
  }
  return normal_upload(slave, index, subindex, first);
}

SdoResult Master::normal_upload(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex,
                                const CoeAnswer& first) {
  const std::string what =
      slave_name(slave.station_address) + " " + format_hex(index, 4) + ":" + std::to_string(subindex) + ": ";
  const std::uint32_t total = get_le32(first.sdo.data() + 4);
  if (total > kMaxUploadBytes) {
    abort_transfer(slave, index, subindex, canopen::kAbortOutOfMemory);
    throw std::runtime_error(what + "an upload of " + std::to_string(total) + " bytes (at most " +
                             std::to_string(kMaxUploadBytes) + " taken)");
  }
  SdoResult r;
  r.expedited = false;
  r.bytes.assign(first.more.begin(), first.more.begin() + std::min<std::size_t>(total, first.more.size()));
  for (std::uint8_t toggle = 0; r.bytes.size() < total; toggle ^= 1U) {
    SdoBytes request{};
    request[0] = static_cast<std::uint8_t>(0x60U | (toggle << 4));  // upload segment request
    const CoeAnswer segment = coe_request(slave, request);
    const std::uint8_t command = segment.sdo[0];
    if ((command >> 5) == 4) {  // the slave's abort
      r.abort_code = get_le32(segment.sdo.data() + 4);
      return r;
    }
    if ((command >> 5) != 0 || ((command >> 4) & 1U) != toggle) {
      abort_transfer(slave, index, subindex, canopen::kAbortToggleBit);
      throw std::runtime_error(what + "segment " + format_hex(command, 2) + " is not the upload segment (toggle " +
                               std::to_string(toggle) + ") asked for");
    }
    // Past 10 bytes of message every byte is data; a message of 10 says how many of its 7 are not.
    const std::size_t in_eight = segment.more.empty() ? 7 - ((command >> 1) & 7U) : 7;
    const std::size_t take = std::min<std::size_t>(total - r.bytes.size(), in_eight + segment.more.size());
    for (std::size_t i = 0; i < take; ++i) {
      r.bytes.push_back(i < in_eight ? segment.sdo[1 + i] : segment.more[i - in_eight]);
    }
    if ((command & 1U) != 0) break;  // the last segment
  }
  if (r.bytes.size() != total) {
    throw std::runtime_error(what + "the upload ended after " + std::to_string(r.bytes.size()) + " of " +
                             std::to_string(total) + " bytes");
  }
  r.done = true;
  for (std::size_t i = 0; i < std::min<std::size_t>(4, total); ++i) r.value |= std::uint32_t{r.bytes[i]} << (8 * i);
  return r;
}

void Master::abort_transfer(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex, std::uint32_t code) {
  const canopen::CanFrame abort = canopen::sdo_abort_request(canopen::NodeId(1), index, subindex, code);
  SdoBytes bytes{};
  std::copy(abort.data.begin(), abort.data.end(), bytes.begin());
  std::array<std::uint8_t, kMaxDatagramDataBytes> mailbox{};
  mailbox_counter_ = static_cast<std::uint8_t>(mailbox_counter_ % 7 + 1);
  write_coe_sdo(mailbox.data(), mailbox_counter_, kCoeServiceSdoRequest, bytes);
  write_register(slave.station_address, slave.mailbox_receive_offset, mailbox.data(), slave.mailbox_receive_size,
                 "receive mailbox");
}

SdoResult Master::sdo_download_record(const SlaveInfo& slave, std::uint16_t index,
                                      const std::vector<std::uint8_t>& record) {
  const std::size_t room = std::min<std::size_t>(slave.mailbox_receive_size, kMaxDatagramDataBytes);
  if (room < kCoeSdoMoreAt) {
    throw std::runtime_error(slave_name(slave.station_address) + ": no mailbox for CoE (receive " +
                             std::to_string(slave.mailbox_receive_size) + " bytes)");
  }
  // 0x31: initiate download, size indicated, not expedited, complete access from sub-index 0, with
  // as much of the record as the receive mailbox holds after the 8 bytes.
  SdoBytes request{};
  request[0] = 0x31;
  put_le16(request.data() + 1, index);
  put_le32(request.data() + 4, static_cast<std::uint32_t>(record.size()));
  std::size_t sent = std::min(record.size(), room - kCoeSdoMoreAt);
  SdoResult r = expedited_answer(slave, coe_request(slave, request, record.data(), sent));
  // The rest in download segments: 7 bytes in the 8, as many after them as the mailbox holds.
  for (std::uint8_t toggle = 0; r.done && sent < record.size(); toggle ^= 1U) {
    const std::size_t take = std::min(record.size() - sent, room - kCoeSdoMoreAt + 7);
    const bool last = sent + take == record.size();
    SdoBytes segment{};
    const std::size_t in_seven = std::min<std::size_t>(take, 7);
    segment[0] = static_cast<std::uint8_t>((toggle << 4) | ((7 - in_seven) << 1) | (last ? 1U : 0U));
    std::copy(record.begin() + static_cast<std::ptrdiff_t>(sent),
              record.begin() + static_cast<std::ptrdiff_t>(sent + in_seven), segment.begin() + 1);
    const CoeAnswer answer = coe_request(slave, segment, record.data() + sent + in_seven, take - in_seven);
    const std::uint8_t command = answer.sdo[0];
    if ((command >> 5) == 4) {  // the slave's abort
      r.done = false;
      r.abort_code = get_le32(answer.sdo.data() + 4);
      return r;
    }
    if ((command >> 5) != 1 || ((command >> 4) & 1U) != toggle) {
      abort_transfer(slave, index, 0, canopen::kAbortToggleBit);
      throw std::runtime_error(slave_name(slave.station_address) + " " + format_hex(index, 4) + ": answer " +
                               format_hex(command, 2) + " is not the download segment response (toggle " +
                               std::to_string(toggle) + ")");
    }
    sent += take;
  }
  return r;
}

SdoResult Master::sdo_download(const SlaveInfo& slave, std::uint16_t index, std::uint8_t subindex, std::uint32_t value,
                               std::uint8_t size) {
  const canopen::Result<canopen::CanFrame> request =
      canopen::sdo_download_request(canopen::NodeId(1), index, subindex, value, size);
  if (!request) throw std::invalid_argument("sdo_download: size must be 1 to 4, got " + std::to_string(size));
  std::array<std::uint8_t, 8> bytes{};
  std::copy(request.value.data.begin(), request.value.data.end(), bytes.begin());
  return sdo_transfer(slave, bytes);
}

void Master::write_pdo_assignment(const SlaveInfo& slave, std::uint16_t assign_index, std::uint16_t first_pdo,
                                  const std::vector<canopen::PdoMapEntry>& entries) {
  // Greedy: each PDO takes entries while they fit (8 entries, 64 bits).
  std::vector<std::vector<canopen::PdoMapEntry>> pdos;
  std::uint32_t bits = 0;
  for (const canopen::PdoMapEntry& e : entries) {
    if (e.bit_length == 0 || e.bit_length > 32) {
      throw std::invalid_argument(format_hex(e.index, 4) + ":" + std::to_string(e.subindex) + ": " +
                                  std::to_string(e.bit_length) + " bits; an entry is 8, 16 or 32");
    }
    if (pdos.empty() || pdos.back().size() == canopen::kPdoMaxEntries || bits + e.bit_length > canopen::kPdoMaxBits) {
      pdos.emplace_back();
      bits = 0;
    }
    pdos.back().push_back(e);
    bits += e.bit_length;
  }
  if (pdos.size() > 4) {
    throw std::invalid_argument(std::to_string(entries.size()) + " entries need " + std::to_string(pdos.size()) +
                                " PDOs of 64 bits; a sync manager takes 4 here");
  }
  // A refusal of a record sends it all again entry by entry, which names the entry refused.
  if ((slave.coe_details & kCoeDetailsCompleteAccess) != 0 &&
      write_pdo_assignment_whole(slave, assign_index, first_pdo, pdos)) {
    return;
  }
  write_pdo_assignment_by_entry(slave, assign_index, first_pdo, pdos);
}

bool Master::write_pdo_assignment_whole(const SlaveInfo& slave, std::uint16_t assign_index, std::uint16_t first_pdo,
                                        const std::vector<std::vector<canopen::PdoMapEntry>>& pdos) {
  // Each record whole: the assignment emptied, each mapping, then the assignment (three SDOs for
  // one PDO instead of an SDO an entry); the slave keeps CiA 301's order inside each.
  if (!sdo_download_record(slave, assign_index, {0, 0}).done) return false;
  std::vector<std::uint8_t> assignment{static_cast<std::uint8_t>(pdos.size()), 0};
  for (std::size_t p = 0; p < pdos.size(); ++p) {
    const auto pdo = static_cast<std::uint16_t>(first_pdo + p);
    std::vector<std::uint8_t> mapping{static_cast<std::uint8_t>(pdos[p].size()), 0};
    for (const canopen::PdoMapEntry& e : pdos[p]) {
      const std::uint32_t coded = canopen::encode_pdo_mapping(e);
      for (int i = 0; i < 4; ++i) mapping.push_back(static_cast<std::uint8_t>(coded >> (8 * i)));
    }
    if (!sdo_download_record(slave, pdo, mapping).done) return false;
    assignment.push_back(static_cast<std::uint8_t>(pdo & 0xFFU));
    assignment.push_back(static_cast<std::uint8_t>(pdo >> 8));
  }
  return sdo_download_record(slave, assign_index, assignment).done;
}

void Master::write_pdo_assignment_by_entry(const SlaveInfo& slave, std::uint16_t assign_index, std::uint16_t first_pdo,
                                           const std::vector<std::vector<canopen::PdoMapEntry>>& pdos) {
  const auto write = [&](std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
    const SdoResult r = sdo_download(slave, index, sub, value, size);
    if (!r.done) {
      throw std::runtime_error(slave_name(slave.station_address) + ": " + format_hex(index, 4) + ":" +
                               std::to_string(sub) + " = " + format_hex(value, 2 * size) + " " + r.describe());
    }
  };
  write(assign_index, 0, 0, 1);
  for (std::size_t p = 0; p < pdos.size(); ++p) {
    const auto pdo = static_cast<std::uint16_t>(first_pdo + p);
    write(pdo, 0, 0, 1);
    for (std::size_t k = 0; k < pdos[p].size(); ++k) {
      write(pdo, static_cast<std::uint8_t>(k + 1), canopen::encode_pdo_mapping(pdos[p][k]), 4);
    }
    write(pdo, 0, static_cast<std::uint32_t>(pdos[p].size()), 1);
    write(assign_index, static_cast<std::uint8_t>(p + 1), pdo, 2);
  }
  write(assign_index, 0, static_cast<std::uint32_t>(pdos.size()), 1);
}

void Master::configure_distributed_clock(std::uint16_t station, std::uint64_t master_time_ns) {
  configure_distributed_clocks({station}, master_time_ns);
}

std::vector<DcSlave> Master::configure_distributed_clocks(const std::vector<std::uint16_t>& stations,
                                                          std::uint64_t master_time_ns) {
  // The latch first, so that the master's time (taken just before the call) is the frame's.
  std::array<std::uint8_t, 4> latch{};
  const Reply r = exchange(Command::kBwr, physical_address(0, reg::kDcReceiveTimePort0), latch.data(), 4);
  std::vector<DcSlave> line;
  for (const std::uint16_t station : stations) {
    std::array<std::uint8_t, 8> bytes{};
    read_register(station, reg::kFeatures, bytes.data(), 2, "ESC features");
    if ((bytes[0] & 0x0C) != 0x0C) continue;  // no 64-bit clock: a piece of cable to the others
    if (!r.answered || r.working_counter == 0) {
      throw std::runtime_error(slave_name(station) + ": the receive time latch (BWR 0x0900) was not taken");
    }
    DcSlave s;
    s.station = station;
    read_register(station, reg::kDcReceiveTimePort0, bytes.data(), 8, "DC receive times, ports 0 and 1");
    const std::uint32_t port0 = get_le32(bytes.data());
    const std::uint32_t port1 = get_le32(bytes.data() + 4);
    // The time the frame spent behind this slave (0 at the end of the line: port 1 closed).
    s.behind_ns = port1 == 0 ? 0 : static_cast<std::uint32_t>(port1 - port0);
    read_register(station, reg::kDcReceiveTimeUnit, bytes.data(), 8, "DC receive time");
    s.latched_local_ns = get_le32(bytes.data()) | (static_cast<std::uint64_t>(get_le32(bytes.data() + 4)) << 32);
    line.push_back(s);
  }
  if (line.empty() && stations.size() == 1) {
    throw std::runtime_error(slave_name(stations[0]) + ": no 64-bit distributed clock");
  }
  // Down a line the frame reaches each slave half of what the one before saw behind it, less what
  // this one sees behind itself, after the one before (ETG.1000.4's propagation delay); the first
  // is the reference, its system time the master's.
  for (std::size_t i = 0; i < line.size(); ++i) {
    DcSlave& s = line[i];
    if (i > 0) {
      const DcSlave& before = line[i - 1];
      const std::int64_t hops = static_cast<std::int64_t>(before.behind_ns) - static_cast<std::int64_t>(s.behind_ns);
      s.delay_ns = before.delay_ns + static_cast<std::uint32_t>(std::max<std::int64_t>(hops, 0) / 2);
    }
    const std::uint64_t offset = master_time_ns + s.delay_ns - s.latched_local_ns;
    std::array<std::uint8_t, 8> bytes{};
    put_le32(bytes.data(), static_cast<std::uint32_t>(offset));
    put_le32(bytes.data() + 4, static_cast<std::uint32_t>(offset >> 32));
    write_register(s.station, reg::kDcSystemTimeOffset, bytes.data(), 8, "DC system time offset");
    put_le32(bytes.data(), s.delay_ns);
    write_register(s.station, reg::kDcSystemTimeDelay, bytes.data(), 4, "DC system time delay");
  }
  return line;
}

std::uint64_t Master::configure_sync0(std::uint16_t station, std::int64_t cycle_ns, std::int64_t shift_ns,
                                      std::int64_t lead_ns) {
  if (cycle_ns <= 0 || cycle_ns > 0xFFFFFFFFLL) {
    throw std::invalid_argument("SYNC0 cycle: 1 ns to 4.29 s, got " + std::to_string(cycle_ns) + " ns");
  }
  if (shift_ns < 0 || shift_ns >= cycle_ns) {
    throw std::invalid_argument("SYNC0 shift: 0 to the cycle (" + std::to_string(cycle_ns) + " ns), got " +
                                std::to_string(shift_ns) + " ns");
  }
  if (lead_ns < 0) throw std::invalid_argument("SYNC0 lead: >= 0, got " + std::to_string(lead_ns) + " ns");
  std::array<std::uint8_t, 8> bytes{};
  write_register(station, reg::kDcActivation, bytes.data(), 1, "DC activation (off)");
  read_register(station, reg::kDcSystemTime, bytes.data(), 8, "DC system time");
  const std::uint64_t now = get_le32(bytes.data()) | (static_cast<std::uint64_t>(get_le32(bytes.data() + 4)) << 32);
  // The first whole cycle at least `lead_ns` ahead, plus the shift: every pulse then falls on the
  // cycle's grid of system time, which the master's own cycle follows (distributed clocks).
  const auto cycle = static_cast<std::uint64_t>(cycle_ns);
  const std::uint64_t start =
      ((now + static_cast<std::uint64_t>(lead_ns)) / cycle + 1) * cycle + static_cast<std::uint64_t>(shift_ns);
  put_le32(bytes.data(), static_cast<std::uint32_t>(cycle_ns));
  write_register(station, reg::kDcSync0CycleTime, bytes.data(), 4, "SYNC0 cycle time");
  put_le32(bytes.data(), static_cast<std::uint32_t>(start));
  put_le32(bytes.data() + 4, static_cast<std::uint32_t>(start >> 32));
  write_register(station, reg::kDcStartTime, bytes.data(), 8, "SYNC0 start time");
  bytes[0] = 0x03;  // the cyclic unit on, with SYNC0
  write_register(station, reg::kDcActivation, bytes.data(), 1, "DC activation (SYNC0)");
  return start;
}

Reply Master::write_system_time(std::uint16_t station, std::uint64_t master_time_ns, std::int64_t reply_timeout_ns,
                                int retries) {
  std::array<std::uint8_t, 8> bytes{};
  put_le32(bytes.data(), static_cast<std::uint32_t>(master_time_ns));
  put_le32(bytes.data() + 4, static_cast<std::uint32_t>(master_time_ns >> 32));
  return exchange(Command::kFpwr, physical_address(station, reg::kDcSystemTime), bytes.data(), 8, reply_timeout_ns,
                  retries);
}

std::int64_t Master::read_system_time_difference(std::uint16_t station) {
  std::array<std::uint8_t, 4> bytes{};
  read_register(station, reg::kDcSystemTimeDifference, bytes.data(), 4, "DC system time difference");
  const std::uint32_t value = get_le32(bytes.data());
  const auto magnitude = static_cast<std::int64_t>(value & 0x7FFFFFFFU);
  return (value & 0x80000000U) != 0 ? magnitude : -magnitude;
}

int ProcessDataLayout::offset_in(const std::vector<canopen::PdoMapEntry>& entries, std::uint16_t index,
                                 std::uint8_t subindex) {
  int bits = 0;
  for (const canopen::PdoMapEntry& e : entries) {
    if (e.index == index && e.subindex == subindex) return bits / 8;
    bits += e.bit_length;
  }
  return -1;
}

std::vector<canopen::PdoMapEntry> Master::assigned_entries(const SlaveInfo& slave, std::uint16_t assign_index) {
  const auto checked = [&](std::uint16_t index, std::uint8_t sub) {
    const SdoResult r = sdo_upload(slave, index, sub);
    if (!r.done) {
      throw std::runtime_error(slave_name(slave.station_address) + ": " + format_hex(index, 4) + ":" +
                               std::to_string(sub) + " " + r.describe());
    }
    return r.value;
  };
  std::vector<canopen::PdoMapEntry> out;
  const std::uint32_t pdos = checked(assign_index, 0);
  for (std::uint32_t i = 1; i <= pdos; ++i) {
    const auto pdo = static_cast<std::uint16_t>(checked(assign_index, static_cast<std::uint8_t>(i)));
    const std::uint32_t entries = checked(pdo, 0);
    for (std::uint32_t e = 1; e <= entries; ++e) {
      out.push_back(canopen::decode_pdo_mapping(checked(pdo, static_cast<std::uint8_t>(e))));
    }
  }
  return out;
}

ProcessDataLayout Master::map_process_data(const SlaveInfo& slave, std::uint32_t logical) {
  const std::uint16_t station = slave.station_address;
  const SiiSyncManager* outputs = nullptr;
  const SiiSyncManager* inputs = nullptr;
  for (const SiiSyncManager& sm : slave.sync_managers) {
    if (sm.type == 3 && outputs == nullptr) outputs = &sm;
    if (sm.type == 4 && inputs == nullptr) inputs = &sm;
  }
  if (outputs == nullptr || inputs == nullptr) {
    throw std::runtime_error(slave_name(station) + ": its SII has no sync manager for the process data");
  }
  ProcessDataLayout layout;
  // Whole bytes: a PDO of a CiA 402 drive is bytes.
  layout.outputs = assigned_entries(slave, 0x1C12);
  layout.inputs = assigned_entries(slave, 0x1C13);
  const auto bytes_of = [](const std::vector<canopen::PdoMapEntry>& entries) {
    std::uint32_t bits = 0;
    for (const canopen::PdoMapEntry& e : entries) bits += e.bit_length;
    return static_cast<std::uint16_t>((bits + 7) / 8);
  };
  layout.output_bytes = bytes_of(layout.outputs);
  layout.input_bytes = bytes_of(layout.inputs);
  layout.outputs_logical = logical;
  layout.inputs_logical = logical + layout.output_bytes;
  if (layout.output_bytes > 0) {
    configure_sync_manager(station, 2, outputs->start, layout.output_bytes, outputs->control);
    configure_fmmu(station, 0, layout.outputs_logical, layout.output_bytes, outputs->start, true);
  }
  if (layout.input_bytes > 0) {
    configure_sync_manager(station, 3, inputs->start, layout.input_bytes, inputs->control);
    configure_fmmu(station, 1, layout.inputs_logical, layout.input_bytes, inputs->start, false);
  }
  return layout;
}

}  // namespace pmlsm::ethercat
