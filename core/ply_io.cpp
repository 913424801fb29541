// PLY mesh I/O. OpenMesh 9 parses and writes the PLY data; this file adds what OpenMesh lacks:
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
// - Our own importer/exporter. OpenMesh's ImporterT builds half-edge connectivity: for a face that
//   would make the mesh non-manifold it DUPLICATES the face's vertices (appended at the end), and
//   it DROPS faces with a repeated or invalid vertex index (evidence: a 5-vertex "fin" of 3
//   triangles on one edge plus a degenerate face reads as 8 vertices / 3 faces with read_mesh into
//   a PolyMesh or TriMesh). Meshes from marching cubes are often non-manifold, so instead our
//   BaseImporter records exactly the vertices and faces of the file, in file order, without
//   connectivity; our BaseExporter writes a TriangleMesh as it is (no half-edge mesh either).
// - Custom properties: OpenMesh's PLY reader (with Options::Custom) stores non-standard properties,
//   such as the float face properties albedo_r/g/b, as named properties of the importer's kernel,
//   in ASCII and binary; its writer writes every *persistent* float property of the exporter's
//   kernel, as `property float <name>`. Both are used here for albedo_r/g/b.
//
// Polygons with more than 3 vertices are fan-triangulated: (v0, v1, ..., vn-1) becomes the
// triangles (v0, vk, vk+1), k = 1 .. n-2, in that order, each with the polygon's colour. The face
// count of the result is then the sum of (n - 2) over the file's faces. A face with a repeated
// vertex index is kept as it is (a degenerate triangle), as the file says.
//
// OpenMesh's reader and writer are singletons with mutable state, so calls into them are
// serialised by a mutex; OpenMesh's log streams are silenced during those calls (our Errors say
// what went wrong).
#include "core/ply_io.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/exporter/BaseExporter.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/Mesh/BaseKernel.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <optional>
#include <streambuf>
#include <string>
#include <system_error>
#include <vector>

#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"

namespace genscene {

namespace {

namespace fs = std::filesystem;
using OpenMesh::EdgeHandle;
using OpenMesh::FaceHandle;
using OpenMesh::HalfedgeHandle;
using OpenMesh::VertexHandle;

constexpr size_t kMaxHeaderBytes = size_t{1} << 20;  // a longer header is an error
constexpr uint64_t kMaxElementCount = std::numeric_limits<int32_t>::max();

// ------------------------------------------------------------------------------------------------
// Header model and parser.

enum class PlyFormat { kAscii, kBinaryLittleEndian };

struct PlyType {
  int size = 0;  // bytes in binary files
  bool is_float = false;
};

std::optional<PlyType> LookupType(const std::string& name) {
  if (name == "char" || name == "int8" || name == "uchar" || name == "uint8")
    return PlyType{1, false};
  if (name == "short" || name == "int16" || name == "ushort" || name == "uint16")
    return PlyType{2, false};
  if (name == "int" || name == "int32" || name == "uint" || name == "uint32")
    return PlyType{4, false};
  if (name == "float" || name == "float32") return PlyType{4, true};
  if (name == "double" || name == "float64") return PlyType{8, true};
  return std::nullopt;
}

bool IsEightBit(const std::string& type) {
  return type == "char" || type == "int8" || type == "uchar" || type == "uint8";
}

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

uint64_t ParseCount(const std::string& token, const std::string& where) {
  uint64_t value = 0;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  if (ec == std::errc::result_out_of_range) {
    throw Error(Format(where, ": element count ", token, " is too large"));
  }
  if (ec != std::errc() || ptr != end) {
    throw Error(Format(where, ": element count '", token, "' is not a non-negative integer"));
  }
  return value;
}

PlyHeader ParseHeader(const fs::path& path, uint64_t file_size) {
  const std::string name = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(Format(name, ": cannot open (", std::strerror(errno), ")"));
  std::string text(static_cast<size_t>(std::min<uint64_t>(file_size, kMaxHeaderBytes)), '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  if (static_cast<size_t>(in.gcount()) != text.size()) {
    throw Error(Format(name, ": cannot read the PLY header (", std::strerror(errno), ")"));
  }

  // Magic: the first line is "ply".
  if (text.compare(0, 3, "ply") != 0 ||
      (text.size() > 3 && text[3] != '\n' && text[3] != '\r' && text[3] != ' ')) {
    throw Error(Format(name, ": not a PLY file (it does not start with the line 'ply')"));
  }

  PlyHeader header;
  bool have_format = false;
  bool ended = false;
  size_t pos = 0;
  int line_number = 0;
  while (pos < text.size()) {
    const size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) break;
    std::string line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_number;
    const std::string where = Format(name, ": PLY header line ", line_number);
    const std::vector<std::string> tokens = SplitWhitespace(line);
    if (line_number == 1) {
      if (tokens.size() != 1 || tokens[0] != "ply") {
        throw Error(Format(name, ": not a PLY file (it does not start with the line 'ply')"));
      }
      continue;
    }
    if (tokens.empty()) continue;  // blank line (OpenMesh skips them too)
    const std::string& keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") {
      if (tokens.size() != 1)
        throw Error(Format(where, ": malformed end_header line '", line, "'"));
      header.data_offset = pos;
      ended = true;
      break;
    }
    if (keyword == "format") {
      if (have_format) throw Error(Format(where, ": second format line"));
      if (!header.elements.empty()) throw Error(Format(where, ": format line after an element"));
      if (tokens.size() != 3) throw Error(Format(where, ": malformed format line '", line, "'"));
      if (tokens[1] == "ascii") {
        header.format = PlyFormat::kAscii;
      } else if (tokens[1] == "binary_little_endian") {
        header.format = PlyFormat::kBinaryLittleEndian;
      } else if (tokens[1] == "binary_big_endian") {
        throw Error(Format(name,
                           ": binary_big_endian PLY is not supported "
                           "(convert it to binary_little_endian or ascii)"));
      } else {
        throw Error(Format(where, ": unknown PLY format '", tokens[1], "'"));
      }
      have_format = true;
    } else if (keyword == "element") {
      if (!have_format) throw Error(Format(where, ": element before the format line"));
      if (tokens.size() != 3) throw Error(Format(where, ": malformed element line '", line, "'"));
      PlyElement element;
      element.name = tokens[1];
      element.count = ParseCount(tokens[2], where);
      if (element.count > kMaxElementCount) {
        throw Error(Format(where, ": ", element.count, " ", element.name, " elements; at most ",
                           kMaxElementCount, " are supported"));
      }
      if (header.FindIndex(element.name) >= 0) {
        throw Error(Format(where, ": second element named '", element.name, "'"));
      }
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) throw Error(Format(where, ": property before any element"));
      PlyProperty property;
      if (tokens.size() == 5 && tokens[1] == "list") {
        property.count_type = tokens[2];
        property.type = tokens[3];
        property.name = tokens[4];
        const auto count_type = LookupType(property.count_type);
        if (!count_type || count_type->is_float) {
          throw Error(Format(where, ": list length type '", property.count_type,
                             "' is not an integer type"));
        }
      } else if (tokens.size() == 3 && tokens[1] != "list") {
        property.type = tokens[1];
        property.name = tokens[2];
      } else {
        throw Error(Format(where, ": malformed property line '", line, "'"));
      }
      if (!LookupType(property.type)) {
        throw Error(Format(where, ": unknown property type '", property.type, "'"));
      }
      PlyElement& element = header.elements.back();
      if (element.Find(property.name)) {
        throw Error(Format(where, ": second property '", property.name, "' in element '",
                           element.name, "'"));
      }
      element.properties.push_back(std::move(property));
    } else {
      throw Error(Format(where, ": unknown header keyword '", keyword, "'"));
    }
  }
  if (!ended) {
    if (file_size > kMaxHeaderBytes) {
      throw Error(Format(name, ": no end_header line in the first ", kMaxHeaderBytes,
                         " bytes (not a PLY mesh, or a corrupt header)"));
    }
    throw Error(Format(name, ": the PLY header has no end_header line (truncated file?)"));
  }
  if (!have_format) throw Error(Format(name, ": the PLY header has no format line"));
  return header;
}

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

