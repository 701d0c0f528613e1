// What the fuzz targets share. Each target is a plain function
//
//   int pmlsm::fuzz::<target>::fuzz_one(const std::uint8_t* data, std::size_t size);
//
// that feeds one input to a parser of outside input and returns 0. Bad input must end in the
// parser's documented error (caught in the target); anything else (a crash, a sanitizer report,
// an exception of another type, a hang) is a defect. The same function runs under libFuzzer
// (fuzz_<target>, -DPMLSM_FUZZ=ON with clang) and in the normal build's regression driver
// (fuzz_regressions, over fuzz/corpus/<target>/ and fuzz/regressions/<target>/).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace pmlsm::fuzz {

/// A file of the source tree (configs/system.yaml, idl/Stamp.idl), read whole; aborts when it
/// is missing: a target without its fixed inputs would test nothing.
std::string source_file(const std::string& relative_path);

/// The absolute path of a file of the source tree.
std::string source_path(const std::string& relative_path);

inline std::string as_text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

/// Reads the input front to back; past the end every read gives 0, so any input is usable.
class ByteReader {
 public:
  ByteReader(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  bool empty() const { return position_ >= size_; }
  std::size_t remaining() const { return empty() ? 0 : size_ - position_; }
  std::uint8_t u8() { return empty() ? 0 : data_[position_++]; }
  // Little endian; each byte read in its own statement (the operands of | are unsequenced).
  std::uint16_t u16() {
    const std::uint16_t low = u8();
    return static_cast<std::uint16_t>(low | (u8() << 8));
  }
  std::uint32_t u32() {
    const std::uint32_t low = u16();
    return low | (static_cast<std::uint32_t>(u16()) << 16);
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t position_ = 0;
};

}  // namespace pmlsm::fuzz
