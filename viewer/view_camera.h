// The viewer's camera: an OpenCV pinhole (core/camera.h) with a world_from_camera pose, its
// OpenGL clip matrix, the orbit / pan / zoom controller of the window, and the --camera names.
// Pure math, no OpenGL: tested without a display.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/view_set.h"

namespace genscene::viewer {

// Near and far clip planes in meters, chosen from the scene size.
struct ClipRange {
  double near_m = 0.01;
  double far_m = 100.0;
};

// OpenGL clip-from-camera matrix for OpenCV intrinsics. Pixel (u, v) of the OpenCV image (centre
// convention, v down) lands on the centre of window pixel (u, H - 1 - v): after glReadPixels the
// rows are flipped once and the image matches CameraIntrinsics::Project exactly.
//   x_clip = (2 fx / W) x + (2 (cx + 0.5) / W - 1) z
//   y_clip = -(2 fy / H) y + (1 - 2 (cy + 0.5) / H) z
//   z_clip = (f + n) / (f - n) z - 2 f n / (f - n),   w_clip = z
Eigen::Matrix4f ClipFromCamera(const CameraIntrinsics& intrinsics, const ClipRange& range);

// ClipFromCamera * camera_from_world.
Eigen::Matrix4f ClipFromWorld(const PosedView& view, const ClipRange& range);

// Intrinsics of a W x H image with horizontal field of view `hfov_degrees`, square pixels and the
// principal point in the middle ((W - 1) / 2).
CameraIntrinsics DefaultIntrinsics(int width, int height, double hfov_degrees = 60.0);

// Clip planes that enclose `bounds` seen from `eye` (near at least 1 mm, far/near <= 1e5).
ClipRange ClipRangeFor(const Eigen::AlignedBox3d& bounds, const Eigen::Vector3d& eye);

// Orbit camera: the eye sits on a sphere around `target`, at an azimuth about the world's `up`
// and an elevation above the plane normal to it. Azimuth 0 is the direction of `Horizontal()[0]`
// (+x for up = +z), pi/2 that of `Horizontal()[1]` (+y for up = +z).
struct OrbitController {
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  double distance = 3.0;       // meters from the target
  double azimuth = -M_PI / 2;  // radians about `up`; -pi/2 = the eye on the -y side for up = +z
  double elevation = 0.35;     // radians above the plane normal to `up`, within +-89 degrees
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // unit world up (image up of the camera)

  // The unit horizontal axes (e1, e2) with e1 x e2 = up: (+x, +y) for up = +z.
  std::pair<Eigen::Vector3d, Eigen::Vector3d> Horizontal() const;

  Eigen::Vector3d Eye() const;
  Eigen::Isometry3d WorldFromCamera() const;
  // Mouse drag by (dx, dy) pixels: turn (0.005 rad per pixel).
  void Rotate(double dx, double dy);
  // Mouse drag by (dx, dy) pixels: move the target in the image plane, so that a point at the
  // target follows the cursor for focal length `fx` pixels.
  void Pan(double dx, double dy, double fx);
  // Scroll by `steps`: distance scaled by 0.9^steps.
  void Zoom(double steps);
  // The controller whose eye and viewing direction are those of `world_from_camera` (roll about
  // `up` is dropped), looking at a target `distance` meters ahead.
  static OrbitController FromPose(const Eigen::Isometry3d& world_from_camera, double distance,
                                  const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());
};

// The world's up as the recording's cameras saw it: the mean of their image-up axes (-y of an
// OpenCV camera); +z without cameras or when they disagree.
Eigen::Vector3d CamerasUp(const std::vector<Eigen::Isometry3d>& world_from_cameras);

// The overview: the bounding sphere of `bounds` fills 1.1 times the narrower field of view.
// Without cameras, seen from the -y side and 20 degrees above, +z up. With the recording's cameras,
// up is theirs (CamerasUp) and the eye looks along their mean viewing direction, from at least 20
// and at most 60 degrees above the horizontal, so that a scan is seen as it was recorded, from
// above.
OrbitController OverviewOrbit(const Eigen::AlignedBox3d& bounds, const CameraIntrinsics& intrinsics,
                              const std::vector<Eigen::Isometry3d>& world_from_cameras = {});

// --camera: "overview", "keyframe:N" (N-th keyframe, 0-based) or "tx ty tz qx qy qz qw"
// (world_from_camera, TUM order).
struct CameraSpec {
  enum class Kind { kOverview, kKeyframe, kPose };
  Kind kind = Kind::kOverview;
  int keyframe = 0;
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
};
// Throws Error quoting the text when it is none of the three forms.
CameraSpec ParseCameraSpec(const std::string& text);

// "WxH" -> (W, H), each in [16, 8192]; throws Error quoting the text otherwise.
Eigen::Vector2i ParseSize(const std::string& text);

}  // namespace genscene::viewer
