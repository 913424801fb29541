// Internal to the Mitsuba XML code: the helpers that both the import (mitsuba_xml.cpp) and the
// export (mitsuba_xml_export.cpp) use. Not part of the library's interface; include it only from
// those two files. The public API is in mitsuba_xml.h.
#pragma once

#include <Eigen/Core>

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

}  // namespace genscene::render::mitsuba_detail
