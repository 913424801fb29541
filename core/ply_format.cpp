// The PLY header model, its parser, the header checks and the data cursor: see ply_format.h.
#include "core/ply_format.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <system_error>
#include <utility>

#include "core/check.h"
#include "core/file_util.h"

namespace genscene::ply {

namespace {

namespace fs = std::filesystem;

constexpr size_t kMaxHeaderBytes = size_t{1} << 20;  // a longer header is an error
constexpr uint64_t kMaxElementCount = std::numeric_limits<int32_t>::max();

std::optional<PlyType> LookupType(const std::string& name) {
  if (name == "char" || name == "int8") return PlyType::kInt8;
  if (name == "uchar" || name == "uint8") return PlyType::kUint8;
  if (name == "short" || name == "int16") return PlyType::kInt16;
  if (name == "ushort" || name == "uint16") return PlyType::kUint16;
  if (name == "int" || name == "int32") return PlyType::kInt32;
  if (name == "uint" || name == "uint32") return PlyType::kUint32;
  if (name == "float" || name == "float32") return PlyType::kFloat32;
  if (name == "double" || name == "float64") return PlyType::kFloat64;
  return std::nullopt;
}

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

std::string NotAPly(const std::string& name) {
  return Format(name, ": not a PLY file (it does not start with the line 'ply')");
}

void ParseFormatLine(const std::vector<std::string>& tokens, const std::string& line,
                     const std::string& where, const std::string& name, PlyHeader* header) {
  if (!header->elements.empty()) throw Error(Format(where, ": format line after an element"));
  if (tokens.size() != 3) throw Error(Format(where, ": malformed format line '", line, "'"));
  if (tokens[1] == "ascii") {
    header->format = PlyFormat::kAscii;
  } else if (tokens[1] == "binary_little_endian") {
    header->format = PlyFormat::kBinaryLittleEndian;
  } else if (tokens[1] == "binary_big_endian") {
    throw Error(Format(name,
                       ": binary_big_endian PLY is not supported "
                       "(convert it to binary_little_endian or ascii)"));
  } else {
    throw Error(Format(where, ": unknown PLY format '", tokens[1], "'"));
  }
}

void ParseElementLine(const std::vector<std::string>& tokens, const std::string& line,
                      const std::string& where, PlyHeader* header) {
  if (tokens.size() != 3) throw Error(Format(where, ": malformed element line '", line, "'"));
  PlyElement element;
  element.name = tokens[1];
  element.count = ParseCount(tokens[2], where);
  if (element.count > kMaxElementCount) {
    throw Error(Format(where, ": ", element.count, " ", element.name, " elements; at most ",
                       kMaxElementCount, " are supported"));
  }
  if (header->FindIndex(element.name) >= 0) {
    throw Error(Format(where, ": second element named '", element.name, "'"));
  }
  header->elements.push_back(std::move(element));
}

void ParsePropertyLine(const std::vector<std::string>& tokens, const std::string& line,
                       const std::string& where, PlyHeader* header) {
  if (header->elements.empty()) throw Error(Format(where, ": property before any element"));
  PlyProperty property;
  if (tokens.size() == 5 && tokens[1] == "list") {
    property.count_type = tokens[2];
    property.type = tokens[3];
    property.name = tokens[4];
    const std::optional<PlyType> count = LookupType(property.count_type);
    if (!count || IsFloat(*count)) {
      throw Error(
          Format(where, ": list length type '", property.count_type, "' is not an integer type"));
    }
    property.count = *count;
  } else if (tokens.size() == 3 && tokens[1] != "list") {
    property.type = tokens[1];
    property.name = tokens[2];
  } else {
    throw Error(Format(where, ": malformed property line '", line, "'"));
  }
  const std::optional<PlyType> value = LookupType(property.type);
  if (!value) throw Error(Format(where, ": unknown property type '", property.type, "'"));
  property.value = *value;
  PlyElement& element = header->elements.back();
  if (element.Find(property.name)) {
    throw Error(
        Format(where, ": second property '", property.name, "' in element '", element.name, "'"));
  }
  element.properties.push_back(std::move(property));
}

std::string ReadHeaderText(const fs::path& path, uint64_t file_size) {
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
    throw Error(NotAPly(name));
  }
  return text;
}

}  // namespace

int TypeSize(PlyType type) {
  switch (type) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 0;
}

bool IsFloat(PlyType type) {
  return type == PlyType::kFloat32 || type == PlyType::kFloat64;
}

