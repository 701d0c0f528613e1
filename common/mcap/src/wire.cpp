// The MCAP byte layout helpers and chunk codecs shared by writer and reader (see wire.hpp).

#include "wire.hpp"

#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <new>
#include <stdexcept>

namespace pmlsm::mcap {

Compression parse_compression(const std::string& name) {
  if (name == "none") return Compression::none;
  if (name == "zstd") return Compression::zstd;
  if (name == "lz4") return Compression::lz4;
  throw std::invalid_argument("mcap: unknown compression '" + name + "' (expected none, zstd or lz4)");
}

std::string to_string(Compression compression) {
  switch (compression) {
    case Compression::none: return "none";
    case Compression::zstd: return "zstd";
    case Compression::lz4: return "lz4";
  }
  return "none";
}

namespace detail {

std::string opcode_name(std::uint8_t opcode) {
  switch (static_cast<Opcode>(opcode)) {
    case Opcode::header: return "Header";
    case Opcode::footer: return "Footer";
    case Opcode::schema: return "Schema";
    case Opcode::channel: return "Channel";
    case Opcode::message: return "Message";
    case Opcode::chunk: return "Chunk";
    case Opcode::message_index: return "MessageIndex";
    case Opcode::chunk_index: return "ChunkIndex";
    case Opcode::attachment: return "Attachment";
    case Opcode::attachment_index: return "AttachmentIndex";
    case Opcode::statistics: return "Statistics";
    case Opcode::metadata: return "Metadata";
    case Opcode::metadata_index: return "MetadataIndex";
    case Opcode::summary_offset: return "SummaryOffset";
    case Opcode::data_end: return "DataEnd";
  }
  char text[32];
  std::snprintf(text, sizeof text, "unknown (0x%02x)", static_cast<unsigned>(opcode));
  return text;
}

// ---- encoding ----

namespace {
// Byte by byte: the file format is little-endian whatever the host is.
template <class T>
void put_le(std::vector<std::uint8_t>& out, T value) {
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    out.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
  }
}
}  // namespace

void put_u8(std::vector<std::uint8_t>& out, std::uint8_t value) { out.push_back(value); }
void put_u16(std::vector<std::uint8_t>& out, std::uint16_t value) { put_le(out, value); }
void put_u32(std::vector<std::uint8_t>& out, std::uint32_t value) { put_le(out, value); }
void put_u64(std::vector<std::uint8_t>& out, std::uint64_t value) { put_le(out, value); }

void put_bytes(std::vector<std::uint8_t>& out, const std::uint8_t* data, std::size_t size) {
  if (size > 0) out.insert(out.end(), data, data + size);
}

void put_string(std::vector<std::uint8_t>& out, const std::string& text) {
  if (text.size() > UINT32_MAX) {
    throw std::invalid_argument("mcap: string of " + std::to_string(text.size()) +
                                " bytes exceeds the format's uint32 length");
  }
  put_u32(out, static_cast<std::uint32_t>(text.size()));
  put_bytes(out, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

void patch_u64(std::vector<std::uint8_t>& out, std::size_t at, std::uint64_t value) {
  for (std::size_t i = 0; i < 8; ++i) out[at + i] = static_cast<std::uint8_t>(value >> (8 * i));
}

void patch_u32(std::vector<std::uint8_t>& out, std::size_t at, std::uint32_t value) {
  for (std::size_t i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>(value >> (8 * i));
}

std::size_t begin_record(std::vector<std::uint8_t>& out, Opcode opcode) {
  put_u8(out, static_cast<std::uint8_t>(opcode));
  const std::size_t length_at = out.size();
  put_u64(out, 0);
  return length_at;
}

void end_record(std::vector<std::uint8_t>& out, std::size_t length_at) {
  patch_u64(out, length_at, out.size() - length_at - 8);
}

// ---- decoding ----

bool Cursor::take(std::size_t size) {
  if (!ok_ || size > size_ - position_) {
    ok_ = false;
    return false;
  }
  position_ += size;
  return true;
}

namespace {
template <class T>
T get_le(const std::uint8_t* data) {
  T value = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) value |= static_cast<T>(static_cast<T>(data[i]) << (8 * i));
  return value;
}
}  // namespace

std::uint8_t Cursor::u8() { return take(1) ? data_[position_ - 1] : 0; }
std::uint16_t Cursor::u16() { return take(2) ? get_le<std::uint16_t>(data_ + position_ - 2) : 0; }
std::uint32_t Cursor::u32() { return take(4) ? get_le<std::uint32_t>(data_ + position_ - 4) : 0; }
std::uint64_t Cursor::u64() { return take(8) ? get_le<std::uint64_t>(data_ + position_ - 8) : 0; }

const std::uint8_t* Cursor::bytes(std::uint64_t size) {
  if (size > remaining()) {
    ok_ = false;
    return nullptr;
  }
  const std::uint8_t* start = data_ + position_;
  take(static_cast<std::size_t>(size));
  return ok_ ? start : nullptr;
}

std::string Cursor::string() {
  const std::uint32_t length = u32();
  const std::uint8_t* text = bytes(length);
  return text != nullptr ? std::string(reinterpret_cast<const char*>(text), length) : std::string();
}

std::map<std::string, std::string> Cursor::string_map() {
  std::map<std::string, std::string> entries;
  const std::uint32_t length_bytes = u32();
  const std::uint8_t* start = bytes(length_bytes);
  if (start == nullptr) return entries;
  Cursor inner(start, length_bytes);
  while (inner.ok() && inner.remaining() > 0) {
    std::string key = inner.string();
    std::string value = inner.string();
    if (inner.ok()) entries[std::move(key)] = std::move(value);
  }
  if (!inner.ok()) ok_ = false;  // an entry ran past the map's declared length
  return entries;
}

// ---- CRC-32 ----

std::uint32_t crc32_update(std::uint32_t crc, const std::uint8_t* data, std::size_t size) {
  // zlib returns its initial value, not `crc`, for a null buffer: an empty range changes nothing.
  if (size == 0) return crc;
  // crc32_z takes a size_t length (crc32 only a uInt), so chunks over 4 GiB are fine too.
  return static_cast<std::uint32_t>(::crc32_z(crc, data, size));
}

// ---- Compressor ----

namespace {
// zstd's own default: about 3x on our telemetry at several hundred MB/s, far more than a recorder
// of a 1 kHz system needs, so no knob for it.
constexpr int kZstdLevel = ZSTD_CLEVEL_DEFAULT;

LZ4F_preferences_t lz4_preferences(std::size_t content_size_bytes) {
  LZ4F_preferences_t preferences;
  std::memset(&preferences, 0, sizeof preferences);
  // 4 MB blocks: a whole default chunk (1 MiB) is one block, compressed with full context.
  preferences.frameInfo.blockSizeID = LZ4F_max4MB;
  // The content size in the frame header lets readers size their buffer from the frame alone.
  preferences.frameInfo.contentSize = content_size_bytes;
  // No frame checksum: the chunk's uncompressed_crc covers the same bytes.
  preferences.frameInfo.contentChecksumFlag = LZ4F_noContentChecksum;
  preferences.compressionLevel = 0;  // the fast default
  // The whole chunk is given at once: compress it straight from the input, no staging copy.
  preferences.autoFlush = 1;
  return preferences;
}
}  // namespace

Compressor::Compressor(Compression compression) : compression_(compression) {
  if (compression_ == Compression::zstd) {
    zstd_ = ZSTD_createCCtx();
    if (zstd_ == nullptr) throw std::bad_alloc();
  } else if (compression_ == Compression::lz4) {
    if (LZ4F_isError(LZ4F_createCompressionContext(&lz4_, LZ4F_VERSION))) throw std::bad_alloc();
  }
}

Compressor::~Compressor() {
  if (zstd_ != nullptr) ZSTD_freeCCtx(zstd_);
  if (lz4_ != nullptr) LZ4F_freeCompressionContext(lz4_);
}

void Compressor::compress_append(const std::uint8_t* data, std::size_t size, std::vector<std::uint8_t>& out) {
  const std::size_t start = out.size();
  switch (compression_) {
    case Compression::none: put_bytes(out, data, size); return;
    case Compression::zstd: {
      const std::size_t bound = ZSTD_compressBound(size);
      out.resize(start + bound);
      const std::size_t written = ZSTD_compressCCtx(zstd_, out.data() + start, bound, data, size, kZstdLevel);
      if (ZSTD_isError(written)) {
        out.resize(start);
        throw std::runtime_error(std::string("mcap: zstd compression failed: ") + ZSTD_getErrorName(written));
      }
      out.resize(start + written);
      return;
    }
    case Compression::lz4: {
      const LZ4F_preferences_t preferences = lz4_preferences(size);
      const std::size_t bound = LZ4F_compressFrameBound(size, &preferences);
      out.resize(start + bound);
      std::uint8_t* const begin = out.data() + start;
      std::size_t written = 0;
      std::size_t result = LZ4F_compressBegin(lz4_, begin, bound, &preferences);
      if (!LZ4F_isError(result)) {
        written += result;
        result = LZ4F_compressUpdate(lz4_, begin + written, bound - written, data, size, nullptr);
      }
      if (!LZ4F_isError(result)) {
        written += result;
        result = LZ4F_compressEnd(lz4_, begin + written, bound - written, nullptr);
      }
      if (LZ4F_isError(result)) {
        out.resize(start);
        throw std::runtime_error(std::string("mcap: lz4 compression failed: ") + LZ4F_getErrorName(result));
      }
      written += result;
      out.resize(start + written);
      return;
    }
  }
}

// ---- Decompressor ----

namespace {
// First output size for a chunk of unknown ratio: enough for typical telemetry ratios (<8x)
// in one go, and small enough that a lying size field costs little before the data runs out.
std::size_t initial_output_bytes(std::size_t compressed_bytes, std::size_t expected_bytes) {
  const std::size_t guess =
      compressed_bytes > (SIZE_MAX - (1U << 16)) / 8 ? SIZE_MAX : compressed_bytes * 8 + (1U << 16);
  return std::min(guess, expected_bytes);
}

// Makes out at least `wanted` long (it never shrinks: the buffer is reused chunk after chunk).
// @return false when memory runs out.
bool grow_to(std::vector<std::uint8_t>& out, std::size_t wanted) {
  if (out.size() >= wanted) return true;
  try {
    out.resize(wanted);
  } catch (const std::bad_alloc&) {
    return false;
  } catch (const std::length_error&) {
    return false;
  }
  return true;
}

// Next output size while a codec still produces: double, bounded by the declared size.
std::size_t next_output_bytes(std::size_t current, std::size_t expected_bytes) {
  const std::size_t doubled = current > SIZE_MAX / 2 ? SIZE_MAX : std::max<std::size_t>(current * 2, 1U << 16);
  return std::min(doubled, expected_bytes);
}

std::string too_large(std::size_t expected_bytes) {
  return "decompresses to more than the declared " + std::to_string(expected_bytes) + " bytes";
}
std::string too_small(std::size_t produced_bytes, std::size_t expected_bytes) {
  return "decompresses to " + std::to_string(produced_bytes) + " bytes, not the declared " +
         std::to_string(expected_bytes);
}
std::string no_memory(std::size_t bytes) {
  return "cannot allocate " + std::to_string(bytes) + " bytes to decompress it";
}
}  // namespace

Decompressor::Decompressor() = default;

Decompressor::~Decompressor() {
  if (zstd_ != nullptr) ZSTD_freeDCtx(zstd_);
  if (lz4_ != nullptr) LZ4F_freeDecompressionContext(lz4_);
}

std::string Decompressor::decompress(const std::string& compression, const std::uint8_t* data, std::size_t size,
                                     std::uint64_t expected_size, std::vector<std::uint8_t>& out) {
  if (expected_size > SIZE_MAX) return "declared uncompressed size " + std::to_string(expected_size) + " is too large";
  const auto expected = static_cast<std::size_t>(expected_size);
  if (compression == "zstd") return zstd(data, size, expected, out);
  if (compression == "lz4") return lz4(data, size, expected, out);
  return "unknown compression '" + compression + "'";
}

std::string Decompressor::zstd(const std::uint8_t* data, std::size_t size, std::size_t expected,
                               std::vector<std::uint8_t>& out) {
  if (zstd_ == nullptr) {
    zstd_ = ZSTD_createDCtx();
    if (zstd_ == nullptr) return no_memory(0);
  }
  ZSTD_DCtx_reset(zstd_, ZSTD_reset_session_only);  // a failed chunk must not leak state into the next
  if (!grow_to(out, initial_output_bytes(size, expected))) return no_memory(expected);

  ZSTD_inBuffer input{data, size, 0};
  std::size_t produced = 0;
  for (;;) {
    if (produced == std::min(out.size(), expected) && out.size() < expected &&
        !grow_to(out, next_output_bytes(out.size(), expected))) {
      return no_memory(expected);
    }
    ZSTD_outBuffer output{out.data(), std::min(out.size(), expected), produced};
    const std::size_t input_before = input.pos;
    const std::size_t result = ZSTD_decompressStream(zstd_, &output, &input);
    if (ZSTD_isError(result)) return std::string("zstd: ") + ZSTD_getErrorName(result);
    const bool progressed = input.pos != input_before || output.pos != produced;
    produced = output.pos;
    if (result == 0 && input.pos == input.size) break;  // last frame complete
    if (!progressed) {
      if (produced >= expected) return too_large(expected);
      return input.pos == input.size ? "zstd: the frame is cut short" : "zstd: no progress";
    }
  }
  if (produced != expected) return too_small(produced, expected);
  return "";
}

std::string Decompressor::lz4(const std::uint8_t* data, std::size_t size, std::size_t expected,
                              std::vector<std::uint8_t>& out) {
  if (lz4_ == nullptr && LZ4F_isError(LZ4F_createDecompressionContext(&lz4_, LZ4F_VERSION))) {
    lz4_ = nullptr;
    return no_memory(0);
  }
  LZ4F_resetDecompressionContext(lz4_);  // a failed chunk must not leak state into the next
  if (!grow_to(out, initial_output_bytes(size, expected))) return no_memory(expected);

  std::size_t consumed = 0;
  std::size_t produced = 0;
  for (;;) {
    if (produced == std::min(out.size(), expected) && out.size() < expected &&
        !grow_to(out, next_output_bytes(out.size(), expected))) {
      return no_memory(expected);
    }
    std::size_t output_bytes = std::min(out.size(), expected) - produced;
    std::size_t input_bytes = size - consumed;
    const std::size_t result =
        LZ4F_decompress(lz4_, out.data() + produced, &output_bytes, data + consumed, &input_bytes, nullptr);
    if (LZ4F_isError(result)) return std::string("lz4: ") + LZ4F_getErrorName(result);
    consumed += input_bytes;
    produced += output_bytes;
    if (result == 0 && consumed == size) break;  // last frame complete
    if (input_bytes == 0 && output_bytes == 0) {
      if (produced >= expected) return too_large(expected);
      return consumed == size ? "lz4: the frame is cut short" : "lz4: no progress";
    }
  }
  if (produced != expected) return too_small(produced, expected);
  return "";
}

}  // namespace detail
}  // namespace pmlsm::mcap
