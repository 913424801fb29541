// Mitsuba 3 XML import, the element level (declared in mitsuba_xml_internal.h): where an element
// is, attribute and number checks, transforms (§4), the properties of one object element (Props)
// the perspective sensor's field of view and pose, and the colour attributes of PLY files as
// Mitsuba reads them. The two passes over the documents are in mitsuba_xml.cpp; the § numbers
// are the sections of the subset in mitsuba_xml.h.
#include <tinyxml2.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <set>
#include <sstream>

#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"
#include "render/formats/mitsuba_xml_internal.h"

namespace genscene::render::mitsuba_detail {

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Matrix4d;
using Eigen::Vector3d;
using tinyxml2::XMLElement;

// ------------------------------------------------------------------------------------------------
// Element helpers: where an element is, attribute checks, numbers.

std::string Where(const XMLElement* el) {
  const auto* file = static_cast<const fs::path*>(el->GetDocument()->GetUserData());
  std::string text = Format(file ? file->string() : "?", ":", el->GetLineNum(), ": <", el->Name());
  for (const char* a : {"type", "name", "id"}) {
    if (const char* v = el->Attribute(a)) text += Format(" ", a, "=\"", v, "\"");
  }
  return text + ">";
}

[[noreturn]] void Fail(const XMLElement* el, const std::string& what) {
  throw Error(Where(el) + ": " + what);
}

void CheckAttributes(const XMLElement* el, std::initializer_list<const char*> allowed) {
  for (const tinyxml2::XMLAttribute* a = el->FirstAttribute(); a; a = a->Next()) {
    bool ok = false;
    for (const char* name : allowed) ok = ok || std::string(name) == a->Name();
    if (!ok) Fail(el, Format("unexpected attribute '", a->Name(), "'"));
  }
}

std::string RequiredAttribute(const XMLElement* el, const char* name) {
  const char* v = el->Attribute(name);
  if (!v) Fail(el, Format("missing attribute '", name, "'"));
  return v;
}

std::vector<std::string> Tokens(const std::string& text) {
  std::vector<std::string> out;
  std::string token;
  for (char c : text + " ") {
    if (c == ',' || c == ' ') {
      if (!token.empty()) out.push_back(token);
      token.clear();
    } else {
      token += c;
    }
  }
  return out;
}

double Number(const std::string& token, const XMLElement* el) {
  double value = 0.0;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  if (ec != std::errc() || ptr != end) Fail(el, Format("'", token, "' is not a number"));
  if (!std::isfinite(value)) Fail(el, Format("'", token, "' is not a finite number"));
  return value;
}

bool IsObjectTag(const std::string& tag) {
  static const std::set<std::string> tags = {"shape",   "bsdf",    "emitter", "sensor",
                                             "film",    "rfilter", "sampler", "integrator",
                                             "texture", "medium",  "phase",   "volume"};
  return tags.count(tag) > 0;
}

std::string Type(const XMLElement* el) {
  return el->Attribute("type") ? el->Attribute("type") : "";
}

namespace {

std::vector<double> Numbers(const std::string& text, const XMLElement* el) {
  std::vector<double> out;
  for (const std::string& t : Tokens(text)) out.push_back(Number(t, el));
  return out;
}

// x/y/z attributes, or `value` with one (replicated) or three numbers (§1).
Vector3d Xyz(const XMLElement* el, std::optional<double> fallback) {
  if (const char* value = el->Attribute("value")) {
    if (el->Attribute("x") || el->Attribute("y") || el->Attribute("z")) {
      Fail(el, "'value' cannot be combined with x/y/z");
    }
    const std::vector<double> v = Numbers(value, el);
    if (v.size() == 1) return Vector3d::Constant(v[0]);
    if (v.size() == 3) return Vector3d(v[0], v[1], v[2]);
    Fail(el, Format("'value' needs 1 or 3 numbers, got ", v.size()));
  }
  Vector3d out;
  for (int i = 0; i < 3; ++i) {
    const char* name = i == 0 ? "x" : i == 1 ? "y" : "z";
    const char* v = el->Attribute(name);
    if (!v && !fallback) Fail(el, Format("missing attribute '", name, "'"));
    out[i] = v ? Number(v, el) : *fallback;
  }
  return out;
}

Vector3d VectorAttribute(const XMLElement* el, const char* name) {
  const std::vector<double> v = Numbers(RequiredAttribute(el, name), el);
  if (v.size() != 3) Fail(el, Format("'", name, "' needs 3 numbers, got ", v.size()));
  return Vector3d(v[0], v[1], v[2]);
}

bool IsPropertyTag(const std::string& tag) {
  static const std::set<std::string> tags = {"float",  "integer", "boolean",  "string",   "point",
                                             "vector", "rgb",     "spectrum", "transform"};
  return tags.count(tag) > 0;
}

// ------------------------------------------------------------------------------------------------
// Transforms (§4): each element left-multiplies the transform built so far.

// Mitsuba's lookat: columns [left, new_up, dir, origin] (§4). A missing or zero `up` becomes the
// first vector of the orthonormal basis of Duff et al. (2017) around the viewing direction.
Matrix4d LookAt(const XMLElement* el) {
  CheckAttributes(el, {"origin", "target", "up"});
  const Vector3d origin = VectorAttribute(el, "origin"), target = VectorAttribute(el, "target");
  Vector3d up = el->Attribute("up") ? VectorAttribute(el, "up") : Vector3d::Zero();
  const Vector3d dir = (target - origin).normalized();
  if (up.isZero(0.0)) {
    const double sign = std::copysign(1.0, dir.z()), a = -1.0 / (sign + dir.z());
    up =
        Vector3d(1.0 + sign * dir.x() * dir.x() * a, sign * dir.x() * dir.y() * a, -sign * dir.x());
  }
  const Vector3d left = up.cross(dir).normalized();
  Matrix3d r;
  r << left, dir.cross(left), dir;
  if (!r.allFinite() || !origin.allFinite() || (target - origin).norm() == 0.0 ||
      up.cross(dir).norm() == 0.0) {
    Fail(el,
         "invalid lookat transformation (origin == target, or up parallel to the view direction)");
  }
  return Affine(r, origin);
}

Matrix4d ParseTransform(const XMLElement* el) {
  CheckAttributes(el, {"name"});
  Matrix4d m = Matrix4d::Identity();
  for (const XMLElement* c = el->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string tag = c->Name();
    if (tag == "translate") {
      CheckAttributes(c, {"value", "x", "y", "z"});
      m = Affine(Matrix3d::Identity(), Xyz(c, 0.0)) * m;
    } else if (tag == "scale") {
      CheckAttributes(c, {"value", "x", "y", "z"});
      m = Affine(Xyz(c, 1.0).asDiagonal(), Vector3d::Zero()) * m;
    } else if (tag == "rotate") {
      CheckAttributes(c, {"value", "x", "y", "z", "angle"});
      const Vector3d axis = Xyz(c, 0.0);
      const double angle = Radians(Number(RequiredAttribute(c, "angle"), c));
      if (axis.isZero(0.0)) Fail(c, "rotation axis cannot be zero");
      // Mitsuba applies Rodrigues' formula to the axis as given (§4): only a unit axis rotates.
      if (std::abs(axis.norm() - 1.0) > 1e-6) {
        Fail(c, Format("rotation axis (", axis.transpose(), ") has length ", axis.norm(),
                       "; Mitsuba does not normalise it, so give a unit axis"));
      }
      m = Affine(Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix(), Vector3d::Zero()) *
          m;
    } else if (tag == "matrix") {
      CheckAttributes(c, {"value"});
      const std::vector<double> v = Numbers(RequiredAttribute(c, "value"), c);
      if (v.size() != 16 && v.size() != 9)
        Fail(c, Format("matrix needs 9 or 16 values, got ", v.size()));
      const int n = v.size() == 16 ? 4 : 3;
      Matrix4d t = Matrix4d::Identity();
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) t(i, j) = v[static_cast<size_t>(i * n + j)];  // row-major
      if (t.row(3) != Eigen::RowVector4d(0, 0, 0, 1))
        Fail(c, "projective matrices are not supported");
      m = t * m;
    } else if (tag == "lookat") {
      m = LookAt(c) * m;
    } else {
      Fail(c, "unexpected element inside <transform>");
    }
  }
  return m;
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Props: the properties of one object element.

Props::Props(XMLElement* object, const std::function<XMLElement*(XMLElement*)>& resolve_ref)
    : object_(object) {
  for (XMLElement* c = object->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string tag = c->Name();
    if (tag == "ref") {
      CheckAttributes(c, {"id", "name"});
      children_.push_back(resolve_ref(c));
    } else if (IsObjectTag(tag)) {
      children_.push_back(c);
    } else if (IsPropertyTag(tag)) {
      const std::string name = RequiredAttribute(c, "name");
      if (!props_.emplace(name, Entry{c, false}).second) Fail(c, "duplicate property");
    } else {
      Fail(c, Format("unexpected element inside <", object->Name(), ">"));
    }
  }
}

std::optional<double> Props::Float(const std::string& name) {
  const XMLElement* el = Take(name, {"float", "integer"});
  if (!el) return std::nullopt;
  CheckAttributes(el, {"name", "value"});
  const std::vector<double> v = Numbers(RequiredAttribute(el, "value"), el);
  if (v.size() != 1) Fail(el, "needs one number");
  return v[0];
}

std::optional<long long> Props::Integer(const std::string& name) {
  const XMLElement* el = Take(name, {"integer"});
  if (!el) return std::nullopt;
  CheckAttributes(el, {"name", "value"});
  const std::vector<std::string> t = Tokens(RequiredAttribute(el, "value"));
  long long value = 0;
  const char* end = t.size() == 1 ? t[0].data() + t[0].size() : nullptr;
  if (t.size() != 1 || std::from_chars(t[0].data(), end, value).ptr != end) {
    Fail(el, "value is not an integer");
  }
  return value;
}

std::optional<bool> Props::Boolean(const std::string& name) {
  const XMLElement* el = Take(name, {"boolean"});
  if (!el) return std::nullopt;
  CheckAttributes(el, {"name", "value"});
  std::string v = RequiredAttribute(el, "value");
  for (char& ch : v) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (v != "true" && v != "false") Fail(el, "value must be \"true\" or \"false\"");
  return v == "true";
}

std::optional<std::string> Props::String(const std::string& name) {
  const XMLElement* el = Take(name, {"string"});
  if (!el) return std::nullopt;
  CheckAttributes(el, {"name", "value"});
  return RequiredAttribute(el, "value");
}

std::optional<Vector3d> Props::Point(const std::string& name) {
  const XMLElement* el = Take(name, {"point", "vector"});
  if (!el) return std::nullopt;
  CheckAttributes(el, {"name", "value", "x", "y", "z"});
  return Xyz(el, std::nullopt);
}

std::optional<Vector3d> Props::Color(const std::string& name) {
  const XMLElement* el = Take(name, {"rgb", "spectrum", "float"});
  if (!el) return std::nullopt;
  CheckAttributes(el, {"name", "value"});
  const std::string value = RequiredAttribute(el, "value");
  if (std::string(el->Name()) == "spectrum" && value.find(':') != std::string::npos) {
    Fail(el, "spectra with wavelength:value pairs are not in the subset (use <rgb>)");
  }
  const std::vector<double> v = Numbers(value, el);
  if (v.size() == 1) return Vector3d::Constant(v[0]);
  if (v.size() == 3 && std::string(el->Name()) == "rgb") return Vector3d(v[0], v[1], v[2]);
  Fail(el, Format("needs ", std::string(el->Name()) == "rgb" ? "1 or 3 values" : "1 value",
                  ", got ", v.size()));
}

std::optional<Matrix4d> Props::Transform(const std::string& name) {
  const XMLElement* el = Take(name, {"transform"});
  if (!el) return std::nullopt;
  return ParseTransform(el);
}

void Props::Finish() const {
  for (const auto& [name, entry] : props_) {
    if (!entry.used) {
      Fail(entry.el, Format("property '", name, "' is not supported by <", object_->Name(),
                            " type=\"", object_->Attribute("type"), "\"> in the subset"));
    }
  }
}

const XMLElement* Props::Take(const std::string& name, std::initializer_list<const char*> tags) {
  auto it = props_.find(name);
  if (it == props_.end()) return nullptr;
  it->second.used = true;
  for (const char* t : tags) {
    if (std::string(t) == it->second.el->Name()) return it->second.el;
  }
  Fail(it->second.el, Format("property '", name, "' has the wrong type"));
}

// ------------------------------------------------------------------------------------------------
// The perspective sensor.

double HorizontalFov(const XMLElement* el, Props* p, double aspect) {
  const std::optional<double> fov = p->Float("fov");
  const std::optional<std::string> focal = p->String("focal_length");
  const std::optional<std::string> fov_axis = p->String("fov_axis");
  if (fov && focal) Fail(el, "give only one of 'fov' and 'focal_length'");
  if (!fov && fov_axis) Fail(el, "'fov_axis' needs 'fov'");
  double given = 0.0;
  std::string axis = "diagonal";
  if (fov) {
    given = *fov;
    axis = fov_axis.value_or("x");
    for (char& ch : axis) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (axis == "smaller") axis = aspect > 1 ? "y" : "x";
    if (axis == "larger") axis = aspect > 1 ? "x" : "y";
  } else {
    std::string f = focal.value_or("50mm");
    if (f.size() > 2 && f.substr(f.size() - 2) == "mm") f.resize(f.size() - 2);
    given = Degrees(2.0 * std::atan(std::sqrt(36.0 * 36.0 + 24.0 * 24.0) / (2.0 * Number(f, el))));
  }
  double x_fov = 0.0;
  if (axis == "x") {
    x_fov = given;
  } else if (axis == "y") {
    x_fov = Degrees(2.0 * std::atan(std::tan(0.5 * Radians(given)) * aspect));
  } else if (axis == "diagonal") {
    const double width =
        2.0 * std::tan(0.5 * Radians(given)) / std::sqrt(1.0 + 1.0 / (aspect * aspect));
    x_fov = Degrees(2.0 * std::atan(0.5 * width));
  } else {
    Fail(el, Format("fov_axis '", axis, "' is not one of x, y, diagonal, smaller, larger"));
  }
  if (!(x_fov > 0.0 && x_fov < 180.0))
    Fail(el, Format("horizontal fov ", x_fov, " is not in (0, 180) degrees"));
  return x_fov;
}

CameraToWorld SplitCameraToWorld(const XMLElement* el, const Matrix4d& to_world) {
  const Matrix3d m = to_world.topLeftCorner<3, 3>();
  const double deviation = (m * m.transpose() - Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(deviation <= kCameraScaleTolerance) || m.determinant() < 0.0) {
    Fail(el, Format("the camera's to_world must be a rotation and translation, with no scale or "
                    "shear beyond Mitsuba's tolerance (M M^T - I up to ",
                    kCameraScaleTolerance, ", here ", deviation, ") and no mirror"));
  }
  CameraToWorld out;
  for (int c = 0; c < 3; ++c) {
    const double norm = m.col(c).norm();
    out.scale[c] = std::abs(norm - 1.0) <= 1e-12 ? 1.0 : norm;
  }
  const Eigen::JacobiSVD<Matrix3d> svd(m * out.scale.cwiseInverse().asDiagonal(),
                                       Eigen::ComputeFullU | Eigen::ComputeFullV);
  out.rigid = to_world;
  out.rigid.topLeftCorner<3, 3>() = svd.matrixU() * svd.matrixV().transpose();
  return out;
}

// ------------------------------------------------------------------------------------------------
// PLY colour attributes, read as Mitsuba's PLY loader reads them (src/shapes/ply.cpp: integer
// properties get Struct::Flags::Normalized | Gamma, "red" is renamed "r" when there is no "r").

namespace {

struct PlyType {
  const char* names[2];
  int size;   // bytes
  char kind;  // 'i' signed integer, 'u' unsigned integer, 'f' floating point
};
constexpr PlyType kPlyTypes[] = {{{"char", "int8"}, 1, 'i'},     {{"uchar", "uint8"}, 1, 'u'},
                                 {{"short", "int16"}, 2, 'i'},   {{"ushort", "uint16"}, 2, 'u'},
                                 {{"int", "int32"}, 4, 'i'},     {{"uint", "uint32"}, 4, 'u'},
                                 {{"float", "float32"}, 4, 'f'}, {{"double", "float64"}, 8, 'f'}};

const PlyType* FindPlyType(const std::string& name) {
  for (const PlyType& t : kPlyTypes) {
    if (name == t.names[0] || name == t.names[1]) return &t;
  }
  return nullptr;
}

struct PlyProperty {
  std::string name;
  const PlyType* type = nullptr;
  const PlyType* count = nullptr;  // a list's length type; null for a scalar
};
struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

// The header's elements; *data_begin is the first byte after the end_header line.
std::vector<PlyElement> PlyHeader(const std::string& data, const std::string& name, bool* ascii,
                                  size_t* data_begin) {
  std::vector<PlyElement> elements;
  std::istringstream header(data.substr(0, std::min<size_t>(data.size(), 1 << 20)));
  std::string line, format;
  for (bool first = true; std::getline(header, line); first = false) {
    std::istringstream words(line);
    std::string keyword, type, count;
    words >> keyword;
    if (first && keyword != "ply") throw Error(Format(name, ": not a PLY file"));
    if (keyword == "format") words >> format;
    if (keyword == "element") elements.emplace_back();
    if (keyword == "element") words >> elements.back().name >> elements.back().count;
    if (keyword == "property" && !elements.empty()) {
      PlyProperty p;
      words >> type;
      if (type == "list") words >> count >> type;
      words >> p.name;
      p.type = FindPlyType(type);
      p.count = count.empty() ? nullptr : FindPlyType(count);
      if (!p.type || (!count.empty() && !p.count))
        throw Error(Format(name, ": unknown PLY type in '", line, "'"));
      elements.back().properties.push_back(p);
    }
    if (keyword == "end_header") {
      if (format != "ascii" && format != "binary_little_endian")
        throw Error(Format(name, ": PLY format '", format, "' is not supported"));
      *ascii = format == "ascii";
      *data_begin = static_cast<size_t>(header.tellg());
      return elements;
    }
  }
  throw Error(Format(name, ": PLY header without end_header"));
}

// The values after the header, one at a time: nullopt at the end of the data or on a token that
// is not a number.
class PlyValues {
 public:
  PlyValues(const std::string& data, size_t begin, bool ascii)
      : data_(data), pos_(begin), ascii_(ascii) {}