bool IsSigned(PlyType type) {
  return type == PlyType::kInt8 || type == PlyType::kInt16 || type == PlyType::kInt32;
}

PlyHeader ParseHeader(const fs::path& path, uint64_t file_size) {
  const std::string name = path.string();
  const std::string text = ReadHeaderText(path, file_size);
  PlyHeader header;
  bool have_format = false;
  size_t pos = 0;
  int line_number = 0;
  while (pos < text.size()) {
    const size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) break;
    const std::string line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_number;
    const std::string where = Format(name, ": PLY header line ", line_number);
    const std::vector<std::string> tokens = SplitWhitespace(line);
    if (line_number == 1) {
      if (tokens.size() != 1 || tokens[0] != "ply") throw Error(NotAPly(name));
      continue;
    }
    if (tokens.empty()) continue;  // blank line
    const std::string& keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") {
      if (tokens.size() != 1)
        throw Error(Format(where, ": malformed end_header line '", line, "'"));
      if (!have_format) throw Error(Format(name, ": the PLY header has no format line"));
      header.data_offset = pos;
      return header;
    }
    if (keyword == "format") {
      if (have_format) throw Error(Format(where, ": second format line"));
      ParseFormatLine(tokens, line, where, name, &header);
      have_format = true;
    } else if (keyword == "element") {
      if (!have_format) throw Error(Format(where, ": element before the format line"));
      ParseElementLine(tokens, line, where, &header);
    } else if (keyword == "property") {
      ParsePropertyLine(tokens, line, where, &header);
    } else {
      throw Error(Format(where, ": unknown header keyword '", keyword, "'"));
    }
  }
  if (file_size > kMaxHeaderBytes) {
    throw Error(Format(name, ": no end_header line in the first ", kMaxHeaderBytes,
                       " bytes (not a PLY mesh, or a corrupt header)"));
  }
  throw Error(Format(name, ": the PLY header has no end_header line (truncated file?)"));
}

// ------------------------------------------------------------------------------------------------
// What ReadPly decodes, and the header checks.

namespace {

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

void RequireFloat(const PlyElement& element, const std::array<const char*, 3>& names,
                  const std::string& where) {
  for (const char* property : names) {
    const PlyProperty* p = element.Find(property);
    if (p && (p->is_list() || !IsFloat(p->value))) {
      throw Error(Format(where, ": ", element.name, " property '", property, "' has type ",
                         p->is_list() ? "list" : p->type, "; a float or double is needed"));
    }
  }
}

// Colours are 8-bit integers, or floats in [0, 1] (scaled to 8 bits).
void RequireColorType(const PlyElement& element, const char* property, const std::string& where) {
  const PlyProperty* p = element.Find(property);
  if (!p) return;
  const bool eight_bit = p->value == PlyType::kInt8 || p->value == PlyType::kUint8;
  if (p->is_list() || !(eight_bit || p->value == PlyType::kFloat32)) {
    throw Error(Format(where, ": ", element.name, " colour property '", property, "' has type ",
                       p->is_list() ? "list" : p->type, "; uchar or float is supported"));
  }
}

void CheckVertexElement(const PlyElement& vertex, const std::string& name, PlyLayout* layout) {
  if (!HasAllOrNone(vertex, kPosition, name)) {
    throw Error(Format(name, ": the vertex element has no x/y/z properties"));
  }
  RequireFloat(vertex, kPosition, name);
  RequireFloat(vertex, kNormal, name);
  layout->vertex_normals = HasAllOrNone(vertex, kNormal, name);
  const bool rgb = HasAllOrNone(vertex, kRgb, name);
  const bool diffuse = HasAllOrNone(vertex, kDiffuseRgb, name);
  if (rgb && diffuse) {
    throw Error(
        Format(name, ": the vertex element has both red/green/blue and diffuse_red/green/blue"));
  }
  layout->vertex_rgb = rgb || diffuse;
  layout->vertex_diffuse = diffuse;
  for (const char* p : kRgb) RequireColorType(vertex, p, name);
  for (const char* p : kDiffuseRgb) RequireColorType(vertex, p, name);
  layout->vertex_albedo = HasAllOrNone(vertex, kAlbedo, name);
  RequireFloat(vertex, kAlbedo, name);
  layout->vertex_color = HasAllOrNone(vertex, kObserved, name);
  RequireFloat(vertex, kObserved, name);
}

void CheckFaceElement(const PlyElement& face, const std::string& name, PlyLayout* layout) {
  const int indices = face.FindIndex("vertex_indices");
  const int index = face.FindIndex("vertex_index");
  if (indices >= 0 && index >= 0) {
    throw Error(Format(name, ": the face element has both vertex_indices and vertex_index"));
  }
  layout->face_indices_property = std::max(indices, index);
  if (layout->face_indices_property < 0) {
    throw Error(Format(name, ": the face element has no vertex_indices list"));
  }
  const PlyProperty& list = face.properties[static_cast<size_t>(layout->face_indices_property)];
  if (!list.is_list() || IsFloat(list.value)) {
    throw Error(Format(name, ": face property '", list.name, "' must be a list of integers"));
  }
  layout->face_rgb = HasAllOrNone(face, kRgb, name);
  for (const char* p : kRgb) RequireColorType(face, p, name);
  layout->face_albedo = HasAllOrNone(face, kAlbedo, name);
  RequireFloat(face, kAlbedo, name);
  layout->face_color = HasAllOrNone(face, kObserved, name);
  RequireFloat(face, kObserved, name);
}

}  // namespace

