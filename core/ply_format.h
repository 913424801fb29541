// The PLY header model and the checks core/ply_io.cpp runs before it hands a file to OpenMesh 9.
// An implementation detail of ply_io.cpp, not a public API: use core/ply_io.h.
//
// - Header check first. We parse the header ourselves and reject, with an Error naming the file,
//   anything OpenMesh would misread: a missing end_header (OpenMesh 9.0 loops forever), big-endian
//   data, element counts that cannot fit in the file (checked before anything is allocated), and
//   property layouts OpenMesh cannot skip. Then a cheap pass over the data walks every record
//   (list lengths included) so that a truncated file is an Error, never a short or garbage mesh.
// - A normalised header. OpenMesh's PLY reader re-parses the header from the stream and then
//   seeks to "12 bytes after the last token before end_header", which is off by one byte when a
//   comment is the last header line (binary data is then silently shifted). It also reads ASCII
//   custom `char`/`uchar` properties one character at a time, which desynchronises the rest of the
//   line. We therefore hand OpenMesh a stream made of a canonical header we write (no comments,
//   ASCII 8-bit types declared as `int`, which reads the same text) followed by the file's data.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <streambuf>
#include <string>
#include <vector>

namespace genscene::ply {

// ------------------------------------------------------------------------------------------------
// Header model and parser.

enum class PlyFormat { kAscii, kBinaryLittleEndian };

struct PlyProperty {
  std::string name;
  std::string type;        // scalar type, or the entry type of a list
  std::string count_type;  // type of a list's length; empty for a scalar
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
// Error naming the file on any problem, e.g. no end_header, big-endian data, an unknown type or
// keyword, a malformed line, more than 2^31 - 1 elements of one kind.
PlyHeader ParseHeader(const std::filesystem::path& path, uint64_t file_size);

// ------------------------------------------------------------------------------------------------
// What we read, and the header checks that keep OpenMesh's reader on safe ground.

struct PlyLayout {
  int vertex = -1;  // element indices in the header
  int face = -1;
  bool vertex_normals = false;
  bool vertex_rgb = false;     // red/green/blue (or diffuse_*): sRGB 8-bit
  bool vertex_albedo = false;  // float albedo_r/g/b: linear, preferred
  bool face_rgb = false;
  bool face_albedo = false;
  int face_indices_property = -1;  // index of vertex_indices in the face element
};

// The linear float colour properties, of vertices or faces.
inline constexpr std::array<const char*, 3> kAlbedo = {"albedo_r", "albedo_g", "albedo_b"};

// Finds what we read (see PlyLayout). Throws Error naming the file `name` for a header OpenMesh
// would misread, e.g. no vertex x/y/z, faces before vertices, a property OpenMesh cannot skip, an
// unsupported type, only some of red/green/blue.
PlyLayout CheckHeader(const PlyHeader& header, const std::string& name);

// ------------------------------------------------------------------------------------------------
// Size check (no allocation) and the walk over the data.

// The smallest data size the declared element counts can have: binary, every record at its
// minimal size (lists empty); ASCII, one character per value (a list: its length) and one
// separator between values. Anything smaller is certainly truncated or has a corrupt header; the
// exact check (face sizes included) is WalkData's.
void CheckCountsFitInFile(const PlyHeader& header, uint64_t file_size, const std::string& name);

// Walks every record of the elements OpenMesh will read, list lengths included, so that a
// truncated or inconsistent file is an Error before OpenMesh sees it (OpenMesh would read a
// corrupt list length of 4e9 as 4e9 indices).
void WalkData(const std::filesystem::path& path, const PlyHeader& header, const PlyLayout& layout,
              uint64_t file_size);

// ------------------------------------------------------------------------------------------------
// What OpenMesh reads: the canonical header, then the file's data.

// The header we hand to OpenMesh: no comments, one space between tokens, "end_header\n" right
// after the last property line (where OpenMesh's seek expects it). In ASCII files 8-bit types and
// list lengths are declared as int: the text reads the same, and OpenMesh then parses numbers
// instead of single characters.
std::string CanonicalHeader(const PlyHeader& header);

// A seekable read-only stream buffer over `prefix`, then bytes [begin, end) of a file, then
// `suffix`: the canonical header followed by the file's own data, without copying the data.
class SplicedFileBuf : public std::streambuf {
 public:
  SplicedFileBuf(std::string prefix, const std::filesystem::path& path, uint64_t begin,
                 uint64_t end, std::string suffix);

 protected:
  int_type underflow() override;
  pos_type seekoff(off_type off, std::ios_base::seekdir dir,
                   std::ios_base::openmode which) override;
  pos_type seekpos(pos_type pos, std::ios_base::openmode which) override;

 private:
  uint64_t Total() const { return prefix_.size() + body_size_ + suffix_.size(); }

  // Fills the buffer from logical position `at`; returns the number of bytes.
  size_t Load(uint64_t at);

  std::string prefix_;
  std::string suffix_;
  std::ifstream file_;
  uint64_t begin_;
  uint64_t body_size_;
  std::vector<char> buffer_;
  uint64_t position_ = 0;  // logical position of eback()
};

}  // namespace genscene::ply