// Either all of `names` are scalar properties of `element`, or none is present.
bool HasAllOrNone(const PlyElement& element, const std::array<const char*, 3>& names,
                  const std::string& where) {
  int present = 0;
  for (const char* n : names) {
    if (const PlyProperty* p = element.Find(n)) {
      ++present;
      if (p->is_list())
        throw Error(Format(where, ": ", element.name, " property '", n, "' is a list"));
    }
  }
  if (present != 0 && present != 3) {
    throw Error(Format(where, ": ", element.name, " element has only some of ", names[0], "/",
                       names[1], "/", names[2]));
  }
  return present == 3;
}

void RequireFloat(const PlyElement& element, const char* property, const std::string& where) {
  const PlyProperty* p = element.Find(property);
  if (!p) return;
  if (p->is_list() || !LookupType(p->type)->is_float) {
    throw Error(Format(where, ": ", element.name, " property '", property, "' has type ",
                       p->is_list() ? "list" : p->type, "; a float or double is needed"));
  }
}

void RequireSameType(const PlyElement& element, const std::array<const char*, 3>& names,
                     const std::string& where) {
  const PlyProperty* first = element.Find(names[0]);
  for (const char* n : names) {
    const PlyProperty* p = element.Find(n);
    if (p && first && LookupType(p->type)->size != LookupType(first->type)->size) {
      throw Error(Format(where, ": ", element.name, " properties ", names[0], "/", names[1], "/",
                         names[2], " have different types"));
    }
  }
}

// OpenMesh reads colours as 8-bit integers or as floats in [0, 1] (scaled to 8 bits).
void RequireColorType(const PlyElement& element, const char* property, const std::string& where) {
  const PlyProperty* p = element.Find(property);
  if (!p) return;
  if (p->is_list() || !(IsEightBit(p->type) || p->type == "float" || p->type == "float32")) {
    throw Error(Format(where, ": ", element.name, " colour property '", property, "' has type ",
                       p->is_list() ? "list" : p->type, "; uchar or float is supported"));
  }
}

constexpr std::array<const char*, 3> kPosition = {"x", "y", "z"};
constexpr std::array<const char*, 3> kNormal = {"nx", "ny", "nz"};
constexpr std::array<const char*, 3> kRgb = {"red", "green", "blue"};
constexpr std::array<const char*, 3> kDiffuseRgb = {"diffuse_red", "diffuse_green", "diffuse_blue"};
constexpr std::array<const char*, 3> kAlbedo = {"albedo_r", "albedo_g", "albedo_b"};

PlyLayout CheckHeader(const PlyHeader& header, const std::string& name) {
  PlyLayout layout;
  layout.vertex = header.FindIndex("vertex");
  layout.face = header.FindIndex("face");
  if (layout.vertex < 0) throw Error(Format(name, ": the PLY file has no 'vertex' element"));
  if (layout.face >= 0 && layout.face < layout.vertex) {
    throw Error(Format(name,
                       ": the 'face' element comes before the 'vertex' element "
                       "(OpenMesh stops reading after the faces)"));
  }

  // OpenMesh stops after the face element; the elements it reads before must be skippable:
  // unknown elements may hold scalars only (OpenMesh skips one value per property).
  const size_t read_end =
      layout.face >= 0 ? static_cast<size_t>(layout.face) + 1 : header.elements.size();
  for (size_t e = 0; e < read_end; ++e) {
    const PlyElement& element = header.elements[e];
    if (element.name == "vertex" || element.name == "face") continue;
    for (const PlyProperty& p : element.properties) {
      if (p.is_list()) {
        throw Error(Format(name, ": element '", element.name,
                           "' before the faces has the list property '", p.name,
                           "', which OpenMesh cannot skip"));
      }
    }
  }
  // OpenMesh's binary reader knows these list length types only (ASCII ones we declare as int).
  if (header.format == PlyFormat::kBinaryLittleEndian) {
    for (const PlyElement& element : header.elements) {
      for (const PlyProperty& p : element.properties) {
        if (p.is_list() && !(p.count_type == "uchar" || p.count_type == "uint8" ||
                             p.count_type == "uint16" || p.count_type == "int")) {
          throw Error(Format(name, ": list length type '", p.count_type, "' of property '", p.name,
                             "' is not supported by OpenMesh (uchar, uint8, uint16 or int)"));
        }
      }
    }
  }

  const PlyElement& vertex = header.elements[static_cast<size_t>(layout.vertex)];
  if (!HasAllOrNone(vertex, kPosition, name)) {
    throw Error(Format(name, ": the vertex element has no x/y/z properties"));
  }
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "u", "v", "s", "t"})
    RequireFloat(vertex, p, name);
  layout.vertex_normals = HasAllOrNone(vertex, kNormal, name);
  const bool rgb = HasAllOrNone(vertex, kRgb, name);
  const bool diffuse = HasAllOrNone(vertex, kDiffuseRgb, name);
  if (rgb && diffuse) {
    throw Error(
        Format(name, ": the vertex element has both red/green/blue and diffuse_red/green/blue"));
  }
  layout.vertex_rgb = rgb || diffuse;
  for (const char* p :
       {"red", "green", "blue", "diffuse_red", "diffuse_green", "diffuse_blue", "alpha"}) {
    RequireColorType(vertex, p, name);
  }
  layout.vertex_albedo = HasAllOrNone(vertex, kAlbedo, name);
  for (const char* p : kAlbedo) RequireFloat(vertex, p, name);
  RequireSameType(vertex, kAlbedo, name);

  if (layout.face >= 0) {
    const PlyElement& face = header.elements[static_cast<size_t>(layout.face)];
    const int indices = face.FindIndex("vertex_indices");
    const int index = face.FindIndex("vertex_index");
    if (indices >= 0 && index >= 0) {
      throw Error(Format(name, ": the face element has both vertex_indices and vertex_index"));
    }
    layout.face_indices_property = std::max(indices, index);
    if (layout.face_indices_property < 0) {
      throw Error(Format(name, ": the face element has no vertex_indices list"));
    }
    const PlyProperty& list = face.properties[static_cast<size_t>(layout.face_indices_property)];
    if (!list.is_list() || LookupType(list.type)->is_float) {
      throw Error(Format(name, ": face property '", list.name, "' must be a list of integers"));
    }
    // OpenMesh skips the face properties declared before the vertex list (except colours).
    for (int i = 0; i < layout.face_indices_property; ++i) {
      const PlyProperty& p = face.properties[static_cast<size_t>(i)];
      if (p.is_list() || p.name.rfind("albedo_", 0) == 0) {
        throw Error(Format(name, ": face property '", p.name, "' comes before '", list.name,
                           "'; OpenMesh cannot read it there"));
      }
    }
    layout.face_rgb = HasAllOrNone(face, kRgb, name);
    for (const char* p : {"red", "green", "blue", "alpha"}) RequireColorType(face, p, name);
    layout.face_albedo = HasAllOrNone(face, kAlbedo, name);
    for (const char* p : kAlbedo) RequireFloat(face, p, name);
    RequireSameType(face, kAlbedo, name);
  }
  return layout;
}

