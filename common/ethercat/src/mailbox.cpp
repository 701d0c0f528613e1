#include "pmlsm/ethercat/mailbox.hpp"

#include <algorithm>

#include "pmlsm/canopen/cob_id.hpp"
#include "pmlsm/util/little_endian.hpp"

namespace pmlsm::ethercat {

namespace {

// CiA 301's command specifiers (the top 3 bits of the command byte) and flags.
constexpr std::uint8_t kCcsDownloadSegment = 0;
constexpr std::uint8_t kCcsInitiateDownload = 1;
constexpr std::uint8_t kCcsInitiateUpload = 2;  // scs 2: initiate upload response
constexpr std::uint8_t kCcsUploadSegment = 3;
constexpr std::uint8_t kCcsInitiateDownloadResponse = 3;
constexpr std::uint8_t kCcsAbort = 4;
constexpr std::uint8_t kBitExpedited = 1U << 1;
constexpr std::uint8_t kBitSizeIndicated = 1U << 0;
constexpr std::uint8_t kBitCompleteAccess = 1U << 4;  // CoE: the whole record (initiate requests)

}  // namespace

const char* to_string(MailboxError error) {
  switch (error) {
    case MailboxError::kNone: return "none";
    case MailboxError::kShort: return "shorter than its headers";
    case MailboxError::kLengthBeyondMailbox: return "a length past the mailbox";
    case MailboxError::kNotCoe: return "not CoE";
    case MailboxError::kNotSdo: return "a CoE service other than SDO";
  }
  return "?";
}

std::size_t write_coe_sdo(std::uint8_t* out, std::uint8_t counter, std::uint8_t service, const SdoBytes& sdo,
                          const std::uint8_t* more, std::size_t more_bytes) {
  put_le16(out, static_cast<std::uint16_t>(kCoeHeaderBytes + kSdoBytes + more_bytes));
  put_le16(out + 2, 0);  // address: the master
  out[4] = 0;            // channel 0, priority 0
  out[5] = static_cast<std::uint8_t>(kMailboxTypeCoe | ((counter & 0x07U) << 4));
  put_le16(out + kMailboxHeaderBytes, static_cast<std::uint16_t>(service << 12));
  std::copy(sdo.begin(), sdo.end(), out + kMailboxHeaderBytes + kCoeHeaderBytes);
  if (more_bytes > 0) std::copy(more, more + more_bytes, out + kCoeSdoMoreAt);
  return kCoeSdoMoreAt + more_bytes;
}

MailboxError parse_coe_sdo(const std::uint8_t* mailbox, std::size_t size, MailboxHeader& header, std::uint8_t& service,
                           SdoBytes& sdo) {
  if (size < kMailboxHeaderBytes) return MailboxError::kShort;
  header.length = get_le16(mailbox);
  header.address = get_le16(mailbox + 2);
  header.channel = static_cast<std::uint8_t>(mailbox[4] & 0x3FU);
  header.priority = static_cast<std::uint8_t>(mailbox[4] >> 6);
  header.type = static_cast<std::uint8_t>(mailbox[5] & 0x0FU);
  header.counter = static_cast<std::uint8_t>((mailbox[5] >> 4) & 0x07U);
  if (kMailboxHeaderBytes + header.length > size) return MailboxError::kLengthBeyondMailbox;
  if (header.type != kMailboxTypeCoe) return MailboxError::kNotCoe;
  if (header.length < kCoeHeaderBytes + kSdoBytes) return MailboxError::kShort;
  service = static_cast<std::uint8_t>(get_le16(mailbox + kMailboxHeaderBytes) >> 12);
  if (service != kCoeServiceSdoRequest && service != kCoeServiceSdoResponse) return MailboxError::kNotSdo;
  std::copy(mailbox + kMailboxHeaderBytes + kCoeHeaderBytes,
            mailbox + kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes, sdo.begin());
  return MailboxError::kNone;
}

std::size_t CoeSdoServer::handle(const std::uint8_t* request, std::size_t size, std::uint8_t* response,
                                 std::size_t capacity) {
  MailboxHeader header;
  std::uint8_t service = 0;
  SdoBytes sdo{};
  if (parse_coe_sdo(request, size, header, service, sdo) != MailboxError::kNone || service != kCoeServiceSdoRequest ||
      capacity < kMailboxHeaderBytes + kCoeHeaderBytes + kSdoBytes) {
    return 0;
  }
  ++requests_;
  const std::uint8_t command = sdo[0];
  const auto index = static_cast<std::uint16_t>(sdo[1] | (sdo[2] << 8));
  const std::uint8_t subindex = sdo[3];
  switch (command >> 5) {
    case kCcsInitiateUpload:
      upload_ = {};  // a new request ends any transfer under way
      download_ = {};
      if ((command & kBitCompleteAccess) != 0) {
        const std::uint32_t code = read_record(index, subindex);
        if (code != canopen::kAbortNone) return abort(response, index, subindex, code);
        return start_upload(index, subindex, true, response, capacity);
      }
      if (const canopen::TextEntry* text = dictionary_.find_text(index, subindex)) {
        upload_data_.assign(text->text.begin(), text->text.end());
        return start_upload(index, subindex, false, response, capacity);
      }
      break;
    case kCcsUploadSegment: return upload_segment(command, response, capacity);
    case kCcsInitiateDownload:
      upload_ = {};
      download_ = {};
      if ((command & kBitExpedited) == 0) {
        return normal_download(sdo, request + kCoeSdoMoreAt, coe_sdo_more_bytes(header), response);
      }
      if ((command & kBitCompleteAccess) != 0) {  // a whole record of up to 4 bytes, expedited
        const std::size_t bytes = (command & kBitSizeIndicated) != 0 ? 4 - ((command >> 2) & 3U) : 4;
        const std::uint32_t code = write_record(index, subindex, sdo.data() + 4, bytes);
        if (code != canopen::kAbortNone) return abort(response, index, subindex, code);
        return downloaded(response, index, subindex);
      }
      break;
    case kCcsDownloadSegment:
      return download_segment(sdo, request + kCoeSdoMoreAt, coe_sdo_more_bytes(header), response);
    case kCcsAbort:
      upload_ = {};
      download_ = {};
      break;
    default: break;
  }
  // The CANopen server's request frame: its own COB-ID, the 8 bytes as they came.
  canopen::CanFrame frame{};
  frame.id = canopen::sdo_rx_cob_id(server_.node());
  frame.dlc = 8;
  std::copy(sdo.begin(), sdo.end(), frame.data.begin());
  const canopen::SdoServerResult r = server_.handle(frame);
  if (!r.respond) return 0;  // the client's abort: nothing to answer
  SdoBytes answer{};
  std::copy(r.response.data.begin(), r.response.data.end(), answer.begin());
  return respond(response, answer);
}

std::size_t CoeSdoServer::respond(std::uint8_t* response, const SdoBytes& sdo, const std::uint8_t* more,
                                  std::size_t more_bytes) {
  counter_ = static_cast<std::uint8_t>(counter_ % 7 + 1);
  return write_coe_sdo(response, counter_, kCoeServiceSdoResponse, sdo, more, more_bytes);
}

std::size_t CoeSdoServer::downloaded(std::uint8_t* response, std::uint16_t index, std::uint8_t subindex) {
  SdoBytes answer{};
  answer[0] = kCcsInitiateDownloadResponse << 5;
  put_le16(answer.data() + 1, index);
  answer[3] = subindex;
  return respond(response, answer);
}

std::size_t CoeSdoServer::abort(std::uint8_t* response, std::uint16_t index, std::uint8_t subindex,
                                std::uint32_t code) {
  upload_ = {};
  SdoBytes sdo{};
  sdo[0] = kCcsAbort << 5;
  put_le16(sdo.data() + 1, index);
  sdo[3] = subindex;
  put_le32(sdo.data() + 4, code);
  return respond(response, sdo);
}

std::size_t CoeSdoServer::start_upload(std::uint16_t index, std::uint8_t subindex, bool complete_access,
                                       std::uint8_t* response, std::size_t capacity) {
  // 0x41: initiate upload response, size indicated, not expedited; the complete size in bytes 4-7.
  SdoBytes sdo{};
  sdo[0] = static_cast<std::uint8_t>((kCcsInitiateUpload << 5) | kBitSizeIndicated |
                                     (complete_access ? kBitCompleteAccess : 0U));
  put_le16(sdo.data() + 1, index);
  sdo[3] = subindex;
  put_le32(sdo.data() + 4, static_cast<std::uint32_t>(upload_data_.size()));
  const std::size_t room = capacity - kCoeSdoMoreAt;
  const std::size_t first = std::min(room, upload_data_.size());
  if (first < upload_data_.size()) upload_ = {true, index, subindex, first, 0};
  return respond(response, sdo, upload_data_.data(), first);
}

std::size_t CoeSdoServer::upload_segment(std::uint8_t command, std::uint8_t* response, std::size_t capacity) {
  if (!upload_.active) return abort(response, 0, 0, canopen::kAbortCommandSpecifier);  // no upload under way
  if (((command >> 4) & 1U) != upload_.toggle) {
    return abort(response, upload_.index, upload_.subindex, canopen::kAbortToggleBit);
  }
  // The command byte, then as many bytes as the mailbox holds; at least 7 (n of them unused).
  const std::size_t room = capacity - kMailboxHeaderBytes - kCoeHeaderBytes - 1;
  const std::size_t left = upload_data_.size() - upload_.sent;
  const std::size_t bytes = std::min(room, left);
  const bool last = bytes == left;
  const std::uint8_t* data = upload_data_.data() + upload_.sent;
  SdoBytes sdo{};
  const std::size_t in_eight = std::min<std::size_t>(bytes, kSdoBytes - 1);
  sdo[0] = static_cast<std::uint8_t>((upload_.toggle << 4) | ((kSdoBytes - 1 - in_eight) << 1) | (last ? 1U : 0U));
  std::copy(data, data + in_eight, sdo.begin() + 1);
  upload_.sent += bytes;
  upload_.toggle ^= 1U;
  ++segments_;
  if (last) upload_ = {};
  return respond(response, sdo, data + in_eight, bytes - in_eight);
}

const canopen::Entry* CoeSdoServer::record_count(std::uint16_t index, std::uint32_t& code) const {
  const canopen::Entry* count = dictionary_.find(index, 0);
  code = dictionary_.locate(index, 0);
  if (count == nullptr) {
    if (code == canopen::kAbortNone) code = canopen::kAbortUnsupportedAccess;  // a text
    return nullptr;
  }
  const bool entries = std::any_of(dictionary_.begin(), dictionary_.end(),
                                   [&](const canopen::Entry& e) { return e.index == index && e.subindex > 0; });
  if (count->type != canopen::DataType::kU8 || !entries) {
    code = canopen::kAbortUnsupportedAccess;  // a variable, not a record
    return nullptr;
  }
  code = canopen::kAbortNone;
  return count;
}

std::uint32_t CoeSdoServer::read_record(std::uint16_t index, std::uint8_t first_subindex) {
  upload_data_.clear();
  std::uint32_t code = canopen::kAbortNone;
  const canopen::Entry* count = record_count(index, code);
  if (count == nullptr) return code;
  if (first_subindex > 1) return canopen::kAbortUnsupportedAccess;
  const auto n = static_cast<std::uint8_t>(count->value);
  if (first_subindex == 0) upload_data_.insert(upload_data_.end(), {n, 0});  // sub-index 0 as 16 bits
  for (unsigned sub = 1; sub <= n; ++sub) {
    const canopen::Result<canopen::SdoData> value = dictionary_.read(index, static_cast<std::uint8_t>(sub));
    if (!value && value.abort_code == canopen::kAbortSubindexMissing) continue;  // a gap in the record
    if (!value) return value.abort_code;
    for (std::uint8_t i = 0; i < value.value.size; ++i) {
      upload_data_.push_back(static_cast<std::uint8_t>(value.value.data >> (8 * i)));
    }
  }
  return canopen::kAbortNone;
}

std::uint32_t CoeSdoServer::write_record(std::uint16_t index, std::uint8_t first_subindex, const std::uint8_t* data,
                                         std::size_t size) {
  std::uint32_t code = canopen::kAbortNone;
  const canopen::Entry* count = record_count(index, code);
  if (count == nullptr) return code;
  if (first_subindex > 1) return canopen::kAbortUnsupportedAccess;
  const bool with_count = first_subindex == 0;
  if (with_count && size < 2) return canopen::kAbortLengthTooLow;
  const auto n = with_count ? data[0] : static_cast<std::uint8_t>(count->value);
  const bool count_writable = canopen::writable(count->access);
  if (with_count && !count_writable && n != count->value) return canopen::kAbortWriteReadOnly;
  // The length first: nothing is written from a record of the wrong size.
  std::size_t expected = with_count ? 2 : 0;
  for (unsigned sub = 1; sub <= n; ++sub) {
    const canopen::Entry* e = dictionary_.find(index, static_cast<std::uint8_t>(sub));
    if (e != nullptr) expected += canopen::size_of(e->type);
  }
  if (size != expected) return size < expected ? canopen::kAbortLengthTooLow : canopen::kAbortLengthTooHigh;
  const auto write = [&](std::uint8_t sub, std::uint32_t value, std::uint8_t bytes) {
    const canopen::Status s = dictionary_.write(index, sub, canopen::SdoData{value, bytes});
    return s ? canopen::kAbortNone : s.abort_code;
  };
  if (with_count && count_writable) {
    code = write(0, 0, 1);
    if (code != canopen::kAbortNone) return code;
  }
  std::size_t at = with_count ? 2 : 0;
  for (unsigned sub = 1; sub <= n; ++sub) {
    const canopen::Entry* e = dictionary_.find(index, static_cast<std::uint8_t>(sub));
    if (e == nullptr) continue;
    const std::uint8_t bytes = canopen::size_of(e->type);
    std::uint32_t value = 0;
    for (std::uint8_t i = 0; i < bytes; ++i) value |= static_cast<std::uint32_t>(data[at + i]) << (8 * i);
    at += bytes;
    code = write(static_cast<std::uint8_t>(sub), value, bytes);
    if (code != canopen::kAbortNone) return code;
  }
  if (with_count && count_writable) return write(0, n, 1);
  return canopen::kAbortNone;
}

std::size_t CoeSdoServer::normal_download(const SdoBytes& sdo, const std::uint8_t* more, std::size_t more_bytes,
                                          std::uint8_t* response) {
  const auto index = static_cast<std::uint16_t>(sdo[1] | (sdo[2] << 8));
  const std::uint8_t subindex = sdo[3];
  if ((sdo[0] & kBitSizeIndicated) == 0) return abort(response, index, subindex, canopen::kAbortCommandSpecifier);
  const std::uint32_t size = get_le32(sdo.data() + 4);
  if ((sdo[0] & kBitCompleteAccess) != 0) {
    if (more_bytes < size) {  // the rest follows in segments
      if (size > kMaxDownloadBytes) return abort(response, index, subindex, canopen::kAbortOutOfMemory);
      download_ = {true, index, subindex, size, 0};
      download_data_.assign(more, more + more_bytes);
      return downloaded(response, index, subindex);
    }
    const std::uint32_t code = write_record(index, subindex, more, size);
    if (code != canopen::kAbortNone) return abort(response, index, subindex, code);
    return downloaded(response, index, subindex);
  }
  if (size > 4) {
    // Nothing writable here is longer: a text is read-only, a missing object missing, the rest
    // too long for their type.
    std::uint32_t code = canopen::kAbortLengthTooHigh;
    if (dictionary_.find_text(index, subindex) != nullptr) {
      code = canopen::kAbortWriteReadOnly;
    } else if (dictionary_.find(index, subindex) == nullptr) {
      code = dictionary_.locate(index, subindex);
    }
    return abort(response, index, subindex, code);
  }
  if (size == 0 || more_bytes < size) return abort(response, index, subindex, canopen::kAbortCommandSpecifier);
  std::uint32_t value = 0;
  for (std::uint32_t i = 0; i < size; ++i) value |= static_cast<std::uint32_t>(more[i]) << (8 * i);
  const canopen::Status written =
      dictionary_.write(index, subindex, canopen::SdoData{value, static_cast<std::uint8_t>(size)});
  if (!written) return abort(response, index, subindex, written.abort_code);
  return downloaded(response, index, subindex);
}

std::size_t CoeSdoServer::download_segment(const SdoBytes& sdo, const std::uint8_t* more, std::size_t more_bytes,
                                           std::uint8_t* response) {
  const std::uint8_t command = sdo[0];
  if (!download_.active) return abort(response, 0, 0, canopen::kAbortCommandSpecifier);
  const Download d = download_;
  if (((command >> 4) & 1U) != d.toggle) {
    download_ = {};
    return abort(response, d.index, d.subindex, canopen::kAbortToggleBit);
  }
  // Past the 8 bytes every byte is data; a message of 8 says how many of its 7 are not (n).
  const std::size_t in_seven = more_bytes > 0 ? 7 : 7 - ((command >> 1) & 7U);
  if (download_data_.size() + in_seven + more_bytes > d.total) {
    download_ = {};
    return abort(response, d.index, d.subindex, canopen::kAbortLengthTooHigh);
  }
  download_data_.insert(download_data_.end(), sdo.begin() + 1, sdo.begin() + 1 + static_cast<std::ptrdiff_t>(in_seven));
  download_data_.insert(download_data_.end(), more, more + more_bytes);
  ++segments_;
  if ((command & 1U) != 0) {  // the last: the record written whole
    download_ = {};
    std::uint32_t code = canopen::kAbortLengthTooLow;
    if (download_data_.size() == d.total) code = write_record(d.index, d.subindex, download_data_.data(), d.total);
    if (code != canopen::kAbortNone) return abort(response, d.index, d.subindex, code);
  } else {
    download_.toggle = static_cast<std::uint8_t>(d.toggle ^ 1U);
  }
  SdoBytes answer{};
  answer[0] = static_cast<std::uint8_t>(0x20U | (d.toggle << 4));  // scs 1: download segment response
  return respond(response, answer);
}

std::size_t CoeSdoServer::write_emergency(std::uint8_t* out, std::uint16_t error_code, std::uint8_t error_register) {
  SdoBytes body{};
  body[0] = static_cast<std::uint8_t>(error_code & 0xFFU);
  body[1] = static_cast<std::uint8_t>(error_code >> 8);
  body[2] = error_register;
  counter_ = static_cast<std::uint8_t>(counter_ % 7 + 1);
  return write_coe_sdo(out, counter_, kCoeServiceEmergency, body);
}

}  // namespace pmlsm::ethercat
