// Internal to the Mitsuba XML code, not part of the library's interface (the public API is in
// mitsuba_xml.h); include it only from the mitsuba_xml*.cpp files. It holds the angle and matrix
// helpers that the import (mitsuba_xml.cpp) and the export (mitsuba_xml_export.cpp) share, and the
// element-level helpers of the import, defined in mitsuba_xml_elements.cpp: where an element is,
// attribute and number checks, the properties of one object element (Props), the perspective
// sensor's field of view and pose, and the colour attributes of PLY files.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace tinyxml2 {
class XMLElement;
}  // namespace tinyxml2

namespace genscene::render::mitsuba_detail {

constexpr double kPi = 3.14159265358979323846;
inline double Radians(double degrees) {
  return degrees * kPi / 180.0;
}
inline double Degrees(double radians) {
  return radians * 180.0 / kPi;
}

// The 4x4 matrix of the affine map x -> linear * x + translation.
inline Eigen::Matrix4d Affine(const Eigen::Matrix3d& linear, const Eigen::Vector3d& translation) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = linear;
  m.topRightCorner<3, 1>() = translation;
  return m;
}

// Mitsuba's envmap: a latitude-longitude image whose texel (u, v) in [0, 1)^2 holds the radiance
// arriving from the local direction d with u = atan2(d.x, -d.z) / (2 pi) (wrapped into [0, 1)),
// v = acos(d.y) / pi (+y up, row 0 at the top); `to_world` turns local into world directions.
// The direction of the texel centre (column i, row j) of a width x height image, local frame.
inline Eigen::Vector3d EnvmapDirection(int i, int j, int width, int height) {
  const double phi = 2.0 * kPi * (i + 0.5) / width, theta = kPi * (j + 0.5) / height;
  return {std::sin(theta) * std::sin(phi), std::cos(theta), -std::sin(theta) * std::cos(phi)};
}
// The size of the envmap the export writes for the distant light: its six lobes are smooth
// (linear between the axis planes), which 64 x 32 texels hold within bilinear interpolation.
constexpr int kEnvmapWidth = 64, kEnvmapHeight = 32;

// ------------------------------------------------------------------------------------------------
// Element helpers of the import (mitsuba_xml_elements.cpp). The § numbers are the sections of the
// subset in mitsuba_xml.h.

// "file:line: <shape type="ply" id="floor">" (each document carries its path as user data).
std::string Where(const tinyxml2::XMLElement* el);

// Throws an Error "Where(el): what".
[[noreturn]] void Fail(const tinyxml2::XMLElement* el, const std::string& what);

// Fails on an attribute of `el` that is not in `allowed`.
void CheckAttributes(const tinyxml2::XMLElement* el, std::initializer_list<const char*> allowed);

// The attribute's value; fails when it is missing.
std::string RequiredAttribute(const tinyxml2::XMLElement* el, const char* name);

// Lists split on commas and spaces only (§1); empty tokens are dropped.
std::vector<std::string> Tokens(const std::string& text);

// One finite number (the whole token); fails naming `el` otherwise.
double Number(const std::string& token, const tinyxml2::XMLElement* el);

// Whether the tag names an object (shape, bsdf, emitter, sensor, ...) rather than a property.
bool IsObjectTag(const std::string& tag);

// The `type` attribute, or "" without one.
std::string Type(const tinyxml2::XMLElement* el);

// The properties of one object element. Every getter marks its property as used; Finish() fails
// on properties nobody read, as Mitsuba HEAD does (§1).
class Props {
 public:
  // Sorts the children of `object`: nested objects and <ref>s (resolved by `resolve_ref`) go to
  // children(), named properties to the getters; anything else fails.
  Props(tinyxml2::XMLElement* object,
        const std::function<tinyxml2::XMLElement*(tinyxml2::XMLElement*)>& resolve_ref);

  std::optional<double> Float(const std::string& name);
  std::optional<long long> Integer(const std::string& name);
  std::optional<bool> Boolean(const std::string& name);
  std::optional<std::string> String(const std::string& name);
  std::optional<Eigen::Vector3d> Point(const std::string& name);
  // rgb (1 or 3 values), a float, or a spectrum with a single value (a constant).
  std::optional<Eigen::Vector3d> Color(const std::string& name);
  // A <transform> (§4): each element left-multiplies the transform built so far.
  std::optional<Eigen::Matrix4d> Transform(const std::string& name);
  const std::vector<tinyxml2::XMLElement*>& children() const { return children_; }

  void Finish() const;

 private:
  struct Entry {
    tinyxml2::XMLElement* el;
    bool used;
  };
  const tinyxml2::XMLElement* Take(const std::string& name,
                                   std::initializer_list<const char*> tags);

  tinyxml2::XMLElement* object_;
  std::map<std::string, Entry> props_;
  std::vector<tinyxml2::XMLElement*> children_;
};

// A perspective sensor's horizontal field of view in degrees from fov / fov_axis, or from
// focal_length (default 50 mm, a diagonal fov of the 36 x 24 mm frame), as Mitsuba does (§5).
double HorizontalFov(const tinyxml2::XMLElement* el, Props* p, double aspect);

// Mitsuba refuses a camera to_world M with an entry of M M^T - I beyond this (has_scale() in
// perspective.cpp); the export keeps the scale it writes for fx != fy within it.
constexpr double kCameraScaleTolerance = 1e-3;

// A perspective sensor's to_world M = R S, taken as Mitsuba takes it: Fail when an entry of
// M M^T - I is beyond kCameraScaleTolerance (Mitsuba refuses it) or M mirrors. S holds the column
// norms of M (a norm within 1e-12 of 1 is 1), R is the rotation nearest M S^-1 (files print
// matrices with a few digits; the shear Mitsuba tolerates is dropped).
struct CameraToWorld {
  Eigen::Matrix4d rigid;  // R and M's translation
  Eigen::Vector3d scale;  // the diagonal of S
};
CameraToWorld SplitCameraToWorld(const tinyxml2::XMLElement* el, const Eigen::Matrix4d& to_world);

// The vertex_color (`element` "vertex") or face_color ("face") attribute that Mitsuba 3's PLY
// loader makes of `file`: the element's r/g/b (else red/green/blue) properties, floating-point
// values as they are, unsigned integers normalised to [0, 1] and sRGB-decoded. Fails naming `el`
// when the element has no such properties, has alpha, or has signed integer colours.
std::vector<Eigen::Vector3f> PlyColorAttribute(const std::filesystem::path& file,
                                               const std::string& element,
                                               const tinyxml2::XMLElement* el);

}  // namespace genscene::render::mitsuba_detail