// ------------------------------------------------------------------------------------------------
// Size check (no allocation) and the walk over the data.

uint64_t SatAdd(uint64_t a, uint64_t b) {
  return a > std::numeric_limits<uint64_t>::max() - b ? std::numeric_limits<uint64_t>::max()
                                                      : a + b;
}
uint64_t SatMul(uint64_t a, uint64_t b) {
  return (b != 0 && a > std::numeric_limits<uint64_t>::max() / b)
             ? std::numeric_limits<uint64_t>::max()
             : a * b;
}

bool IsFaceIndexList(const PlyLayout& layout, size_t element, size_t property) {
  return static_cast<int>(element) == layout.face &&
         static_cast<int>(property) == layout.face_indices_property;
}

std::string DescribeCounts(const PlyHeader& header) {
  std::string text;
  for (size_t e = 0; e < header.elements.size(); ++e) {
    text += Format(e == 0 ? "" : ", ", header.elements[e].count, " ", header.elements[e].name);
  }
  return text.empty() ? "no elements" : text;
}

// The smallest data size the declared element counts can have: binary, every record at its
// minimal size (lists empty); ASCII, one character per value (a list: its length) and one
// separator between values. Anything smaller is certainly truncated or has a corrupt header; the
// exact check (face sizes included) is WalkData's.
void CheckCountsFitInFile(const PlyHeader& header, uint64_t file_size, const std::string& name) {
  const uint64_t available = file_size - header.data_offset;
  uint64_t need = 0;
  for (size_t e = 0; e < header.elements.size(); ++e) {
    const PlyElement& element = header.elements[e];
    uint64_t record = 0;  // binary: bytes; ASCII: values
    for (size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& prop = element.properties[p];
      if (header.format == PlyFormat::kAscii) {
        record += 1;
      } else {
        record += LookupType(prop.is_list() ? prop.count_type : prop.type)->size;
      }
    }
    need = SatAdd(need, SatMul(record, element.count));
  }
  if (header.format == PlyFormat::kAscii && need > 0) need = SatMul(need, 2) - 1;
  if (need > available) {
    throw Error(Format(name, ": truncated file or corrupt header: the header declares ",
                       DescribeCounts(header), " elements, which need at least ", need,
                       " bytes of ", header.format == PlyFormat::kAscii ? "ASCII" : "binary",
                       " data, but only ", available, " bytes follow the header"));
  }
}

// Buffered reading of [begin, end) of a file.
class DataCursor {
 public:
  DataCursor(const fs::path& path, uint64_t begin, uint64_t end)
      : file_(path, std::ios::binary), next_(begin), end_(end), buffer_(size_t{1} << 20) {
    if (!file_) throw Error(Format(path.string(), ": cannot open (", std::strerror(errno), ")"));
  }

  uint64_t offset() const { return next_ - (length_ - pos_); }

  int Get() {
    if (pos_ == length_ && !Fill()) return -1;
    return static_cast<unsigned char>(buffer_[pos_++]);
  }

  bool Read(void* destination, size_t n) {
    char* out = static_cast<char*>(destination);
    while (n > 0) {
      if (pos_ == length_ && !Fill()) return false;
      const size_t k = std::min(n, length_ - pos_);
      std::memcpy(out, buffer_.data() + pos_, k);
      pos_ += k;
      out += k;
      n -= k;
    }
    return true;
  }

  bool Skip(uint64_t n) {
    if (n <= length_ - pos_) {
      pos_ += static_cast<size_t>(n);
      return true;
    }
    n -= length_ - pos_;
    pos_ = length_ = 0;
    if (n > end_ - next_) return false;
    next_ += n;
    return true;
  }

  // ASCII: the next whitespace-separated token (at most 64 characters kept); false at the end.
  bool NextToken(std::string* token) {
    int c = Get();
    while (c >= 0 && std::isspace(c)) c = Get();
    if (c < 0) return false;
    if (token) token->clear();
    while (c >= 0 && !std::isspace(c)) {
      if (token && token->size() < 64) token->push_back(static_cast<char>(c));
      c = Get();
    }
    return true;
  }

 private:
  bool Fill() {
    if (next_ >= end_) return false;
    const size_t n = static_cast<size_t>(std::min<uint64_t>(buffer_.size(), end_ - next_));
    file_.seekg(static_cast<std::streamoff>(next_));
    file_.read(buffer_.data(), static_cast<std::streamsize>(n));
    length_ = static_cast<size_t>(file_.gcount());
    pos_ = 0;
    next_ += length_;
    return length_ > 0;
  }

  std::ifstream file_;
  uint64_t next_;  // file offset of the byte after the buffer
  uint64_t end_;
  std::vector<char> buffer_;
  size_t pos_ = 0;
  size_t length_ = 0;
};

bool IsSignedType(const std::string& type) {
  return type == "char" || type == "int8" || type == "short" || type == "int16" || type == "int" ||
         type == "int32";
}

int64_t DecodeLittleEndianInteger(const unsigned char* bytes, int size, bool is_signed) {
  uint64_t u = 0;
  for (int i = size - 1; i >= 0; --i) u = (u << 8) | bytes[i];
  if (is_signed && size < 8 && (u >> (8 * size - 1)) != 0) {
    return static_cast<int64_t>(u) - (int64_t{1} << (8 * size));
  }
  return static_cast<int64_t>(u);
}