PlyLayout CheckHeader(const PlyHeader& header, const std::string& name) {
  PlyLayout layout;
  layout.vertex = header.FindIndex("vertex");
  layout.face = header.FindIndex("face");
  if (layout.vertex < 0) throw Error(Format(name, ": the PLY file has no 'vertex' element"));
  CheckVertexElement(header.elements[static_cast<size_t>(layout.vertex)], name, &layout);
  if (layout.face >= 0) {
    CheckFaceElement(header.elements[static_cast<size_t>(layout.face)], name, &layout);
  }
  return layout;
}

// ------------------------------------------------------------------------------------------------
// Size check (no allocation).

namespace {

uint64_t SatAdd(uint64_t a, uint64_t b) {
  return a > std::numeric_limits<uint64_t>::max() - b ? std::numeric_limits<uint64_t>::max()
                                                      : a + b;
}
uint64_t SatMul(uint64_t a, uint64_t b) {
  return (b != 0 && a > std::numeric_limits<uint64_t>::max() / b)
             ? std::numeric_limits<uint64_t>::max()
             : a * b;
}

std::string DescribeCounts(const PlyHeader& header) {
  std::string text;
  for (size_t e = 0; e < header.elements.size(); ++e) {
    text += Format(e == 0 ? "" : ", ", header.elements[e].count, " ", header.elements[e].name);
  }
  return text.empty() ? "no elements" : text;
}

}  // namespace

void CheckCountsFitInFile(const PlyHeader& header, uint64_t file_size, const std::string& name) {
  const uint64_t available = file_size - header.data_offset;
  uint64_t need = 0;
  for (const PlyElement& element : header.elements) {
    uint64_t record = 0;  // binary: bytes; ASCII: values
    for (const PlyProperty& prop : element.properties) {
      if (header.format == PlyFormat::kAscii) {
        record += 1;
      } else {
        record += static_cast<uint64_t>(TypeSize(prop.is_list() ? prop.count : prop.value));
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

// ------------------------------------------------------------------------------------------------
// Data cursor.

DataCursor::DataCursor(const fs::path& path, uint64_t begin, uint64_t end)
    : file_(path, std::ios::binary), next_(begin), end_(end), buffer_(size_t{1} << 20) {
  if (!file_) throw Error(Format(path.string(), ": cannot open (", std::strerror(errno), ")"));
}

bool DataCursor::Read(void* destination, size_t n) {
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

bool DataCursor::Skip(uint64_t n) {
  if (n <= length_ - pos_) {
    pos_ += static_cast<size_t>(n);
    return true;
  }
  n -= length_ - pos_;
  pos_ = length_ = 0;
  if (n > end_ - next_) {
    next_ = end_;
    return false;
  }
  next_ += n;
  return true;
}

bool DataCursor::Fill() {
  if (next_ >= end_) return false;
  const size_t n = static_cast<size_t>(std::min<uint64_t>(buffer_.size(), end_ - next_));
  file_.clear();
  file_.seekg(static_cast<std::streamoff>(next_));
  file_.read(buffer_.data(), static_cast<std::streamsize>(n));
  length_ = static_cast<size_t>(std::max<std::streamsize>(file_.gcount(), 0));
  pos_ = 0;
  next_ = length_ > 0 ? next_ + length_ : end_;  // a file that shrank under us ends here
  return length_ > 0;
}

}  // namespace genscene::ply
