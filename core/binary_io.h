// Little helpers for the project's binary files (.gsv TSDF volumes, .mcol Mesh Colors): values
// appended to a byte string, and a reader that names the file and the field when it runs out.
// Little-endian hosts only (x86-64, aarch64), which the static_assert below keeps honest.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>

#include "core/check.h"

namespace genscene {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the binary formats are little-endian");

// Appends the bytes of a trivially copyable value.
template <typename T>
void PutBinary(std::string& out, const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  out.append(bytes, sizeof(T));
}

// The unsigned 32-bit value at bytes[at], little-endian (LoadLE32) or big-endian (LoadBE32, as in
// PNG); nullopt when the four bytes run past the end.
inline std::optional<uint32_t> LoadLE32(std::string_view bytes, size_t at) {
  if (at > bytes.size() || bytes.size() - at < 4) return std::nullopt;
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
  return v;
}
inline std::optional<uint32_t> LoadBE32(std::string_view bytes, size_t at) {
  if (at > bytes.size() || bytes.size() - at < 4) return std::nullopt;
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
  return v;
}

// Reads values in order from a byte string; throws Error("<path>: truncated <kind> file (N bytes)
// while reading <what>") when the data runs out.
class BinaryReader {
 public:
  BinaryReader(const std::string& data, std::filesystem::path path, std::string kind)
      : data_(data), path_(std::move(path)), kind_(std::move(kind)) {}

  template <typename T>
  T Get(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (pos_ + sizeof(T) > data_.size()) {
      throw Error(Format(path_.string(), ": truncated ", kind_, " file (", data_.size(),
                         " bytes) while reading ", what));
    }
    T value;
    std::memcpy(&value, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  size_t position() const { return pos_; }
  size_t remaining() const { return data_.size() - pos_; }

 private:
  const std::string& data_;
  std::filesystem::path path_;
  std::string kind_;
  size_t pos_ = 0;
};

}  // namespace genscene
