// PLY mesh I/O: the reader decodes the data itself in one pass after the header checks of
// core/ply_format.h; the writer writes the header and the records by hand.
//
// Reading. Every element up to the later of `vertex` and `face` is walked record by record, each
// value decoded (binary little-endian) or tokenised and parsed (ASCII: whitespace-separated
// tokens, line breaks carry no meaning). Values of properties ReadPly does not use are checked
// and skipped. Elements after the vertices and faces are not read (their size is part of
// CheckCountsFitInFile only).
// - Exactly the file's vertices and faces, in file order: no connectivity is built, so a
//   non-manifold mesh or a face with a repeated vertex (a degenerate triangle) reads as it is.
// - Polygons are fan-triangulated: (v0, v1, ..., vn-1) becomes the triangles (v0, vk, vk+1),
//   k = 1 .. n-2, in that order, each with the polygon's colour.
// - Colours: float albedo_r/g/b (linear) are preferred; otherwise red/green/blue (or
//   diffuse_red/green/blue for vertices) are sRGB 8-bit values (8-bit integers, or floats in
//   [0, 1] scaled to 8 bits), converted to linear.
// - Errors, each naming the file: a file that ends inside a record ("truncated or corrupt PLY
//   data: it ends in <element> <i> of <n>"), an ASCII value that is not an integer (integer
//   types) or not a finite number (float types), a negative list length, a face with fewer than
//   3 corners, an ASCII value of more than 1024 characters. A corner index outside the vertices is
//   reported after the walk, so that a structural problem anywhere in the file comes first;
//   non-finite binary positions and normals are reported by TriangleMesh::Validate. Binary NaN or
//   infinite albedo values are read as they are.
//
// Writing: binary little-endian or ASCII, floats printed with 9 significant digits (they read
// back exactly), through a temporary file renamed into place.
#include "core/ply_io.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <system_error>
#include <vector>

#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"
#include "core/ply_format.h"

namespace genscene {

namespace {

namespace fs = std::filesystem;
using ply::DataCursor;
using ply::PlyElement;
using ply::PlyHeader;
using ply::PlyLayout;
using ply::PlyProperty;
using ply::PlyType;

// ------------------------------------------------------------------------------------------------
// Reading.

// Where a decoded scalar goes; kSkip: checked, then dropped.
enum Slot : int { kSkip = -1, kX, kY, kZ, kNx, kNy, kNz, kRed, kGreen, kBlue, kAlbR, kAlbG, kAlbB };
constexpr int kSlotCount = kAlbB + 1;

struct Field {
  const PlyProperty* property = nullptr;
  int slot = kSkip;
  bool corners = false;  // the face's vertex index list
};

uint64_t LoadLittleEndian(const unsigned char* bytes, int size) {
  uint64_t u = 0;
  for (int i = size - 1; i >= 0; --i) u = (u << 8) | bytes[i];
  return u;
}

bool ParseInteger64(const std::string& token, int64_t* value) {
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, *value);
  return ec == std::errc() && ptr == end;
}

class PlyDecoder {
 public:
  PlyDecoder(const fs::path& path, const PlyHeader& header, const PlyLayout& layout,
             uint64_t file_size)
      : name_(path.string()),
        header_(header),
        layout_(layout),
        ascii_(header.format == ply::PlyFormat::kAscii),
        cursor_(path, header.data_offset, file_size),
        file_vertices_(header.elements[static_cast<size_t>(layout.vertex)].count) {}

  TriangleMesh Decode() {
    const int last = std::max(layout_.vertex, layout_.face);
    for (int e = 0; e <= last; ++e) DecodeElement(static_cast<size_t>(e));
    if (!problem_.empty()) throw Error(Format(name_, ": ", problem_));
    return std::move(mesh_);
  }

 private:
  std::vector<Field> MakeFields(size_t e) const;
  void DecodeElement(size_t e);
  void DecodeRecord(const std::vector<Field>& fields, float* values);
  void AddVertex(const float* values);
  void AddFace(const float* values);

  double ReadFiniteToken(const PlyProperty& p);
  float ReadFloat(const PlyProperty& p);
  int64_t ReadInteger(PlyType type, const PlyProperty& p);
  float ReadColorByte(const PlyProperty& p);
  void SkipValue(const PlyProperty& p);
  int64_t ReadListLength(const PlyProperty& p);
  void ReadList(const PlyProperty& p, int64_t length, bool keep);

