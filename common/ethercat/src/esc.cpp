#include "pmlsm/ethercat/esc.hpp"

#include <algorithm>
#include <stdexcept>

namespace pmlsm::ethercat {

namespace {

constexpr std::uint8_t kSmModeMask = 0x03;
constexpr std::uint8_t kSmModeMailbox = 0x02;
constexpr std::uint8_t kSmDirectionMask = 0x0C;
constexpr std::uint8_t kSmDirectionWrite = 0x04;  ///< the master writes (ECAT write, PDI read)
constexpr std::uint8_t kSmEnable = 0x01;
constexpr std::uint8_t kFmmuRead = 0x01;
constexpr std::uint8_t kFmmuWrite = 0x02;
constexpr std::uint8_t kRamSizeKib = 8;

/// Registers the master may write (the others, status and identity, keep their value).
bool writable(std::uint32_t address) {
  if (address >= reg::kProcessRam) return true;
  if (address >= reg::kSyncManager0 && address < reg::kSyncManager0 + 16 * kSyncManagerBytes) {
    const std::uint32_t byte = (address - reg::kSyncManager0) % kSyncManagerBytes;
    return byte != 5 && byte != 7;  // SM status and PDI control are the slave's
  }
  return (address >= reg::kStationAddress && address < reg::kStationAddress + 2) ||
         (address >= 0x0100 && address < 0x0104) ||                              // DL control
         (address >= reg::kAlControl && address < reg::kAlControl + 2) ||        //
         (address >= 0x0200 && address < 0x0206) ||                              // event masks
         (address >= 0x0300 && address < 0x0314) ||                              // error counters
         (address >= 0x0400 && address < 0x0444) ||                              // watchdogs
         (address >= reg::kSiiControl && address < 0x0510) ||                    // SII interface
         (address >= reg::kFmmu0 && address < reg::kFmmu0 + 16 * kFmmuBytes) ||  //
         (address >= 0x0900 && address < 0x0A00);                                // distributed clocks
}

bool is_read(Command c) { return c == Command::kAprd || c == Command::kFprd || c == Command::kBrd; }
bool is_write(Command c) { return c == Command::kApwr || c == Command::kFpwr || c == Command::kBwr; }
bool is_read_write(Command c) { return c == Command::kAprw || c == Command::kFprw || c == Command::kBrw; }

}  // namespace

const char* to_string(AlState state) {
  switch (state) {
    case AlState::kInit: return "INIT";
    case AlState::kPreOp: return "PREOP";
    case AlState::kBoot: return "BOOT";
    case AlState::kSafeOp: return "SAFEOP";
    case AlState::kOp: return "OP";
  }
  return "?";
}

const char* al_status_code_name(std::uint16_t code) {
  switch (code) {
    case 0x0000: return "no error";
    case 0x0001: return "unspecified error";
    case 0x0002: return "no memory";
    case 0x0011: return "invalid requested state change";
    case 0x0012: return "unknown requested state";
    case 0x0013: return "bootstrap not supported";
    case 0x0014: return "no valid firmware";
    case 0x0015: return "invalid mailbox configuration (BOOT)";
    case 0x0016: return "invalid mailbox configuration";
    case 0x0017: return "invalid sync manager configuration";
    case 0x0018: return "no valid inputs available";
    case 0x0019: return "no valid outputs";
    case 0x001A: return "synchronization error";
    case 0x001B: return "sync manager watchdog";
    case 0x001C: return "invalid sync manager types";
    case 0x001D: return "invalid output configuration";
    case 0x001E: return "invalid input configuration";
    case 0x001F: return "invalid watchdog configuration";
    case 0x0020: return "slave needs cold start";
    case 0x0021: return "slave needs INIT";
    case 0x0022: return "slave needs PREOP";
    case 0x0023: return "slave needs SAFEOP";
    case 0x0024: return "invalid input mapping";
    case 0x0025: return "invalid output mapping";
    case 0x0026: return "inconsistent settings";
    case 0x0027: return "free run not supported";
    case 0x0028: return "synchronization not supported";
    case 0x002C: return "fatal sync error";
    case 0x0030: return "invalid DC SYNC configuration";
    case 0x0035: return "invalid DC sync cycle time";
    case 0x0043: return "CoE mailbox error";
    case 0x0050: return "EEPROM no access";
    case 0x0051: return "EEPROM error";
    default: return "unknown AL status code";
  }
}

void EscParams::validate() const {
  if (sii.size() < sii::kMinWords) {
    throw std::invalid_argument("sii: at least " + std::to_string(sii::kMinWords) + " words (the fixed part and " +
                                "an end category), got " + std::to_string(sii.size()));
  }
  dc.validate();
  if (fmmus == 0 || fmmus > 16) throw std::invalid_argument("fmmus: 1 to 16, got " + std::to_string(fmmus));
  if (sync_managers < 4 || sync_managers > 16) {
    throw std::invalid_argument("sync_managers: 4 to 16, got " + std::to_string(sync_managers));
  }
}

Esc::Esc(EscParams params)
    : params_((params.validate(), std::move(params))), memory_(kMemoryBytes, 0), dc_(params_.dc) {
  memory_[reg::kType] = params_.type;
  memory_[reg::kFeatures] = 0x0C;  // distributed clocks, 64 bits
  memory_[reg::kRevision] = 1;
  memory_[reg::kFmmuCount] = params_.fmmus;
  memory_[reg::kSyncManagerCount] = params_.sync_managers;
  memory_[reg::kRamSizeKib] = kRamSizeKib;
  const std::uint16_t alias = params_.sii[sii::kStationAlias];
  memory_[reg::kStationAlias] = static_cast<std::uint8_t>(alias & 0xFFU);
  memory_[reg::kStationAlias + 1] = static_cast<std::uint8_t>(alias >> 8);
  memory_[reg::kDlStatus] = 0x10;  // port 0: link up
  memory_[reg::kAlControl] = static_cast<std::uint8_t>(AlState::kInit);
  memory_[reg::kAlStatus] = static_cast<std::uint8_t>(AlState::kInit);
  memory_[reg::kSiiControl] = kSiiRead8Bytes;
  constexpr std::uint16_t kDefaultDivider = 2498;  // 100 us a unit
  constexpr std::uint16_t kDefaultTime = 1000;     // 100 ms
  memory_[reg::kWatchdogDivider] = static_cast<std::uint8_t>(kDefaultDivider & 0xFFU);
  memory_[reg::kWatchdogDivider + 1] = static_cast<std::uint8_t>(kDefaultDivider >> 8);
  memory_[reg::kWatchdogTimeProcessData] = static_cast<std::uint8_t>(kDefaultTime & 0xFFU);
  memory_[reg::kWatchdogTimeProcessData + 1] = static_cast<std::uint8_t>(kDefaultTime >> 8);
  memory_[reg::kWatchdogStatusProcessData] = 0x01;
}

std::int64_t Esc::process_data_watchdog_ns() const {
  const std::int64_t unit_ns = (static_cast<std::int64_t>(word_at(reg::kWatchdogDivider)) + 2) * 40;
  return unit_ns * word_at(reg::kWatchdogTimeProcessData);
}

void Esc::process_data_watchdog_expired() {
  memory_[reg::kWatchdogStatusProcessData] = 0x00;
  if (al_state() != AlState::kOp) return;
  memory_[reg::kAlStatus] = static_cast<std::uint8_t>(kAlErrorIndicator | static_cast<std::uint8_t>(AlState::kSafeOp));
  refuse(al_code::kSyncManagerWatchdog);
}

std::uint16_t Esc::word_at(std::uint16_t address) const {
  return static_cast<std::uint16_t>(memory_[address] | (memory_[(address + 1U) & 0xFFFFU] << 8));
}

std::uint32_t Esc::long_at(std::uint16_t address) const {
  return static_cast<std::uint32_t>(word_at(address)) |
         (static_cast<std::uint32_t>(word_at(static_cast<std::uint16_t>(address + 2))) << 16);
}

AlState Esc::al_state() const { return static_cast<AlState>(memory_[reg::kAlStatus] & 0x0F); }
std::uint16_t Esc::al_status_code() const { return word_at(reg::kAlStatusCode); }
std::uint16_t Esc::station_address() const { return word_at(reg::kStationAddress); }

void Esc::write_memory(std::uint16_t address, const std::uint8_t* bytes, std::size_t size) {
  const std::size_t n = std::min<std::size_t>(size, kMemoryBytes - address);
  std::copy(bytes, bytes + n, memory_.begin() + address);
}

void Esc::pass(DatagramHeader& header, std::uint8_t* data, std::uint16_t& working_counter) {
  const Command c = header.command;
  if (c == Command::kNop) return;
  if (is_logical(c)) {
    logical(header, data, working_counter);
    return;
  }
  physical(header, data, working_counter);
  if (is_auto_increment(c)) {
    header.address = physical_address(static_cast<std::uint16_t>(header.adp() + 1), header.ado());
  }
}

bool Esc::addressed(const DatagramHeader& header) const {
  switch (header.command) {
    case Command::kBrd:
    case Command::kBwr:
    case Command::kBrw: return true;
    case Command::kFprd:
    case Command::kFpwr:
    case Command::kFprw:
    case Command::kFrmw: return header.adp() == station_address();
    default: return header.adp() == 0;  // auto increment: this slave's position
  }
}

void Esc::physical(const DatagramHeader& header, std::uint8_t* data, std::uint16_t& working_counter) {
  const Command c = header.command;
  const std::uint16_t offset = header.ado();
  if (static_cast<std::size_t>(offset) + header.length > kMemoryBytes) return;  // past its memory: not done
  const bool is_addressed = addressed(header);
  if (c == Command::kArmw || c == Command::kFrmw) {
    // The addressed slave's value read into the datagram, written into every other slave.
    if (is_addressed) {
      read_into(offset, data, header.length, false);
    } else {
      write_from(offset, data, header.length);
    }
    ++working_counter;
    return;
  }
  if (!is_addressed) return;
  const bool broadcast = c == Command::kBrd || c == Command::kBrw;
  if (is_read(c)) {
    if (send_mailbox_empty_for(offset, header.length)) return;
    read_into(offset, data, header.length, broadcast);
    after_read(offset, header.length);
    working_counter = static_cast<std::uint16_t>(working_counter + 1);
  } else if (is_write(c)) {
    write_from(offset, data, header.length);
    working_counter = static_cast<std::uint16_t>(working_counter + 1);
  } else if (is_read_write(c)) {
    std::array<std::uint8_t, kMaxDatagramDataBytes> before{};
    read_into(offset, before.data(), header.length, false);
    write_from(offset, data, header.length);
    for (std::uint16_t i = 0; i < header.length; ++i) {
      data[i] = broadcast ? static_cast<std::uint8_t>(data[i] | before[i]) : before[i];
    }
    working_counter = static_cast<std::uint16_t>(working_counter + 3);
  }
}

void Esc::logical(const DatagramHeader& header, std::uint8_t* data, std::uint16_t& working_counter) {
  const Command c = header.command;
  bool read_hit = false;
  bool write_hit = false;
  const std::uint64_t first = header.address;
  const std::uint64_t end = first + header.length;
  for (std::size_t i = 0; i < params_.fmmus; ++i) {
    const auto at = static_cast<std::uint16_t>(reg::kFmmu0 + i * kFmmuBytes);
    if ((memory_[at + 12] & 0x01) == 0) continue;
    const std::uint64_t start = long_at(at);
    const std::uint64_t stop = start + word_at(static_cast<std::uint16_t>(at + 4));
    const std::uint16_t physical_start = word_at(static_cast<std::uint16_t>(at + 8));
    const std::uint8_t type = memory_[at + 11];
    const std::uint64_t from = std::max(first, start);
    const std::uint64_t to = std::min(end, stop);
    if (from >= to) continue;
    for (std::uint64_t l = from; l < to; ++l) {
      const std::size_t phys = physical_start + (l - start);
      if (phys >= kMemoryBytes) break;
      std::uint8_t& byte = data[l - first];
      if ((type & kFmmuWrite) != 0 && (c == Command::kLwr || c == Command::kLrw)) {
        write_from(static_cast<std::uint16_t>(phys), &byte, 1);
        write_hit = true;
      }
      if ((type & kFmmuRead) != 0 && (c == Command::kLrd || c == Command::kLrw)) {
        byte = memory_[phys];
        read_hit = true;
      }
    }
  }
  // LRD and LWR: 1 for the read or the write; LRW: 1 read + 2 written.
  std::uint16_t add = 0;
  if (c == Command::kLrw) {
    add = static_cast<std::uint16_t>((read_hit ? 1 : 0) + (write_hit ? 2 : 0));
  } else {
    add = (read_hit || write_hit) ? 1 : 0;
  }
  working_counter = static_cast<std::uint16_t>(working_counter + add);
}

void Esc::read_into(std::uint16_t address, std::uint8_t* out, std::size_t size, bool or_in) const {
  for (std::size_t i = 0; i < size; ++i) {
    out[i] = or_in ? static_cast<std::uint8_t>(out[i] | memory_[address + i]) : memory_[address + i];
  }
}

void Esc::write_from(std::uint16_t address, const std::uint8_t* in, std::size_t size) {
  bool any = false;
  for (std::size_t i = 0; i < size; ++i) {
    if (!writable(address + i)) continue;
    memory_[address + i] = in[i];
    any = true;
  }
  if (any) after_write(address, size);
}

void Esc::set_time(std::int64_t now_ns) {
  now_ns_ = now_ns;
  dc_.advance_to(now_ns);
  show_dc();
  run_sync0(now_ns);
}

std::int64_t Esc::ns_to_next_sync0() const {
  if (!sync0_.active) return -1;
  const std::uint64_t now = dc_.system_time_ns();
  return sync0_.next_ns > now ? static_cast<std::int64_t>(sync0_.next_ns - now) : 0;
}

void Esc::sync0_written() {
  const bool on = (memory_[reg::kDcActivation] & 0x03U) == 0x03U;
  if (on == sync0_.active) return;
  sync0_.active = on;
  if (!on) return;
  sync0_.cycle_ns = long_at(reg::kDcSync0CycleTime);
  const std::uint64_t start = static_cast<std::uint64_t>(long_at(reg::kDcStartTime)) |
                              (static_cast<std::uint64_t>(long_at(reg::kDcStartTime + 4)) << 32);
  const std::uint64_t now = dc_.system_time_ns();
  sync0_.next_ns = start;
  if (start < now) {
    // The ET1100 compares 32 bits: the start's low half comes round again after the wrap.
    ++sync0_.late_starts;
    constexpr std::uint64_t kWrap = std::uint64_t{1} << 32;
    sync0_.next_ns = (now & ~(kWrap - 1)) | (start & (kWrap - 1));
    if (sync0_.next_ns < now) sync0_.next_ns += kWrap;
  }
  outputs_at_last_pulse_ = outputs_written_;
  run_sync0(now_ns_);
}

void Esc::run_sync0(std::int64_t now_ns) {
  const std::uint64_t now = dc_.system_time_ns();
  // A clock moved far ahead at once (a master's time beyond the loop's reach): the pulses a second
  // behind and more are not each the application's; the unit goes on from the last of them.
  constexpr std::uint64_t kMaxBacklog = 1000;
  if (sync0_.active && sync0_.cycle_ns > 0 && sync0_.next_ns <= now) {
    const std::uint64_t due = (now - sync0_.next_ns) / sync0_.cycle_ns + 1;
    if (due > kMaxBacklog) {
      sync0_.next_ns += (due - kMaxBacklog) * sync0_.cycle_ns;
      sync0_.dropped += due - kMaxBacklog;
    }
  }
  while (sync0_.active && sync0_.next_ns <= now) {
    ++sync0_.pulses;
    if (outputs_written_ == outputs_at_last_pulse_) ++sync0_.pulses_without_outputs;
    outputs_at_last_pulse_ = outputs_written_;
    memory_[reg::kDcSync0Status] = 0x01;
    if (sync0_.cycle_ns == 0) {
      sync0_.active = false;  // a single pulse
    } else {
      sync0_.next_ns += sync0_.cycle_ns;
    }
    if (sync0_handler_) sync0_handler_(now_ns);
  }
  if (!sync0_.active) return;  // 0x0990 holds what the master writes until the unit runs
  for (int i = 0; i < 8; ++i) memory_[reg::kDcStartTime + i] = static_cast<std::uint8_t>(sync0_.next_ns >> (8 * i));
}

void Esc::show_dc() {
  const std::uint64_t system = dc_.system_time_ns();
  for (int i = 0; i < 8; ++i) memory_[reg::kDcSystemTime + i] = static_cast<std::uint8_t>(system >> (8 * i));
  const std::int64_t difference = dc_.difference_ns();
  const std::uint64_t magnitude = difference < 0 ? static_cast<std::uint64_t>(-difference) : difference;
  std::uint32_t value = static_cast<std::uint32_t>(std::min<std::uint64_t>(magnitude, 0x7FFFFFFFU));
  if (difference > 0) value |= 0x80000000U;  // its own time behind the ones received
  for (int i = 0; i < 4; ++i) memory_[reg::kDcSystemTimeDifference + i] = static_cast<std::uint8_t>(value >> (8 * i));
}

void Esc::dc_written(std::uint16_t address, std::size_t size) {
  const auto covers = [&](std::uint16_t reg_address) { return address <= reg_address && reg_address < address + size; };
  const auto u64_at = [&](std::uint16_t at) {
    return static_cast<std::uint64_t>(long_at(at)) | (static_cast<std::uint64_t>(long_at(at + 4)) << 32);
  };
  if (covers(reg::kDcReceiveTimePort0)) {
    // The frame's arrival latched: port 0's receive time (32 bits) and the unit's (64 bits); port
    // 1's when the frame comes back through it (0 when it is closed); ports 2-3 lead nowhere here.
    const std::uint64_t local = dc_.local_ns();
    const std::uint64_t port1 = port1_return_ns_ < 0 ? 0 : local + static_cast<std::uint64_t>(port1_return_ns_);
    for (int i = 0; i < 16; ++i) {
      std::uint8_t byte = 0;
      if (i < 4) byte = static_cast<std::uint8_t>(local >> (8 * i));
      if (i >= 4 && i < 8) byte = static_cast<std::uint8_t>(port1 >> (8 * (i - 4)));
      memory_[reg::kDcReceiveTimePort0 + i] = byte;
    }
    for (int i = 0; i < 8; ++i) memory_[reg::kDcReceiveTimeUnit + i] = static_cast<std::uint8_t>(local >> (8 * i));
  }
  if (covers(reg::kDcActivation)) sync0_written();
  if (covers(reg::kDcSystemTimeOffset)) dc_.set_offset_ns(u64_at(reg::kDcSystemTimeOffset));
  if (covers(reg::kDcSystemTimeDelay)) dc_.set_delay_ns(long_at(reg::kDcSystemTimeDelay));
  if (covers(reg::kDcSystemTime)) {
    // A 32-bit write carries the low half; the high half is the clock's own.
    std::uint64_t received = u64_at(reg::kDcSystemTime);
    if (!covers(reg::kDcSystemTime + 4)) {
      received = (dc_.system_time_ns() & 0xFFFFFFFF00000000ULL) | (received & 0xFFFFFFFFULL);
    }
    dc_.on_system_time_written(received);
  }
  show_dc();
}

void Esc::after_write(std::uint16_t address, std::size_t size) {
  const auto covers = [&](std::uint16_t reg_address) { return address <= reg_address && reg_address < address + size; };
  if (address < 0x0A00 && address + size > reg::kDcReceiveTimePort0) dc_written(address, size);
  if (covers(reg::kAlControl)) request_state(memory_[reg::kAlControl]);
  if (covers(reg::kSiiControl) || covers(reg::kSiiControl + 1)) sii_command();
  const MailboxArea receive = mailbox_area(0);
  if (receive.active && covers(static_cast<std::uint16_t>(receive.start + receive.length - 1))) mailbox_received();
  constexpr auto kOutputs = static_cast<std::uint16_t>(reg::kSyncManager0 + 2 * kSyncManagerBytes);
  const std::uint16_t outputs_length = word_at(static_cast<std::uint16_t>(kOutputs + 2));
  const bool outputs_buffer = (memory_[kOutputs + 4] & kSmModeMask) == 0 && (memory_[kOutputs + 6] & kSmEnable) != 0;
  if (outputs_buffer && outputs_length > 0 &&
      covers(static_cast<std::uint16_t>(word_at(kOutputs) + outputs_length - 1))) {
    ++outputs_written_;
    memory_[reg::kWatchdogStatusProcessData] = 0x01;
  }
}

Esc::MailboxArea Esc::mailbox_area(std::size_t index) const {
  const auto at = static_cast<std::uint16_t>(reg::kSyncManager0 + index * kSyncManagerBytes);
  MailboxArea area;
  area.start = word_at(at);
  area.length = word_at(static_cast<std::uint16_t>(at + 2));
  // A mailbox lies in process RAM: one set over the registers is no mailbox.
  area.active = (memory_[at + 4] & kSmModeMask) == kSmModeMailbox && (memory_[at + 6] & kSmEnable) != 0 &&
                area.length > 0 && area.start >= reg::kProcessRam &&
                static_cast<std::size_t>(area.start) + area.length <= kMemoryBytes;
  return area;
}

void Esc::set_sync_manager_full(std::size_t index, bool full) {
  constexpr std::uint8_t kMailboxFull = 0x08;  // SM status bit 3
  std::uint8_t& status = memory_[reg::kSyncManager0 + index * kSyncManagerBytes + 5];
  status = static_cast<std::uint8_t>(full ? (status | kMailboxFull) : (status & ~kMailboxFull));
}

bool Esc::send_mailbox_empty_for(std::uint16_t address, std::uint16_t length) const {
  const MailboxArea send = mailbox_area(1);
  const bool overlaps = send.active && address < send.start + send.length && send.start < address + length;
  return overlaps && (memory_[reg::kSyncManager0 + kSyncManagerBytes + 5] & 0x08) == 0;
}

void Esc::after_read(std::uint16_t address, std::uint16_t length) {
  if (address <= reg::kDcSync0Status && reg::kDcSync0Status < static_cast<std::uint32_t>(address) + length) {
    memory_[reg::kDcSync0Status] = 0;  // read, acknowledged
  }
  const MailboxArea send = mailbox_area(1);
  const std::uint32_t last = send.start + send.length - 1U;
  if (send.active && address <= last && last < static_cast<std::uint32_t>(address) + length) {
    set_sync_manager_full(1, false);
    if (send_count_ > 0) {  // the next message waiting
      put_into_send_mailbox(send_queue_[send_head_].data(), send_sizes_[send_head_]);
      send_head_ = (send_head_ + 1) % kSendQueue;
      --send_count_;
    }
  }
}

void Esc::mailbox_received() {
  const MailboxArea receive = mailbox_area(0);
  const MailboxArea send = mailbox_area(1);
  if (mailbox_handler_ == nullptr || !send.active) return;  // taken, nothing to answer with
  std::array<std::uint8_t, kMaxDatagramDataBytes> answer{};
  const std::size_t size =
      mailbox_handler_->handle(memory_.data() + receive.start, receive.length, answer.data(), send.length);
  if (size == 0) return;
  post_mailbox(answer.data(), size);
}

void Esc::put_into_send_mailbox(const std::uint8_t* message, std::size_t size) {
  const MailboxArea send = mailbox_area(1);
  std::fill(memory_.begin() + send.start, memory_.begin() + send.start + send.length, 0);
  std::copy(message, message + std::min<std::size_t>(size, send.length), memory_.begin() + send.start);
  set_sync_manager_full(1, true);
}

bool Esc::post_mailbox(const std::uint8_t* message, std::size_t size) {
  const MailboxArea send = mailbox_area(1);
  if (!send.active || size > kMaxDatagramDataBytes) return false;
  constexpr std::uint8_t kMailboxFull = 0x08;
  const bool full = (memory_[reg::kSyncManager0 + kSyncManagerBytes + 5] & kMailboxFull) != 0;
  if (!full && send_count_ == 0) {
    put_into_send_mailbox(message, size);
    return true;
  }
  if (send_count_ == kSendQueue) {
    ++mailbox_dropped_;
    return false;
  }
  const std::size_t slot = (send_head_ + send_count_) % kSendQueue;
  std::copy(message, message + size, send_queue_[slot].begin());
  send_sizes_[slot] = size;
  ++send_count_;
  return true;
}

void Esc::refuse(std::uint16_t code) {
  memory_[reg::kAlStatus] = static_cast<std::uint8_t>(memory_[reg::kAlStatus] | kAlErrorIndicator);
  memory_[reg::kAlStatusCode] = static_cast<std::uint8_t>(code & 0xFFU);
  memory_[reg::kAlStatusCode + 1] = static_cast<std::uint8_t>(code >> 8);
}

bool Esc::sync_manager_is(std::size_t index, std::uint16_t start, std::uint16_t length, std::uint8_t control) const {
  const auto at = static_cast<std::uint16_t>(reg::kSyncManager0 + index * kSyncManagerBytes);
  const std::uint8_t c = memory_[at + 4];
  return word_at(at) == start && word_at(static_cast<std::uint16_t>(at + 2)) == length &&
         (c & (kSmModeMask | kSmDirectionMask)) == control && (memory_[at + 6] & kSmEnable) != 0;
}

bool Esc::sync_manager_active_with(std::size_t index, std::uint16_t length) const {
  const auto at = static_cast<std::uint16_t>(reg::kSyncManager0 + index * kSyncManagerBytes);
  return length == 0 || (word_at(static_cast<std::uint16_t>(at + 2)) == length && (memory_[at + 6] & kSmEnable) != 0);
}

void Esc::request_state(std::uint8_t control) {
  if ((control & kAlErrorIndicator) != 0) {  // the master acknowledges the error
    memory_[reg::kAlStatus] = static_cast<std::uint8_t>(memory_[reg::kAlStatus] & ~kAlErrorIndicator);
    memory_[reg::kAlStatusCode] = 0;
    memory_[reg::kAlStatusCode + 1] = 0;
  }
  const std::uint8_t requested = control & 0x0F;
  const AlState now = al_state();
  if (requested == static_cast<std::uint8_t>(now)) return;
  const auto go = [&](AlState s) {
    memory_[reg::kAlStatus] =
        static_cast<std::uint8_t>((memory_[reg::kAlStatus] & kAlErrorIndicator) | static_cast<std::uint8_t>(s));
  };
  switch (requested) {
    case static_cast<std::uint8_t>(AlState::kInit): go(AlState::kInit); return;
    case static_cast<std::uint8_t>(AlState::kBoot): refuse(al_code::kBootstrapNotSupported); return;
    case static_cast<std::uint8_t>(AlState::kPreOp): {
      if (now != AlState::kInit) {
        go(AlState::kPreOp);  // down from SAFEOP or OP
        return;
      }
      const std::vector<std::uint16_t>& s = params_.sii;
      const bool mailbox = s[sii::kMailboxReceiveSize] != 0;
      if (mailbox && !(sync_manager_is(0, s[sii::kMailboxReceiveOffset], s[sii::kMailboxReceiveSize],
                                       kSmModeMailbox | kSmDirectionWrite) &&
                       sync_manager_is(1, s[sii::kMailboxSendOffset], s[sii::kMailboxSendSize], kSmModeMailbox))) {
        refuse(al_code::kInvalidMailboxConfiguration);
        return;
      }
      go(AlState::kPreOp);
      return;
    }
    case static_cast<std::uint8_t>(AlState::kSafeOp): {
      if (now == AlState::kOp) {
        go(AlState::kSafeOp);
        return;
      }
      if (now != AlState::kPreOp) {
        refuse(al_code::kInvalidStateChange);
        return;
      }
      if (before_safeop_) {
        const std::uint16_t code = before_safeop_();
        if (code != 0) {
          refuse(code);
          return;
        }
      }
      if (!sync_manager_active_with(2, params_.output_bytes)) {
        refuse(al_code::kInvalidOutputConfiguration);
        return;
      }
      if (!sync_manager_active_with(3, params_.input_bytes)) {
        refuse(al_code::kInvalidInputConfiguration);
        return;
      }
      go(AlState::kSafeOp);
      return;
    }
    case static_cast<std::uint8_t>(AlState::kOp):
      if (now != AlState::kSafeOp) {
        refuse(al_code::kInvalidStateChange);
        return;
      }
      if (before_op_) {
        const std::uint16_t code = before_op_();
        if (code != 0) {
          refuse(code);
          return;
        }
      }
      go(AlState::kOp);
      return;
    default: refuse(al_code::kUnknownState); return;
  }
}

void Esc::sii_command() {
  const std::uint16_t control = word_at(reg::kSiiControl);
  if ((control & kSiiCommandMask) == kSiiReadCommand) {
    const std::uint32_t word = long_at(reg::kSiiAddress);
    for (std::uint32_t i = 0; i < 4; ++i) {
      const std::uint16_t value = word + i < params_.sii.size() ? params_.sii[word + i] : 0xFFFF;  // erased
      memory_[reg::kSiiData + 2 * i] = static_cast<std::uint8_t>(value & 0xFFU);
      memory_[reg::kSiiData + 2 * i + 1] = static_cast<std::uint8_t>(value >> 8);
    }
  }
  // Done at once: no command pending, not busy, reads of 8 bytes.
  const auto status = static_cast<std::uint16_t>((control & ~(kSiiCommandMask | kSiiBusy)) | kSiiRead8Bytes);
  memory_[reg::kSiiControl] = static_cast<std::uint8_t>(status & 0xFFU);
  memory_[reg::kSiiControl + 1] = static_cast<std::uint8_t>(status >> 8);
}

FrameError VirtualSegment::pass(std::uint8_t* bytes, std::size_t size) {
  return pass(bytes, size, clock_ ? clock_() : -1);
}

FrameError VirtualSegment::pass(std::uint8_t* bytes, std::size_t size, std::int64_t at_ns) {
  ParsedFrame parsed;
  const FrameError error = parse_ethernet_frame(bytes, size, parsed);
  if (error != FrameError::kNone) return error;
  if (at_ns >= 0) {
    const std::int64_t now_ns = at_ns;
    const auto last = static_cast<std::int64_t>(slaves_.size()) - 1;
    for (std::int64_t i = 0; i <= last; ++i) {
      Esc* slave = slaves_[static_cast<std::size_t>(i)];
      slave->set_time(now_ns + i * hop_ns_);
      slave->set_port1_return_ns(i < last ? 2 * (last - i) * hop_ns_ : -1);
    }
  }
  // An ESC sets the locally administered bit of the source address on the way (ETG.1000.4): a
  // master tells the frames coming back from its own.
  bytes[6] = static_cast<std::uint8_t>(bytes[6] | 0x02U);
  for (std::size_t i = 0; i < parsed.count; ++i) {
    const DatagramView& view = parsed.datagrams[i];
    // The views point into `bytes`: the same datagram, writable.
    std::uint8_t* data = bytes + (view.data - bytes);
    std::uint8_t* header_bytes = data - kDatagramHeaderBytes;
    DatagramHeader header = view.header;
    std::uint16_t working_counter = view.working_counter;
    for (Esc* slave : slaves_) slave->pass(header, data, working_counter);
    for (int b = 0; b < 4; ++b) header_bytes[2 + b] = static_cast<std::uint8_t>((header.address >> (8 * b)) & 0xFFU);
    data[header.length] = static_cast<std::uint8_t>(working_counter & 0xFFU);
    data[header.length + 1] = static_cast<std::uint8_t>(working_counter >> 8);
  }
  return FrameError::kNone;
}

bool VirtualSegmentLink::send(Bytes ethernet_frame) {
  if (pending_ || ethernet_frame.size > buffer_.size()) return false;
  std::copy(ethernet_frame.data, ethernet_frame.data + ethernet_frame.size, buffer_.begin());
  size_ = ethernet_frame.size;
  pending_ = segment_.pass(buffer_.data(), size_) == FrameError::kNone;  // a refused frame is lost
  if (pending_ && after_frame_) after_frame_();
  return true;
}

std::size_t VirtualSegmentLink::receive(std::uint8_t* buffer, std::int64_t /*timeout_ns*/) {
  if (!pending_) return 0;
  pending_ = false;
  std::copy(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(size_), buffer);
  return size_;
}

std::size_t VirtualSegment::serve(Link& link, std::int64_t timeout_ns, const std::function<void()>& between_frames) {
  std::size_t answered = 0;
  for (;;) {
    const std::size_t size = link.receive(buffer_.data(), timeout_ns);
    if (size == 0) return answered;
    if (pass(buffer_.data(), size) != FrameError::kNone) continue;  // dropped, as a slave drops it
    if (link.send({buffer_.data(), size})) ++answered;
    if (between_frames) between_frames();
  }
}

}  // namespace pmlsm::ethercat
