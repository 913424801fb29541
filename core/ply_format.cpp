// The PLY header model and the checks that run before OpenMesh reads a file: see ply_format.h.
#include "core/ply_format.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <system_error>
#include <utility>

#include "core/check.h"
#include "core/file_util.h"

namespace genscene::ply {

namespace {

namespace fs = std::filesystem;

// ------------------------------------------------------------------------------------------------
// Header model and parser.

constexpr size_t kMaxHeaderBytes = size_t{1} << 20;  // a longer header is an error
constexpr uint64_t kMaxElementCount = std::numeric_limits<int32_t>::max();

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

}  // namespace

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

}  // namespace

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

}  // namespace

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

namespace {

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

}  // namespace

// OpenMesh parses ASCII values with istream >>, which fails on "nan", "inf" or a stray letter and
// then misreads the rest of the file (or loops); every value is checked here first: integer
// properties need an integer, float properties a finite number.
static void CheckAsciiNumber(const std::string& token, bool is_float, const std::string& name,
                             const PlyElement& element, uint64_t record,
                             const std::string& property) {
  const char* end = token.data() + token.size();
  bool ok = false;
  if (is_float) {
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(token.data(), end, value);
    ok = ec == std::errc() && ptr == end && std::isfinite(value);
  } else {
    int64_t value = 0;
    const auto [ptr, ec] = std::from_chars(token.data(), end, value);
    ok = ec == std::errc() && ptr == end;
  }
  if (!ok) {
    throw Error(Format(name, ": ", element.name, " ", record, ": value '", token, "' of property ",
                       property, " is not ", is_float ? "a finite number" : "an integer"));
  }
}

void WalkData(const fs::path& path, const PlyHeader& header, const PlyLayout& layout,
              uint64_t file_size) {
  struct Field {
    bool list = false;
    bool is_float = false;  // a float/double scalar, or list entries of that type
    int size = 0;           // binary: a scalar's size, or a list entry's size
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
      field.is_float = LookupType(prop.type)->is_float;
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
          if (ascii) {
            if (!cursor.NextToken(&token)) throw truncated(r);
            CheckAsciiNumber(token, field.is_float, name, element, r, element.properties[p].name);
          } else if (!cursor.Skip(static_cast<uint64_t>(field.size))) {
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
            if (!cursor.NextToken(&token)) throw truncated(r);
            CheckAsciiNumber(token, field.is_float, name, element, r, element.properties[p].name);
          }
        } else if (!cursor.Skip(
                       SatMul(static_cast<uint64_t>(length), static_cast<uint64_t>(field.size)))) {
          throw truncated(r);
        }
      }
    }
  }
}

// ------------------------------------------------------------------------------------------------
// What OpenMesh reads: the canonical header, then the file's data.

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

SplicedFileBuf::SplicedFileBuf(std::string prefix, const fs::path& path, uint64_t begin,
                               uint64_t end, std::string suffix)
    : prefix_(std::move(prefix)),
      suffix_(std::move(suffix)),
      file_(path, std::ios::binary),
      begin_(begin),
      body_size_(end - begin),
      buffer_(size_t{1} << 16) {
  if (!file_) throw Error(Format(path.string(), ": cannot open (", std::strerror(errno), ")"));
  setg(buffer_.data(), buffer_.data(), buffer_.data());
}

SplicedFileBuf::int_type SplicedFileBuf::underflow() {
  if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
  position_ += static_cast<uint64_t>(egptr() - eback());
  const size_t n = Load(position_);
  setg(buffer_.data(), buffer_.data(), buffer_.data() + n);
  return n == 0 ? traits_type::eof() : traits_type::to_int_type(*gptr());
}

SplicedFileBuf::pos_type SplicedFileBuf::seekoff(off_type off, std::ios_base::seekdir dir,
                                                 std::ios_base::openmode which) {
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

SplicedFileBuf::pos_type SplicedFileBuf::seekpos(pos_type pos, std::ios_base::openmode which) {
  return seekoff(off_type(pos), std::ios_base::beg, which);
}

size_t SplicedFileBuf::Load(uint64_t at) {
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

}  // namespace genscene::ply