// Walks every record of the elements OpenMesh will read, list lengths included, so that a
// truncated or inconsistent file is an Error before OpenMesh sees it (OpenMesh would read a
// corrupt list length of 4e9 as 4e9 indices).
void WalkData(const fs::path& path, const PlyHeader& header, const PlyLayout& layout,
              uint64_t file_size) {
  struct Field {
    bool list = false;
    int size = 0;  // binary: a scalar's size, or a list entry's size
    int count_size = 0;
    bool count_signed = false;
    bool face_indices = false;
  };
  const std::string name = path.string();
  const bool ascii = header.format == PlyFormat::kAscii;
  DataCursor cursor(path, header.data_offset, file_size);
  const size_t read_end =
      layout.face >= 0 ? static_cast<size_t>(layout.face) + 1 : header.elements.size();
  std::string token;
  for (size_t e = 0; e < read_end; ++e) {
    const PlyElement& element = header.elements[e];
    auto truncated = [&](uint64_t record) {
      return Error(Format(name, ": truncated or corrupt PLY data: it ends in ", element.name, " ",
                          record, " of ", element.count));
    };
    std::vector<Field> fields;
    bool has_list = false;
    uint64_t record_bytes = 0;
    for (size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& prop = element.properties[p];
      Field field;
      field.list = prop.is_list();
      field.size = LookupType(prop.type)->size;
      if (field.list) {
        field.count_size = LookupType(prop.count_type)->size;
        field.count_signed = IsSignedType(prop.count_type);
        field.face_indices = IsFaceIndexList(layout, e, p);
      }
      has_list = has_list || field.list;
      record_bytes += static_cast<uint64_t>(field.size);
      fields.push_back(field);
    }
    if (!ascii && !has_list) {
      const uint64_t start = cursor.offset();
      if (!cursor.Skip(SatMul(record_bytes, element.count))) {
        throw truncated(record_bytes == 0 ? 0 : (file_size - start) / record_bytes);
      }
      continue;
    }
    for (uint64_t r = 0; r < element.count; ++r) {
      for (size_t p = 0; p < fields.size(); ++p) {
        const Field& field = fields[p];
        if (!field.list) {
          if (ascii ? !cursor.NextToken(nullptr)
                    : !cursor.Skip(static_cast<uint64_t>(field.size))) {
            throw truncated(r);
          }
          continue;
        }
        int64_t length = 0;
        if (ascii) {
          if (!cursor.NextToken(&token)) throw truncated(r);
          const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), length);
          if (ec != std::errc() || ptr != token.data() + token.size()) {
            throw Error(Format(name, ": ", element.name, " ", r, ": list length '", token,
                               "' of property ", element.properties[p].name, " is not an integer"));
          }
        } else {
          unsigned char bytes[8] = {};
          if (!cursor.Read(bytes, static_cast<size_t>(field.count_size))) throw truncated(r);
          length = DecodeLittleEndianInteger(bytes, field.count_size, field.count_signed);
        }
        if (length < 0) {
          throw Error(Format(name, ": ", element.name, " ", r, ": negative list length ", length,
                             " of property ", element.properties[p].name));
        }
        if (field.face_indices && length < 3) {
          throw Error(
              Format(name, ": face ", r, " has ", length, " vertices; at least 3 are needed"));
        }
        if (ascii) {
          for (int64_t k = 0; k < length; ++k) {
            if (!cursor.NextToken(nullptr)) throw truncated(r);
          }
        } else if (!cursor.Skip(
                       SatMul(static_cast<uint64_t>(length), static_cast<uint64_t>(field.size)))) {
          throw truncated(r);
        }
      }
    }
  }
}

// The header we hand to OpenMesh: no comments, one space between tokens, "end_header\n" right
// after the last property line (where OpenMesh's seek expects it). In ASCII files 8-bit types and
// list lengths are declared as int: the text reads the same, and OpenMesh then parses numbers
// instead of single characters.
std::string CanonicalHeader(const PlyHeader& header) {
  const bool ascii = header.format == PlyFormat::kAscii;
  auto type = [&](const std::string& t) { return ascii && IsEightBit(t) ? std::string("int") : t; };
  std::string text = "ply\n";
  text += ascii ? "format ascii 1.0\n" : "format binary_little_endian 1.0\n";
  for (const PlyElement& element : header.elements) {
    text += Format("element ", element.name, " ", element.count, "\n");
    for (const PlyProperty& p : element.properties) {
      if (p.is_list()) {
        text += Format("property list ", ascii ? std::string("int") : p.count_type, " ",
                       type(p.type), " ", p.name, "\n");
      } else {
        text += Format("property ", type(p.type), " ", p.name, "\n");
      }
    }
  }
  text += "end_header\n";
  return text;
}

// A seekable read-only stream buffer over `prefix`, then bytes [begin, end) of a file, then
// `suffix`: the canonical header followed by the file's own data, without copying the data.
class SplicedFileBuf : public std::streambuf {
 public:
  SplicedFileBuf(std::string prefix, const fs::path& path, uint64_t begin, uint64_t end,
                 std::string suffix)
      : prefix_(std::move(prefix)),
        suffix_(std::move(suffix)),
        file_(path, std::ios::binary),
        begin_(begin),
        body_size_(end - begin),
        buffer_(size_t{1} << 16) {
    if (!file_) throw Error(Format(path.string(), ": cannot open (", std::strerror(errno), ")"));
    setg(buffer_.data(), buffer_.data(), buffer_.data());
  }

 protected:
  int_type underflow() override {
    if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
    position_ += static_cast<uint64_t>(egptr() - eback());
    const size_t n = Load(position_);
    setg(buffer_.data(), buffer_.data(), buffer_.data() + n);
    return n == 0 ? traits_type::eof() : traits_type::to_int_type(*gptr());
  }

  pos_type seekoff(off_type off, std::ios_base::seekdir dir,
                   std::ios_base::openmode which) override {
    if (!(which & std::ios_base::in)) return pos_type(off_type(-1));
    const int64_t current = static_cast<int64_t>(position_) + (gptr() - eback());
    const int64_t base = dir == std::ios_base::beg   ? 0
                         : dir == std::ios_base::cur ? current
                                                     : static_cast<int64_t>(Total());
    const int64_t target = base + off;
    if (target < 0 || static_cast<uint64_t>(target) > Total()) return pos_type(off_type(-1));
    const int64_t in_buffer = target - static_cast<int64_t>(position_);
    if (in_buffer >= 0 && in_buffer <= egptr() - eback()) {
      setg(eback(), eback() + in_buffer, egptr());
    } else {
      position_ = static_cast<uint64_t>(target);
      setg(buffer_.data(), buffer_.data(), buffer_.data());
    }
    return pos_type(target);
  }