  std::optional<double> Next(const PlyType& type) {
    if (ascii_) {
      const auto space = [this] { return std::isspace(static_cast<unsigned char>(data_[pos_])); };
      while (pos_ < data_.size() && space()) ++pos_;
      const size_t begin = pos_;
      while (pos_ < data_.size() && !space()) ++pos_;
      double v = 0.0;
      const auto r = std::from_chars(data_.data() + begin, data_.data() + pos_, v);
      if (begin == pos_ || r.ptr != data_.data() + pos_) return std::nullopt;
      return v;
    }
    const size_t n = static_cast<size_t>(type.size);
    if (data_.size() - pos_ < n) return std::nullopt;
    const char* p = data_.data() + pos_;
    pos_ += n;
    if (type.kind == 'f') {
      float f;
      double d;
      return n == 4 ? (std::memcpy(&f, p, 4), f) : (std::memcpy(&d, p, 8), d);
    }
    uint64_t u = 0;  // little-endian, as the host
    std::memcpy(&u, p, n);
    const uint64_t sign = type.kind == 'i' ? uint64_t{1} << (8 * n - 1) : 0;
    return static_cast<double>(static_cast<int64_t>(u ^ sign) - static_cast<int64_t>(sign));
  }

 private:
  const std::string& data_;
  size_t pos_;
  bool ascii_;
};

// The properties of `e` that Mitsuba makes its colour: r/g/b, else red/green/blue; -1 without.
std::array<int, 3> ColorChannels(const PlyElement& e) {
  for (const auto& names : {std::array<std::string, 3>{"r", "g", "b"},
                            std::array<std::string, 3>{"red", "green", "blue"}}) {
    std::array<int, 3> out = {-1, -1, -1};
    for (size_t p = 0; p < e.properties.size(); ++p) {
      for (size_t c = 0; c < 3; ++c) {
        if (e.properties[p].name == names[c]) out[c] = static_cast<int>(p);
      }
    }
    if (*std::min_element(out.begin(), out.end()) >= 0) return out;
  }
  return {-1, -1, -1};
}

}  // namespace

std::vector<Eigen::Vector3f> PlyColorAttribute(const fs::path& file, const std::string& element,
                                               const XMLElement* el) {
  const std::string name = file.string(), attribute = element + "_color";
  try {
    const std::string data = ReadTextFile(file);
    bool ascii = false;
    size_t begin = 0;
    const std::vector<PlyElement> elements = PlyHeader(data, name, &ascii, &begin);
    size_t target = 0;
    while (target < elements.size() && elements[target].name != element) ++target;
    if (target == elements.size()) throw Error(Format(name, ": no '", element, "' element"));
    const PlyElement& e = elements[target];
    const std::array<int, 3> channel = ColorChannels(e);
    if (channel[0] < 0) {
      throw Error(Format(name, ": the ", element,
                         " element has no r/g/b or red/green/blue properties, so Mitsuba gives "
                         "the mesh no ",
                         attribute, " attribute"));
    }
    const PlyType* type = e.properties[static_cast<size_t>(channel[0])].type;
    for (const PlyProperty& p : e.properties) {
      if (p.name == "a" || p.name == "alpha")
        throw Error(Format(name, ": ", attribute, " with alpha is not in the subset"));
    }
    for (int c : channel) {
      const PlyProperty& p = e.properties[static_cast<size_t>(c)];
      if (p.type != type || p.count || type->kind == 'i') {
        throw Error(Format(name, ": ", attribute,
                           " needs three float or three unsigned integer properties of one type"));
      }
    }
    if (e.count > data.size()) throw Error(Format(name, ": truncated PLY data"));
    const double top = std::ldexp(1.0, 8 * type->size) - 1.0;  // integers: normalised by this
    std::vector<Eigen::Vector3f> colors;
    colors.reserve(static_cast<size_t>(e.count));
    PlyValues values(data, begin, ascii);
    const auto next = [&](const PlyType& t) {
      const std::optional<double> v = values.Next(t);
      if (!v) throw Error(Format(name, ": truncated or malformed PLY data"));
      return *v;
    };
    for (size_t i = 0; i <= target; ++i) {
      for (uint64_t record = 0; record < elements[i].count; ++record) {
        Eigen::Vector3f color = Eigen::Vector3f::Zero();
        for (size_t p = 0; p < elements[i].properties.size(); ++p) {
          const PlyProperty& prop = elements[i].properties[p];
          for (double k = 0, n = prop.count ? next(*prop.count) : 0.0; k < n; ++k) next(*prop.type);
          if (prop.count) continue;
          const double v = next(*prop.type);
          for (int c = 0; c < 3; ++c) {
            if (i != target || channel[static_cast<size_t>(c)] != static_cast<int>(p)) continue;
            color[c] = type->kind == 'f' ? static_cast<float>(v)
                                         : SrgbToLinear(static_cast<float>(v / top));
          }
        }
        if (i == target) colors.push_back(color);
      }
    }
    return colors;
  } catch (const Error& e) {
    Fail(el, e.what());
  }
}

}  // namespace genscene::render::mitsuba_detail
