#include "viewer/view_camera.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/check.h"
#include "core/se3.h"

namespace genscene::viewer {

Eigen::Matrix4f ClipFromCamera(const CameraIntrinsics& k, const ClipRange& range) {
  const double w = k.width, h = k.height, n = range.near_m, f = range.far_m;
  Eigen::Matrix4d m = Eigen::Matrix4d::Zero();
  m(0, 0) = 2.0 * k.fx / w;
  m(0, 2) = 2.0 * (k.cx + 0.5) / w - 1.0;
  m(1, 1) = -2.0 * k.fy / h;
  m(1, 2) = 1.0 - 2.0 * (k.cy + 0.5) / h;
  m(2, 2) = (f + n) / (f - n);
  m(2, 3) = -2.0 * f * n / (f - n);
  m(3, 2) = 1.0;
  return m.cast<float>();
}

Eigen::Matrix4f ClipFromWorld(const PosedView& view, const ClipRange& range) {
  const Eigen::Matrix4d camera_from_world = view.world_from_camera.inverse().matrix();
  return (ClipFromCamera(view.intrinsics, range).cast<double>() * camera_from_world).cast<float>();
}

CameraIntrinsics DefaultIntrinsics(int width, int height, double hfov_degrees) {
  return CameraIntrinsics::FromHorizontalFov(width, height, hfov_degrees);
}

ClipRange ClipRangeFor(const Eigen::AlignedBox3d& bounds, const Eigen::Vector3d& eye) {
  ClipRange range;
  if (bounds.isEmpty()) return range;
  const double radius = 0.5 * bounds.diagonal().norm();
  const double to_center = (bounds.center() - eye).norm();
  range.far_m = std::max(to_center + radius, 1e-2) * 1.05;
  range.near_m = std::max({to_center - radius, range.far_m * 1e-5, 1e-3}) * 0.9;
  return range;
}

std::pair<Eigen::Vector3d, Eigen::Vector3d> OrbitController::Horizontal() const {
  // e1: +x made normal to up (+y when up is along x), e2 = up x e1.
  const Eigen::Vector3d axis =
      std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = (axis - axis.dot(up) * up).normalized();
  return {e1, up.cross(e1)};
}

Eigen::Vector3d OrbitController::Eye() const {
  const auto [e1, e2] = Horizontal();
  const Eigen::Vector3d dir = std::cos(elevation) * std::cos(azimuth) * e1 +
                              std::cos(elevation) * std::sin(azimuth) * e2 +
                              std::sin(elevation) * up;
  return target + distance * dir;
}

Eigen::Isometry3d OrbitController::WorldFromCamera() const {
  // OpenCV axes: z towards the target, x = z x up (right), y = z x x (image down).
  const Eigen::Vector3d eye = Eye();
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(up).normalized();  // |elevation| < 90
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = x;
  pose.linear().col(1) = z.cross(x);
  pose.linear().col(2) = z;
  pose.translation() = eye;
  return pose;
}

void OrbitController::Rotate(double dx, double dy) {
  constexpr double kLimit = 89.0 * M_PI / 180.0;
  azimuth -= 0.005 * dx;
  elevation = std::clamp(elevation + 0.005 * dy, -kLimit, kLimit);
}

void OrbitController::Pan(double dx, double dy, double fx) {
  const Eigen::Isometry3d pose = WorldFromCamera();
  const double meters_per_pixel = distance / fx;
  target -= meters_per_pixel * (dx * pose.linear().col(0) + dy * pose.linear().col(1));
}

void OrbitController::Zoom(double steps) {
  distance = std::max(1e-3, distance * std::pow(0.9, steps));
}

OrbitController OrbitController::FromPose(const Eigen::Isometry3d& world_from_camera,
                                          double distance, const Eigen::Vector3d& up) {
  constexpr double kLimit = 89.0 * M_PI / 180.0;
  OrbitController orbit;
  orbit.up = up.normalized();
  const auto [e1, e2] = orbit.Horizontal();
  const Eigen::Vector3d forward = world_from_camera.linear().col(2).normalized();
  orbit.distance = std::max(distance, 1e-3);
  orbit.target = world_from_camera.translation() + orbit.distance * forward;
  // The eye is at target - distance * forward, i.e. in direction -forward from the target.
  orbit.azimuth = std::atan2(-forward.dot(e2), -forward.dot(e1));
  orbit.elevation =
      std::clamp(std::asin(std::clamp(-forward.dot(orbit.up), -1.0, 1.0)), -kLimit, kLimit);
  return orbit;
}

Eigen::Vector3d CamerasUp(const std::vector<Eigen::Isometry3d>& world_from_cameras) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Eigen::Isometry3d& pose : world_from_cameras) sum -= pose.linear().col(1);
  // Cameras that roll every way have no common up: keep +z.
  if (world_from_cameras.empty() || sum.norm() < 0.5 * world_from_cameras.size())
    return Eigen::Vector3d::UnitZ();
  return sum.normalized();
}