  pos_type seekpos(pos_type pos, std::ios_base::openmode which) override {
    return seekoff(off_type(pos), std::ios_base::beg, which);
  }

 private:
  uint64_t Total() const { return prefix_.size() + body_size_ + suffix_.size(); }

  // Fills the buffer from logical position `at`; returns the number of bytes.
  size_t Load(uint64_t at) {
    size_t filled = 0;
    while (filled < buffer_.size() && at < Total()) {
      const size_t room = buffer_.size() - filled;
      size_t n = 0;
      if (at < prefix_.size()) {
        n = std::min<size_t>(room, prefix_.size() - at);
        std::memcpy(buffer_.data() + filled, prefix_.data() + at, n);
      } else if (at < prefix_.size() + body_size_) {
        const uint64_t in_body = at - prefix_.size();
        n = static_cast<size_t>(std::min<uint64_t>(room, body_size_ - in_body));
        file_.clear();
        file_.seekg(static_cast<std::streamoff>(begin_ + in_body));
        file_.read(buffer_.data() + filled, static_cast<std::streamsize>(n));
        n = static_cast<size_t>(std::max<std::streamsize>(file_.gcount(), 0));
        if (n == 0) break;  // the file shrank under us: report the end
      } else {
        const uint64_t in_suffix = at - prefix_.size() - body_size_;
        n = std::min<size_t>(room, suffix_.size() - in_suffix);
        std::memcpy(buffer_.data() + filled, suffix_.data() + in_suffix, n);
      }
      filled += n;
      at += n;
    }
    return filled;
  }

  std::string prefix_;
  std::string suffix_;
  std::ifstream file_;
  uint64_t begin_;
  uint64_t body_size_;
  std::vector<char> buffer_;
  uint64_t position_ = 0;  // logical position of eback()
};

// ------------------------------------------------------------------------------------------------
// OpenMesh adapters.

std::mutex& OpenMeshMutex() {
  static std::mutex mutex;
  return mutex;
}

// Silences OpenMesh's log streams for the life of the object (restores their previous state).
class QuietOpenMesh {
 public:
  QuietOpenMesh()
      : err_(omerr().is_enabled()), log_(omlog().is_enabled()), out_(omout().is_enabled()) {
    omerr().disable();
    omlog().disable();
    omout().disable();
  }
  ~QuietOpenMesh() {
    if (err_) omerr().enable();
    if (log_) omlog().enable();
    if (out_) omout().enable();
  }
  QuietOpenMesh(const QuietOpenMesh&) = delete;
  QuietOpenMesh& operator=(const QuietOpenMesh&) = delete;

 private:
  bool err_, log_, out_;
};

// Holds the named (custom) properties OpenMesh's PLY reader and writer use, for a mesh of
// n_vertices / n_faces elements without connectivity.
class PropertyKernel final : public OpenMesh::BaseKernel {
 public:
  size_t n_vertices() const override { return n_vertices_; }
  size_t n_faces() const override { return n_faces_; }
  void Reserve(size_t vertices, size_t faces) {
    vprops_reserve(vertices);
    fprops_reserve(faces);
  }
  void SetVertexCount(size_t n) {
    n_vertices_ = n;
    vprops_resize(n);
  }
  void SetFaceCount(size_t n) {
    n_faces_ = n;
    fprops_resize(n);
  }

 private:
  size_t n_vertices_ = 0;
  size_t n_faces_ = 0;
};

// Reads the three float or double properties `names` of every element of one kind; false when
// the kernel does not have them.
template <template <typename> class PropHandle, typename ElementHandle, typename T>
bool ReadChannels(const OpenMesh::BaseKernel& kernel, const std::array<const char*, 3>& names,
                  size_t n, std::vector<Eigen::Vector3f>* out) {
  PropHandle<T> handles[3];
  for (int c = 0; c < 3; ++c) {
    if (!kernel.get_property_handle(handles[c], names[static_cast<size_t>(c)])) return false;
  }
  out->resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      (*out)[i][c] =
          static_cast<float>(kernel.property(handles[c], ElementHandle(static_cast<int>(i))));
    }
  }
  return true;
}

template <template <typename> class PropHandle, typename ElementHandle>
bool ReadFloatChannels(const OpenMesh::BaseKernel& kernel, const std::array<const char*, 3>& names,
                       size_t n, std::vector<Eigen::Vector3f>* out) {
  return ReadChannels<PropHandle, ElementHandle, float>(kernel, names, n, out) ||
         ReadChannels<PropHandle, ElementHandle, double>(kernel, names, n, out);
}

Eigen::Vector3f SrgbBytesToLinear(const OpenMesh::Vec3uc& c) {
  return {SrgbToLinear(c[0] / 255.0f), SrgbToLinear(c[1] / 255.0f), SrgbToLinear(c[2] / 255.0f)};
}

// Receives what OpenMesh's PLY reader parses, exactly as the file has it: no connectivity, no
// duplicated vertices, no dropped faces. Problems are recorded, not thrown, because OpenMesh's
// reader must not be unwound mid-read (it toggles global log state).
class CollectingImporter final : public OpenMesh::IO::BaseImporter {
 public:
  using BaseImporter::add_vertex;
  CollectingImporter(size_t file_vertices, size_t file_faces, const PlyLayout& layout)
      : file_vertices_(file_vertices), layout_(layout) {
    first_triangle_.reserve(file_faces + 1);
    first_triangle_.push_back(0);
  }

  const std::string& problem() const { return problem_; }
  size_t polygon_count() const { return first_triangle_.size() - 1; }

  TriangleMesh Build(const std::string& name) {
    TriangleMesh mesh;
    const size_t nv = positions_.size();
    mesh.vertices = std::move(positions_);
    if (layout_.vertex_normals) mesh.normals = std::move(normals_);
    if (layout_.vertex_albedo) {
      if (!ReadFloatChannels<OpenMesh::VPropHandleT, VertexHandle>(kernel_, kAlbedo, nv,
                                                                   &mesh.vertex_colors) &&
          nv > 0) {
        throw Error(Format(name, ": OpenMesh did not deliver the vertex albedo_r/g/b properties"));
      }
    } else if (layout_.vertex_rgb) {
      mesh.vertex_colors.resize(nv);
      for (size_t i = 0; i < nv; ++i) mesh.vertex_colors[i] = SrgbBytesToLinear(vertex_rgb_[i]);
    }
    mesh.faces = std::move(triangles_);
    const size_t polygons = polygon_count();
    std::vector<Eigen::Vector3f> polygon_colors;
    if (layout_.face_albedo) {
      if (!ReadFloatChannels<OpenMesh::FPropHandleT, FaceHandle>(kernel_, kAlbedo, polygons,
                                                                 &polygon_colors) &&
          polygons > 0) {
        throw Error(Format(name, ": OpenMesh did not deliver the face albedo_r/g/b properties"));
      }
    } else if (layout_.face_rgb) {
      polygon_colors.resize(polygons);
      for (size_t f = 0; f < polygons; ++f) polygon_colors[f] = SrgbBytesToLinear(face_rgb_[f]);
    }
    if (layout_.face_albedo || layout_.face_rgb) {
      mesh.face_colors.resize(mesh.faces.size());
      for (size_t f = 0; f < polygons; ++f) {
        for (size_t t = first_triangle_[f]; t < first_triangle_[f + 1]; ++t)
          mesh.face_colors[t] = polygon_colors[f];
      }
    }
    return mesh;
  }