  // Binary: the next value of `type` as raw little-endian bits. ASCII: the next token.
  uint64_t NextBits(PlyType type);
  const std::string& NextToken();

  Error Truncated() const {
    return Error(Format(name_, ": truncated or corrupt PLY data: it ends in ", element_->name, " ",
                        record_, " of ", element_->count));
  }
  Error BadValue(const PlyProperty& p, const char* what) const {
    return Error(Format(name_, ": ", element_->name, " ", record_, ": value '", token_,
                        "' of property ", p.name, " is ", what));
  }

  static constexpr size_t kMaxToken = 1024;

  const std::string name_;
  const PlyHeader& header_;
  const PlyLayout& layout_;
  const bool ascii_;
  DataCursor cursor_;
  const uint64_t file_vertices_;
  const PlyElement* element_ = nullptr;
  uint64_t record_ = 0;
  std::string token_;
  std::vector<int64_t> corners_;  // of the current face
  std::string problem_;           // the first corner index out of range
  TriangleMesh mesh_;
};

std::vector<Field> PlyDecoder::MakeFields(size_t e) const {
  const bool vertex = static_cast<int>(e) == layout_.vertex;
  const bool face = static_cast<int>(e) == layout_.face;
  const PlyElement& element = header_.elements[e];
  std::vector<Field> fields(element.properties.size());
  for (size_t p = 0; p < fields.size(); ++p) fields[p].property = &element.properties[p];
  auto assign = [&](const std::array<const char*, 3>& names, int first_slot) {
    for (int c = 0; c < 3; ++c) {
      fields[static_cast<size_t>(element.FindIndex(names[static_cast<size_t>(c)]))].slot =
          first_slot + c;
    }
  };
  if (vertex) {
    assign(ply::kPosition, kX);
    if (layout_.vertex_normals) assign(ply::kNormal, kNx);
    if (layout_.vertex_albedo || layout_.vertex_color) {
      assign(layout_.vertex_albedo ? ply::kAlbedo : ply::kObserved, kAlbR);
    } else if (layout_.vertex_rgb) {
      assign(layout_.vertex_diffuse ? ply::kDiffuseRgb : ply::kRgb, kRed);
    }
  }
  if (face) {
    fields[static_cast<size_t>(layout_.face_indices_property)].corners = true;
    if (layout_.face_albedo || layout_.face_color) {
      assign(layout_.face_albedo ? ply::kAlbedo : ply::kObserved, kAlbR);
    } else if (layout_.face_rgb) {
      assign(ply::kRgb, kRed);
    }
  }
  return fields;
}

void PlyDecoder::DecodeElement(size_t e) {
  element_ = &header_.elements[e];
  const bool vertex = static_cast<int>(e) == layout_.vertex;
  const bool face = static_cast<int>(e) == layout_.face;
  const std::vector<Field> fields = MakeFields(e);
  const size_t count = static_cast<size_t>(element_->count);  // fits: checked against the size
  // Memory is reserved for the records the rest of the file can hold (a face has 3 corners or
  // more), so that a corrupt count fails before a large allocation.
  uint64_t min_record = 0;  // binary: bytes; ASCII: bytes of one-character values and separators
  for (const Field& f : fields) {
    const PlyProperty& p = *f.property;
    const uint64_t entries = f.corners ? 3 : 0;
    const auto size = [](PlyType type) { return static_cast<uint64_t>(ply::TypeSize(type)); };
    min_record += ascii_ ? 2 * (1 + entries)
                         : size(p.is_list() ? p.count : p.value) + entries * size(p.value);
  }
  const size_t reserve =
      min_record == 0 ? 0 : std::min<uint64_t>(count, cursor_.remaining() / min_record + 1);
  if (vertex) {
    mesh_.vertices.reserve(reserve);
    if (layout_.vertex_normals) mesh_.normals.reserve(reserve);
    if (layout_.vertex_albedo || layout_.vertex_color || layout_.vertex_rgb)
      mesh_.vertex_colors.reserve(reserve);
  }
  if (face) {
    mesh_.faces.reserve(reserve);
    if (layout_.face_albedo || layout_.face_color || layout_.face_rgb)
      mesh_.face_colors.reserve(reserve);
  }
  float values[kSlotCount] = {};
  for (record_ = 0; record_ < count; ++record_) {
    DecodeRecord(fields, values);
    if (vertex) AddVertex(values);
    if (face) AddFace(values);
  }
}

void PlyDecoder::DecodeRecord(const std::vector<Field>& fields, float* values) {
  for (const Field& field : fields) {
    const PlyProperty& p = *field.property;
    if (p.is_list()) {
      const int64_t length = ReadListLength(p);
      if (field.corners && length < 3) {
        throw Error(
            Format(name_, ": face ", record_, " has ", length, " vertices; at least 3 are needed"));
      }
      ReadList(p, length, field.corners);
    } else if (field.slot == kSkip) {
      SkipValue(p);
    } else if (field.slot >= kRed && field.slot <= kBlue) {
      values[field.slot] = ReadColorByte(p);
    } else {
      values[field.slot] = ReadFloat(p);
    }
  }
}

Eigen::Vector3f SrgbBytesToLinear(const float* bytes) {
  return {SrgbToLinear(bytes[0] / 255.0f), SrgbToLinear(bytes[1] / 255.0f),
          SrgbToLinear(bytes[2] / 255.0f)};
}

void PlyDecoder::AddVertex(const float* values) {
  mesh_.vertices.emplace_back(values[kX], values[kY], values[kZ]);
  if (layout_.vertex_normals) mesh_.normals.emplace_back(values[kNx], values[kNy], values[kNz]);
  if (layout_.vertex_albedo || layout_.vertex_color) {
    mesh_.vertex_colors.emplace_back(values[kAlbR], values[kAlbG], values[kAlbB]);
  } else if (layout_.vertex_rgb) {
    mesh_.vertex_colors.push_back(SrgbBytesToLinear(values + kRed));
  }
}

void PlyDecoder::AddFace(const float* values) {
  for (const int64_t index : corners_) {
    if (problem_.empty() && (index < 0 || static_cast<uint64_t>(index) >= file_vertices_)) {
      problem_ = Format("face ", record_, " uses vertex ", index, " but the file has ",
                        file_vertices_, " vertices");
    }
  }
  if (!problem_.empty()) return;  // the file is refused: build nothing more
  Eigen::Vector3f color = Eigen::Vector3f::Zero();
  if (layout_.face_albedo || layout_.face_color) {
    color = Eigen::Vector3f(values[kAlbR], values[kAlbG], values[kAlbB]);
  } else if (layout_.face_rgb) {
    color = SrgbBytesToLinear(values + kRed);
  }
  const bool colored = layout_.face_albedo || layout_.face_color || layout_.face_rgb;
  for (size_t k = 1; k + 1 < corners_.size(); ++k) {  // fan triangulation
    mesh_.faces.emplace_back(static_cast<int>(corners_[0]), static_cast<int>(corners_[k]),
                             static_cast<int>(corners_[k + 1]));
    if (colored) mesh_.face_colors.push_back(color);
  }
}

const std::string& PlyDecoder::NextToken() {
  int c = cursor_.Get();
  while (c >= 0 && std::isspace(c)) c = cursor_.Get();
  if (c < 0) throw Truncated();
  token_.clear();
  while (c >= 0 && !std::isspace(c)) {
    if (token_.size() == kMaxToken) {
      throw Error(Format(name_, ": ", element_->name, " ", record_, ": a value of more than ",
                         kMaxToken, " characters"));
    }
    token_.push_back(static_cast<char>(c));
    c = cursor_.Get();
  }
  return token_;
}

uint64_t PlyDecoder::NextBits(PlyType type) {
  unsigned char bytes[8];
  const int size = ply::TypeSize(type);
  if (!cursor_.Read(bytes, static_cast<size_t>(size))) throw Truncated();
  return LoadLittleEndian(bytes, size);
}

int64_t PlyDecoder::ReadInteger(PlyType type, const PlyProperty& p) {
  if (ascii_) {
    int64_t value = 0;
    if (!ParseInteger64(NextToken(), &value)) throw BadValue(p, "not an integer");
    return value;
  }
  const uint64_t u = NextBits(type);
  const int bits = 8 * ply::TypeSize(type);
  if (ply::IsSigned(type) && (u >> (bits - 1)) != 0) {
    return static_cast<int64_t>(u) - (int64_t{1} << bits);
  }
  return static_cast<int64_t>(u);
}

// Float properties only (CheckHeader).
float PlyDecoder::ReadFloat(const PlyProperty& p) {
  if (!ascii_) {
    const uint64_t u = NextBits(p.value);
    if (p.value == PlyType::kFloat32) {
      const uint32_t u32 = static_cast<uint32_t>(u);
      float f;
      std::memcpy(&f, &u32, sizeof f);
      return f;
    }
    double d;
    std::memcpy(&d, &u, sizeof d);
    return static_cast<float>(d);
  }
  const double d = ReadFiniteToken(p);
  float f = 0.0f;
  const auto [ptr, ec] = std::from_chars(token_.data(), token_.data() + token_.size(), f);
  if (ec == std::errc() && ptr == token_.data() + token_.size()) return f;
  if (std::fabs(d) > std::numeric_limits<float>::max()) throw BadValue(p, "out of the float range");
  return static_cast<float>(d);  // below the float range: zero or subnormal
}

// ASCII: the next token as a finite double.
double PlyDecoder::ReadFiniteToken(const PlyProperty& p) {
  const std::string& token = NextToken();
  const char* end = token.data() + token.size();
  double d = 0.0;
  const auto [ptr, ec] = std::from_chars(token.data(), end, d);
  if (ec != std::errc() || ptr != end || !std::isfinite(d))
    throw BadValue(p, "not a finite number");
  return d;
}

// A colour channel as its 8-bit value: a float in [0, 1] times 255, truncated (clamped to the
// interval first, NaN as 0); an integer modulo 256 (a char -1 is 255).
float PlyDecoder::ReadColorByte(const PlyProperty& p) {
  if (ply::IsFloat(p.value)) {
    const float v = ReadFloat(p);
    if (!(v > 0.0f)) return 0.0f;
    return static_cast<float>(static_cast<int>(std::min(v, 1.0f) * 255.0f));
  }
  return static_cast<float>(static_cast<unsigned char>(ReadInteger(p.value, p) & 0xff));
}

void PlyDecoder::SkipValue(const PlyProperty& p) {
  if (!ascii_) {
    if (!cursor_.Skip(static_cast<uint64_t>(ply::TypeSize(p.value)))) throw Truncated();
  } else if (ply::IsFloat(p.value)) {
    ReadFiniteToken(p);
  } else {
    ReadInteger(p.value, p);
  }
}

int64_t PlyDecoder::ReadListLength(const PlyProperty& p) {
  int64_t length = 0;
  if (ascii_) {
    if (!ParseInteger64(NextToken(), &length)) {
      throw Error(Format(name_, ": ", element_->name, " ", record_, ": list length '", token_,
                         "' of property ", p.name, " is not an integer"));
    }
  } else {
    length = ReadInteger(p.count, p);
  }
  if (length < 0) {
    throw Error(Format(name_, ": ", element_->name, " ", record_, ": negative list length ", length,
                       " of property ", p.name));
  }
  return length;
}

// Reads `length` entries of the list property `p`: into corners_ when `keep`, else checked and
// dropped.
void PlyDecoder::ReadList(const PlyProperty& p, int64_t length, bool keep) {
  const uint64_t n = static_cast<uint64_t>(length);
  if (keep) corners_.clear();
  if (!ascii_) {
    const uint64_t size = static_cast<uint64_t>(ply::TypeSize(p.value));
    if (n > cursor_.remaining() / size) throw Truncated();  // before anything is allocated
    if (!keep) {
      cursor_.Skip(n * size);
      return;
    }
    for (uint64_t k = 0; k < n; ++k) corners_.push_back(ReadInteger(p.value, p));
    return;
  }
  for (uint64_t k = 0; k < n; ++k) {
    if (keep) {
      corners_.push_back(ReadInteger(p.value, p));
    } else {
      SkipValue(p);
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Writing.

unsigned char LinearToSrgbByte(float linear) {
  return static_cast<unsigned char>(
      std::lround(LinearToSrgb(std::clamp(linear, 0.0f, 1.0f)) * 255.0f));
}

// Vertex and face colours are stored exactly as float albedo_r/g/b or color_r/g/b (their 8-bit
// red/green/blue copy, for viewers, is clamped to [0, 1]); they only have to be finite.
void CheckColorsWritable(const TriangleMesh& mesh, const std::string& name) {
  for (size_t i = 0; i < mesh.vertex_colors.size(); ++i) {
    if (!mesh.vertex_colors[i].allFinite()) {
      throw Error(Format(name, ": vertex colour ", i, " is not finite"));
    }
  }
  for (size_t f = 0; f < mesh.face_colors.size(); ++f) {
    if (!mesh.face_colors[f].allFinite())
      throw Error(Format(name, ": face colour ", f, " is not finite"));
  }
}

std::string WriteHeader(const TriangleMesh& mesh, const PlyWriteOptions& options) {
  const bool binary = options.binary;
  const auto& linear = options.colors == PlyColors::kObserved ? ply::kObserved : ply::kAlbedo;
  auto properties = [](const char* type, const std::array<const char*, 3>& names) {
    std::string text;
    for (const char* n : names) text += Format("property ", type, " ", n, "\n");
    return text;
  };
  std::string text = "ply\n";
  text += binary ? "format binary_little_endian 1.0\n" : "format ascii 1.0\n";
  text += Format("element vertex ", mesh.vertices.size(), "\n");
  text += properties("float", ply::kPosition);
  if (!mesh.normals.empty()) text += properties("float", ply::kNormal);
  if (!mesh.vertex_colors.empty()) {
    text += properties("uchar", ply::kRgb) + properties("float", linear);
  }
  text += Format("element face ", mesh.faces.size(), "\n");
  text += "property list uchar int vertex_indices\n";
  if (!mesh.face_colors.empty()) {
    text += properties("uchar", ply::kRgb) + properties("float", linear);
  }
  return text + "end_header\n";
}

// Appends records to a buffer that is flushed to the file every MiB. ASCII: values separated by
// one space, one record per line.
class RecordWriter {
 public:
  RecordWriter(std::ofstream* out, bool binary) : out_(out), binary_(binary) {}

  void Float(float v) {
    if (binary_) return Raw(&v, sizeof v);
    char text[32];
    const int n = std::snprintf(text, sizeof text, "%.9g", static_cast<double>(v));
    Text(text, static_cast<size_t>(n));
  }
  void Int(int32_t v) { binary_ ? Raw(&v, sizeof v) : TextNumber(v); }
  void Byte(unsigned char v) { binary_ ? Raw(&v, 1) : TextNumber(v); }
  void Vector(const Eigen::Vector3f& v) {
    for (int c = 0; c < 3; ++c) Float(v[c]);
  }
  void Colour(const Eigen::Vector3f& linear) {
    for (int c = 0; c < 3; ++c) Byte(LinearToSrgbByte(linear[c]));
    Vector(linear);
  }
  void EndRecord() {
    if (!binary_) buffer_.push_back('\n');
    first_ = true;
    if (buffer_.size() >= (size_t{1} << 20)) Flush();
  }
  void Flush() {
    out_->write(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
    buffer_.clear();
  }

 private:
  void Raw(const void* data, size_t n) { buffer_.append(static_cast<const char*>(data), n); }
  void TextNumber(int64_t v) {
    const std::string text = std::to_string(v);
    Text(text.data(), text.size());
  }
  void Text(const char* text, size_t n) {
    if (!first_) buffer_.push_back(' ');
    first_ = false;
    buffer_.append(text, n);
  }

  std::ofstream* out_;
  bool binary_;
  bool first_ = true;
  std::string buffer_;
};

void WriteRecords(const TriangleMesh& mesh, bool binary, std::ofstream* out) {
  RecordWriter writer(out, binary);
  for (size_t v = 0; v < mesh.vertices.size(); ++v) {
    writer.Vector(mesh.vertices[v]);
    if (!mesh.normals.empty()) writer.Vector(mesh.normals[v]);
    if (!mesh.vertex_colors.empty()) writer.Colour(mesh.vertex_colors[v]);
    writer.EndRecord();
  }
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    writer.Byte(3);
    for (int k = 0; k < 3; ++k) writer.Int(mesh.faces[f][k]);
    if (!mesh.face_colors.empty()) writer.Colour(mesh.face_colors[f]);
    writer.EndRecord();
  }
  writer.Flush();
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

  const PlyHeader header = ply::ParseHeader(path, file_size);
  const PlyLayout layout = ply::CheckHeader(header, name);
  ply::CheckCountsFitInFile(header, file_size, name);
  TriangleMesh mesh = PlyDecoder(path, header, layout, file_size).Decode();
  mesh.Validate(name);
  return mesh;
}

void WritePly(const fs::path& path, const TriangleMesh& mesh, const PlyWriteOptions& options) {
  const std::string name = path.string();
  mesh.Validate(name);
  CheckColorsWritable(mesh, name);
  WriteFileAtomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out)
      throw Error(Format(name, ": cannot write ", tmp.string(), " (", std::strerror(errno), ")"));
    out << WriteHeader(mesh, options);
    WriteRecords(mesh, options.binary, &out);
    out.close();
    if (!out) throw Error(Format(name, ": write failed (disk full?)"));
  });
}

}  // namespace genscene
