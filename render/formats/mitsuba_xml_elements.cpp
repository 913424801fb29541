// Mitsuba 3 XML import, the element level (declared in mitsuba_xml_internal.h): where an element
// is, attribute and number checks, transforms (§4), the properties of one object element (Props)
// and the perspective sensor's field of view and pose. The two passes over the documents are in
// mitsuba_xml.cpp; the § numbers are the sections of the subset in mitsuba_xml.h.
#include <tinyxml2.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <set>

#include "core/check.h"
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

Matrix4d RigidCameraToWorld(const XMLElement* el, Matrix4d to_world) {
  const Matrix3d r = to_world.topLeftCorner<3, 3>();
  if (!(r.transpose() * r).isIdentity(1e-3) || r.determinant() < 0.0) {
    Fail(el,
         "the camera's to_world must be a rotation and translation (no scale, shear or mirror)");
  }
  const Eigen::JacobiSVD<Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  to_world.topLeftCorner<3, 3>() = svd.matrixU() * svd.matrixV().transpose();
  return to_world;
}

}  // namespace genscene::render::mitsuba_detail