  // --- what the PLY reader calls.
  VertexHandle add_vertex(const OpenMesh::Vec3f& point) override {
    const VertexHandle vh = add_vertex();
    set_point(vh, point);
    return vh;
  }
  VertexHandle add_vertex() override {
    positions_.emplace_back(0.0f, 0.0f, 0.0f);
    if (layout_.vertex_normals) normals_.emplace_back(0.0f, 0.0f, 0.0f);
    if (layout_.vertex_rgb) vertex_rgb_.emplace_back(0, 0, 0);
    kernel_.SetVertexCount(positions_.size());
    return VertexHandle(static_cast<int>(positions_.size() - 1));
  }
  FaceHandle add_face(const VHandles& indices) override {
    const size_t polygon = polygon_count();
    if (indices.size() < 3) Note(Format("face ", polygon, " has ", indices.size(), " vertices"));
    for (const VertexHandle& vh : indices) {
      if (vh.idx() < 0 || static_cast<size_t>(vh.idx()) >= file_vertices_) {
        Note(Format("face ", polygon, " uses vertex ", vh.idx(), " but the file has ",
                    file_vertices_, " vertices"));
      }
    }
    for (size_t k = 1; k + 1 < indices.size(); ++k) {  // fan triangulation
      triangles_.emplace_back(indices[0].idx(), indices[k].idx(), indices[k + 1].idx());
    }
    first_triangle_.push_back(triangles_.size());
    if (layout_.face_rgb) face_rgb_.emplace_back(0, 0, 0);
    kernel_.SetFaceCount(polygon + 1);
    return FaceHandle(static_cast<int>(polygon));
  }
  void set_point(VertexHandle vh, const OpenMesh::Vec3f& p) override {
    if (ValidVertex(vh)) positions_[Index(vh)] = Eigen::Vector3f(p[0], p[1], p[2]);
  }
  void set_normal(VertexHandle vh, const OpenMesh::Vec3f& n) override {
    if (layout_.vertex_normals && ValidVertex(vh))
      normals_[Index(vh)] = Eigen::Vector3f(n[0], n[1], n[2]);
  }
  void set_normal(VertexHandle vh, const OpenMesh::Vec3d& n) override {
    set_normal(vh, OpenMesh::Vec3f(static_cast<float>(n[0]), static_cast<float>(n[1]),
                                   static_cast<float>(n[2])));
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec4uc& c) override {
    if (layout_.vertex_rgb && ValidVertex(vh))
      vertex_rgb_[Index(vh)] = OpenMesh::Vec3uc(c[0], c[1], c[2]);
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec3uc& c) override {
    set_color(vh, OpenMesh::Vec4uc(c[0], c[1], c[2], 255));
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec3f& c) override {
    set_color(vh, ToBytes(c[0], c[1], c[2]));
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec4f& c) override {
    set_color(vh, ToBytes(c[0], c[1], c[2]));
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec4uc& c) override {
    if (layout_.face_rgb && fh.idx() >= 0 && static_cast<size_t>(fh.idx()) < face_rgb_.size()) {
      face_rgb_[static_cast<size_t>(fh.idx())] = OpenMesh::Vec3uc(c[0], c[1], c[2]);
    }
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec3uc& c) override {
    set_color(fh, OpenMesh::Vec4uc(c[0], c[1], c[2], 255));
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec3f& c) override {
    set_color(fh, ToBytes(c[0], c[1], c[2]));
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec4f& c) override {
    set_color(fh, ToBytes(c[0], c[1], c[2]));
  }
  OpenMesh::BaseKernel* kernel() override { return &kernel_; }
  void reserve(unsigned int vertices, unsigned int /*edges*/, unsigned int faces) override {
    // The counts come from a header already checked against the file size.
    positions_.reserve(vertices);
    if (layout_.vertex_normals) normals_.reserve(vertices);
    if (layout_.vertex_rgb) vertex_rgb_.reserve(vertices);
    if (layout_.face_rgb) face_rgb_.reserve(faces);
    triangles_.reserve(faces);
    kernel_.Reserve(vertices, faces);
  }
  size_t n_vertices() const override { return positions_.size(); }
  size_t n_faces() const override { return polygon_count(); }
  size_t n_edges() const override { return 0; }