OrbitController OverviewOrbit(const Eigen::AlignedBox3d& bounds, const CameraIntrinsics& k,
                              const std::vector<Eigen::Isometry3d>& world_from_cameras) {
  OrbitController orbit;
  orbit.azimuth = -M_PI / 2;
  orbit.elevation = 20.0 * M_PI / 180.0;
  if (!world_from_cameras.empty()) {
    Eigen::Vector3d forward = Eigen::Vector3d::Zero();
    for (const Eigen::Isometry3d& pose : world_from_cameras) forward += pose.linear().col(2);
    if (forward.norm() > 1e-9) {
      const Eigen::Isometry3d mean = Eigen::Isometry3d(
          Eigen::Translation3d(Eigen::Vector3d::Zero()) *
          Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), forward.normalized()));
      orbit = OrbitController::FromPose(mean, 1.0, CamerasUp(world_from_cameras));
      orbit.elevation = std::clamp(orbit.elevation, 20.0 * M_PI / 180.0, 60.0 * M_PI / 180.0);
    }
  }
  if (bounds.isEmpty()) return orbit;
  orbit.target = bounds.center();
  // The bounding sphere fills 1.1 times the narrower field of view: a box's outline is smaller
  // than its sphere's, so the model fills most of the image without leaving it.
  const double radius = std::max(0.5 * bounds.diagonal().norm(), 1e-3);
  const double half_fov =
      std::min(std::atan(0.5 * k.width / k.fx), std::atan(0.5 * k.height / k.fy));
  orbit.distance = 0.9 * radius / std::tan(half_fov);
  return orbit;
}

CameraSpec ParseCameraSpec(const std::string& text) {
  CameraSpec spec;
  if (text == "overview") return spec;
  const std::string bad =
      Format("--camera '", text, "' is not 'overview', 'keyframe:N' or 'tx ty tz qx qy qz qw'");
  if (text.rfind("keyframe:", 0) == 0) {
    std::istringstream in(text.substr(9));
    int n = -1;
    if (!(in >> n) || n < 0 || !(in >> std::ws).eof()) throw Error(bad);
    spec.kind = CameraSpec::Kind::kKeyframe;
    spec.keyframe = n;
    return spec;
  }
  std::istringstream in(text);
  double v[7];
  for (double& x : v) {
    if (!(in >> x) || !std::isfinite(x)) throw Error(bad);
  }
  if (!(in >> std::ws).eof()) throw Error(bad);
  spec.kind = CameraSpec::Kind::kPose;
  spec.world_from_camera = PoseFromTranslationQuaternion(
      Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Quaterniond(v[6], v[3], v[4], v[5]));
  return spec;
}

Eigen::Vector2i ParseSize(const std::string& text) {
  std::istringstream in(text);
  int w = 0, h = 0;
  char x = 0;
  if (!(in >> w >> x >> h) || (x != 'x' && x != 'X') || !(in >> std::ws).eof() || w < 16 ||
      h < 16 || w > 8192 || h > 8192) {
    throw Error(Format("--size '", text, "' is not WxH with W and H in [16, 8192]"));
  }
  return {w, h};
}

}  // namespace genscene::viewer
