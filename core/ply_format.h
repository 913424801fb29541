// The PLY header model, its parser and the header checks that core/ply_io.cpp runs before it
// decodes the data. An implementation detail of ply_io.cpp, not a public API: use core/ply_io.h.
//
// - ParseHeader reads the header and rejects, with an Error naming the file, a missing
//   end_header, big-endian data, an unknown type or keyword, a malformed line, or more than
//   2^31 - 1 elements of one kind.
// - CheckHeader finds what ReadPly decodes (positions, normals, colours, face corners) and
//   rejects layouts whose meaning is unclear, e.g. only some of red/green/blue.
// - CheckCountsFitInFile rejects element counts that cannot fit in the file before anything is
//   allocated; the exact check (every record, list lengths included) is the decoder's.
// - DataCursor reads the data after the header, buffered.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace genscene::ply {

enum class PlyFormat { kAscii, kBinaryLittleEndian };

// The scalar types of the PLY format (each has two spellings, e.g. uchar and uint8).
enum class PlyType : uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kFloat32,
  kFloat64
};

// Bytes of one value in binary files.
int TypeSize(PlyType type);
bool IsFloat(PlyType type);
bool IsSigned(PlyType type);

struct PlyProperty {
  std::string name;
  std::string type;        // as spelled in the header: a scalar's type, or a list's entry type
  std::string count_type;  // as spelled in the header: a list's length type; empty for a scalar
  PlyType value = PlyType::kFloat32;  // `type`
  PlyType count = PlyType::kUint8;    // `count_type`, for a list
  bool is_list() const { return !count_type.empty(); }
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;

  int FindIndex(const std::string& property) const {
    for (size_t i = 0; i < properties.size(); ++i) {
      if (properties[i].name == property) return static_cast<int>(i);
    }
    return -1;
  }
  const PlyProperty* Find(const std::string& property) const {
    const int i = FindIndex(property);
    return i < 0 ? nullptr : &properties[static_cast<size_t>(i)];
  }
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  uint64_t data_offset = 0;  // first byte after the end_header line

  int FindIndex(const std::string& element) const {
    for (size_t i = 0; i < elements.size(); ++i) {
      if (elements[i].name == element) return static_cast<int>(i);
    }
    return -1;
  }
};

// Parses the header of the PLY file `path` of `file_size` bytes (within its first MiB). Throws
// Error naming the file on any problem.
PlyHeader ParseHeader(const std::filesystem::path& path, uint64_t file_size);

// What ReadPly decodes.
struct PlyLayout {
  int vertex = -1;  // element indices in the header; face is -1 without faces
  int face = -1;
  bool vertex_normals = false;  // nx/ny/nz
  bool vertex_rgb = false;      // red/green/blue (or diffuse_*): sRGB 8-bit, or float in [0, 1]
  bool vertex_albedo = false;   // float albedo_r/g/b: linear, preferred over vertex_rgb
  bool vertex_color = false;    // float color_r/g/b: linear observed colour, after albedo_r/g/b
  bool vertex_diffuse = false;  // vertex_rgb is spelled diffuse_red/green/blue
  bool face_rgb = false;
  bool face_albedo = false;
  bool face_color = false;
  int face_indices_property = -1;  // index of vertex_indices (or vertex_index) in the face element
};

inline constexpr std::array<const char*, 3> kPosition = {"x", "y", "z"};
inline constexpr std::array<const char*, 3> kNormal = {"nx", "ny", "nz"};
inline constexpr std::array<const char*, 3> kRgb = {"red", "green", "blue"};
inline constexpr std::array<const char*, 3> kDiffuseRgb = {"diffuse_red", "diffuse_green",
                                                           "diffuse_blue"};
// The linear float colour properties, of vertices or faces: albedo (reflectance), or the colour a
// camera observed (shading included).
inline constexpr std::array<const char*, 3> kAlbedo = {"albedo_r", "albedo_g", "albedo_b"};
inline constexpr std::array<const char*, 3> kObserved = {"color_r", "color_g", "color_b"};

// Finds what ReadPly decodes (see PlyLayout). Throws Error naming the file `name` for a header
// without vertex x/y/z, with a face element but no integer vertex_indices list, with only some
// of x/y/z, nx/ny/nz, red/green/blue or albedo_r/g/b, or with a type that does not fit the
// property (positions, normals and albedo: float or double; colours: 8-bit or float).
PlyLayout CheckHeader(const PlyHeader& header, const std::string& name);

// The smallest data size the declared element counts can have: binary, every record at its
// minimal size (lists empty); ASCII, one character per value (a list: its length) and one
// separator between values. Anything smaller is certainly truncated or has a corrupt header.
void CheckCountsFitInFile(const PlyHeader& header, uint64_t file_size, const std::string& name);

// Buffered reading of bytes [begin, end) of a file, for the data after the header.
class DataCursor {
 public:
  DataCursor(const std::filesystem::path& path, uint64_t begin, uint64_t end);

  uint64_t remaining() const { return end_ - next_ + (length_ - pos_); }

  // The next byte, or -1 at the end.
  int Get() {
    if (pos_ == length_ && !Fill()) return -1;
    return static_cast<unsigned char>(buffer_[pos_++]);
  }

  // False (having consumed what is left) when fewer than n bytes remain.
  bool Read(void* destination, size_t n);
  bool Skip(uint64_t n);

 private:
  bool Fill();

  std::ifstream file_;
  uint64_t next_;  // file offset of the byte after the buffer
  uint64_t end_;
  std::vector<char> buffer_;
  size_t pos_ = 0;
  size_t length_ = 0;
};

}  // namespace genscene::ply