  // --- not used by the PLY reader (connectivity, texture coordinates, status, edges).
  HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
  FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<OpenMesh::Vec2f>&) override {}
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<OpenMesh::Vec3f>&) override {}
  void set_face_texindex(FaceHandle, int) override {}
  void set_halfedge(VertexHandle, HalfedgeHandle) override {}
  void set_texcoord(VertexHandle, const OpenMesh::Vec2f&) override {}
  void set_texcoord(HalfedgeHandle, const OpenMesh::Vec2f&) override {}
  void set_texcoord(VertexHandle, const OpenMesh::Vec3f&) override {}
  void set_texcoord(HalfedgeHandle, const OpenMesh::Vec3f&) override {}
  void set_status(VertexHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_status(HalfedgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_status(EdgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_status(FaceHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_next(HalfedgeHandle, HalfedgeHandle) override {}
  void set_face(HalfedgeHandle, FaceHandle) override {}
  void request_face_texcoords2D() override {}
  void set_color(EdgeHandle, const OpenMesh::Vec3uc&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec4uc&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec3f&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec4f&) override {}
  void set_normal(FaceHandle, const OpenMesh::Vec3f&) override {}
  void set_normal(FaceHandle, const OpenMesh::Vec3d&) override {}
  void add_texture_information(int, std::string) override {}

 private:
  static OpenMesh::Vec4uc ToBytes(float r, float g, float b) {
    auto byte = [](float v) {
      return static_cast<unsigned char>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
    };
    return OpenMesh::Vec4uc(byte(r), byte(g), byte(b), 255);
  }
  bool ValidVertex(VertexHandle vh) const {
    return vh.idx() >= 0 && static_cast<size_t>(vh.idx()) < positions_.size();
  }
  static size_t Index(VertexHandle vh) { return static_cast<size_t>(vh.idx()); }
  void Note(const std::string& problem) {
    if (problem_.empty()) problem_ = problem;
  }

  size_t file_vertices_;
  PlyLayout layout_;
  std::string problem_;
  std::vector<Eigen::Vector3f> positions_;
  std::vector<Eigen::Vector3f> normals_;
  std::vector<OpenMesh::Vec3uc> vertex_rgb_;
  std::vector<Eigen::Vector3i> triangles_;
  std::vector<size_t>
      first_triangle_;  // polygon f -> triangles [first_triangle_[f], first_triangle_[f+1])
  std::vector<OpenMesh::Vec3uc> face_rgb_;
  PropertyKernel kernel_;
};

unsigned char LinearToSrgbByte(float linear) {
  return static_cast<unsigned char>(
      std::lround(LinearToSrgb(std::clamp(linear, 0.0f, 1.0f)) * 255.0f));
}

// Presents a TriangleMesh to OpenMesh's PLY writer as it is: vertices and triangles in order,
// colours as sRGB bytes, and the exact linear face colours as persistent float face properties
// albedo_r/g/b of a property kernel (written by OpenMesh as `property float albedo_r` ...).
class TriangleMeshExporter final : public OpenMesh::IO::BaseExporter {
 public:
  explicit TriangleMeshExporter(const TriangleMesh& mesh) : mesh_(mesh) {
    vertex_rgb_.reserve(mesh.vertex_colors.size());
    for (const Eigen::Vector3f& c : mesh.vertex_colors) {
      vertex_rgb_.emplace_back(LinearToSrgbByte(c[0]), LinearToSrgbByte(c[1]),
                               LinearToSrgbByte(c[2]));
    }
    face_rgb_.reserve(mesh.face_colors.size());
    for (const Eigen::Vector3f& c : mesh.face_colors) {
      face_rgb_.emplace_back(LinearToSrgbByte(c[0]), LinearToSrgbByte(c[1]),
                             LinearToSrgbByte(c[2]));
    }
    kernel_.SetVertexCount(mesh.vertices.size());
    kernel_.SetFaceCount(mesh.faces.size());
    if (!mesh.face_colors.empty()) {
      for (int c = 0; c < 3; ++c) {
        OpenMesh::FPropHandleT<float> handle;
        kernel_.add_property(handle, kAlbedo[static_cast<size_t>(c)]);
        kernel_.property(handle).set_persistent(true);
        for (size_t f = 0; f < mesh.faces.size(); ++f) {
          kernel_.property(handle, FaceHandle(static_cast<int>(f))) = mesh.face_colors[f][c];
        }
      }
    }
  }

  OpenMesh::Vec3f point(VertexHandle vh) const override { return ToOm(mesh_.vertices[Index(vh)]); }
  OpenMesh::Vec3d pointd(VertexHandle vh) const override { return OpenMesh::Vec3d(point(vh)); }
  bool is_point_double() const override { return false; }
  OpenMesh::Vec3f normal(VertexHandle vh) const override { return ToOm(mesh_.normals[Index(vh)]); }
  OpenMesh::Vec3d normald(VertexHandle vh) const override { return OpenMesh::Vec3d(normal(vh)); }
  bool is_normal_double() const override { return false; }
  OpenMesh::Vec3uc color(VertexHandle vh) const override { return vertex_rgb_[Index(vh)]; }
  OpenMesh::Vec4uc colorA(VertexHandle vh) const override { return WithAlpha(color(vh)); }
  OpenMesh::Vec3ui colori(VertexHandle vh) const override { return ToUi(color(vh)); }
  OpenMesh::Vec4ui colorAi(VertexHandle vh) const override { return ToUiA(color(vh)); }
  OpenMesh::Vec3f colorf(VertexHandle vh) const override { return ToF(color(vh)); }
  OpenMesh::Vec4f colorAf(VertexHandle vh) const override { return ToFA(color(vh)); }
  OpenMesh::Vec2f texcoord(VertexHandle) const override { return OpenMesh::Vec2f(0.0f, 0.0f); }
  OpenMesh::Vec2f texcoord(HalfedgeHandle) const override { return OpenMesh::Vec2f(0.0f, 0.0f); }
  OpenMesh::Attributes::StatusInfo status(VertexHandle) const override { return {}; }

  unsigned int get_vhandles(FaceHandle fh, std::vector<VertexHandle>& handles) const override {
    const Eigen::Vector3i& f = mesh_.faces[static_cast<size_t>(fh.idx())];
    handles = {VertexHandle(f[0]), VertexHandle(f[1]), VertexHandle(f[2])};
    return 3;
  }
  HalfedgeHandle getHeh(FaceHandle, VertexHandle) const override { return HalfedgeHandle(); }
  unsigned int get_face_texcoords(std::vector<OpenMesh::Vec2f>& texcoords) const override {
    texcoords.clear();
    return 0;
  }
  OpenMesh::Vec3f normal(FaceHandle fh) const override {
    return ToOm(mesh_.FaceNormalScaled(static_cast<size_t>(fh.idx())).normalized());
  }
  OpenMesh::Vec3d normald(FaceHandle fh) const override { return OpenMesh::Vec3d(normal(fh)); }
  OpenMesh::Vec3uc color(FaceHandle fh) const override {
    return face_rgb_[static_cast<size_t>(fh.idx())];
  }
  OpenMesh::Vec4uc colorA(FaceHandle fh) const override { return WithAlpha(color(fh)); }
  OpenMesh::Vec3ui colori(FaceHandle fh) const override { return ToUi(color(fh)); }
  OpenMesh::Vec4ui colorAi(FaceHandle fh) const override { return ToUiA(color(fh)); }
  OpenMesh::Vec3f colorf(FaceHandle fh) const override { return ToF(color(fh)); }
  OpenMesh::Vec4f colorAf(FaceHandle fh) const override { return ToFA(color(fh)); }
  OpenMesh::Attributes::StatusInfo status(FaceHandle) const override { return {}; }

  OpenMesh::Vec3uc color(EdgeHandle) const override { return OpenMesh::Vec3uc(0, 0, 0); }
  OpenMesh::Vec4uc colorA(EdgeHandle) const override { return OpenMesh::Vec4uc(0, 0, 0, 255); }
  OpenMesh::Vec3ui colori(EdgeHandle) const override { return OpenMesh::Vec3ui(0, 0, 0); }
  OpenMesh::Vec4ui colorAi(EdgeHandle) const override { return OpenMesh::Vec4ui(0, 0, 0, 255); }
  OpenMesh::Vec3f colorf(EdgeHandle) const override { return OpenMesh::Vec3f(0.0f, 0.0f, 0.0f); }
  OpenMesh::Vec4f colorAf(EdgeHandle) const override {
    return OpenMesh::Vec4f(0.0f, 0.0f, 0.0f, 1.0f);
  }
  OpenMesh::Attributes::StatusInfo status(EdgeHandle) const override { return {}; }

  int get_halfedge_id(VertexHandle) override { return -1; }
  int get_halfedge_id(FaceHandle) override { return -1; }
  int get_next_halfedge_id(HalfedgeHandle) override { return -1; }
  int get_to_vertex_id(HalfedgeHandle) override { return -1; }
  int get_face_id(HalfedgeHandle) override { return -1; }
  OpenMesh::Attributes::StatusInfo status(HalfedgeHandle) const override { return {}; }

  const OpenMesh::BaseKernel* kernel() override { return &kernel_; }
  size_t n_vertices() const override { return mesh_.vertices.size(); }
  size_t n_faces() const override { return mesh_.faces.size(); }
  size_t n_edges() const override { return 0; }
  bool is_triangle_mesh() const override { return true; }
  bool has_vertex_normals() const override { return !mesh_.normals.empty(); }
  bool has_vertex_colors() const override { return !mesh_.vertex_colors.empty(); }
  bool has_face_colors() const override { return !mesh_.face_colors.empty(); }

 private:
  static size_t Index(VertexHandle vh) { return static_cast<size_t>(vh.idx()); }
  static OpenMesh::Vec3f ToOm(const Eigen::Vector3f& v) {
    return OpenMesh::Vec3f(v[0], v[1], v[2]);
  }
  static OpenMesh::Vec4uc WithAlpha(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec4uc(c[0], c[1], c[2], 255);
  }
  static OpenMesh::Vec3ui ToUi(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec3ui(c[0], c[1], c[2]);
  }
  static OpenMesh::Vec4ui ToUiA(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec4ui(c[0], c[1], c[2], 255);
  }
  static OpenMesh::Vec3f ToF(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec3f(c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f);
  }
  static OpenMesh::Vec4f ToFA(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec4f(c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f, 1.0f);
  }

  const TriangleMesh& mesh_;
  std::vector<OpenMesh::Vec3uc> vertex_rgb_;
  std::vector<OpenMesh::Vec3uc> face_rgb_;
  PropertyKernel kernel_;
};

// Vertex colours are stored only as 8-bit sRGB, so they must be in [0, 1]; face colours are stored
// exactly as float albedo_r/g/b (their 8-bit red/green/blue copy, for viewers, is clamped).
void CheckColorsWritable(const TriangleMesh& mesh, const std::string& name) {
  for (size_t i = 0; i < mesh.vertex_colors.size(); ++i) {
    const Eigen::Vector3f& c = mesh.vertex_colors[i];
    if (!c.allFinite() || c.minCoeff() < 0.0f || c.maxCoeff() > 1.0f) {
      throw Error(Format(name, ": vertex colour ", i, " is (", c[0], ", ", c[1], ", ", c[2],
                         "), outside [0, 1]; PLY vertex colours are 8-bit"));
    }
  }
  for (size_t f = 0; f < mesh.face_colors.size(); ++f) {
    if (!mesh.face_colors[f].allFinite())
      throw Error(Format(name, ": face colour ", f, " is not finite"));
  }
}

}  // namespace

TriangleMesh ReadPly(const fs::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(Format(name, ": file not found"));
  if (fs::is_directory(path, ec)) throw Error(Format(name, ": is a folder, not a PLY file"));
  const uint64_t file_size = fs::file_size(path, ec);
  if (ec) throw Error(Format(name, ": cannot read the file size (", ec.message(), ")"));
  if (file_size == 0) throw Error(Format(name, ": empty file, not a PLY mesh"));

  const PlyHeader header = ParseHeader(path, file_size);
  const PlyLayout layout = CheckHeader(header, name);
  CheckCountsFitInFile(header, file_size, name);
  WalkData(path, header, layout, file_size);

  const size_t file_vertices = header.elements[static_cast<size_t>(layout.vertex)].count;
  const size_t file_faces =
      layout.face >= 0 ? header.elements[static_cast<size_t>(layout.face)].count : 0;
  CollectingImporter importer(file_vertices, file_faces, layout);
  // ASCII: a final newline so that a file without one still parses (OpenMesh treats end of file
  // before the last element as an error).
  SplicedFileBuf buffer(CanonicalHeader(header), path, header.data_offset, file_size,
                        header.format == PlyFormat::kAscii ? "\n" : "");
  std::istream stream(&buffer);
  OpenMesh::IO::Options options = OpenMesh::IO::Options::VertexNormal |
                                  OpenMesh::IO::Options::VertexColor |
                                  OpenMesh::IO::Options::FaceColor | OpenMesh::IO::Options::Custom;
  bool ok = false;
  {
    std::lock_guard<std::mutex> lock(OpenMeshMutex());
    QuietOpenMesh quiet;
    ok = OpenMesh::IO::IOManager().read(stream, "ply", importer, options);
  }
  if (!ok) throw Error(Format(name, ": OpenMesh could not read the PLY data (corrupt file?)"));
  if (stream.fail()) {
    throw Error(Format(
        name, ": malformed PLY data (a value that is not a number, or a file that ends early)"));
  }
  if (!importer.problem().empty()) throw Error(Format(name, ": ", importer.problem()));
  if (importer.n_vertices() != file_vertices) {
    throw Error(Format(name, ": read ", importer.n_vertices(), " vertices but the header declares ",
                       file_vertices));
  }
  if (importer.polygon_count() != file_faces) {
    throw Error(Format(name, ": read ", importer.polygon_count(), " faces but the header declares ",
                       file_faces));
  }
  TriangleMesh mesh = importer.Build(name);
  mesh.Validate(name);
  return mesh;
}

void WritePly(const fs::path& path, const TriangleMesh& mesh, const PlyWriteOptions& options) {
  const std::string name = path.string();
  mesh.Validate(name);
  CheckColorsWritable(mesh, name);
  TriangleMeshExporter exporter(mesh);
  OpenMesh::IO::Options om_options = OpenMesh::IO::Options::Default;
  if (options.binary) om_options += OpenMesh::IO::Options::Binary;
  if (!mesh.normals.empty()) om_options += OpenMesh::IO::Options::VertexNormal;
  if (!mesh.vertex_colors.empty()) om_options += OpenMesh::IO::Options::VertexColor;
  if (!mesh.face_colors.empty()) om_options += OpenMesh::IO::Options::FaceColor;

  WriteFileAtomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out)
      throw Error(Format(name, ": cannot write ", tmp.string(), " (", std::strerror(errno), ")"));
    bool ok = false;
    {
      std::lock_guard<std::mutex> lock(OpenMeshMutex());
      QuietOpenMesh quiet;
      // Precision 9 = std::numeric_limits<float>::max_digits10: ASCII floats read back exactly.
      ok = OpenMesh::IO::IOManager().write(out, "ply", exporter, om_options, 9);
    }
    if (!ok) throw Error(Format(name, ": OpenMesh's PLY writer failed"));
    out.close();
    if (!out) throw Error(Format(name, ": write failed (disk full?)"));
  });
}

}  // namespace genscene
