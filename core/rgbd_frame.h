// One RGB-D frame as every stage sees it: linear colour, planar depth in meters, intrinsics,
// timestamp and, when the source knows it, the camera pose.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/image.h"

namespace genscene {

struct RgbdFrame {
  double timestamp = 0.0;  // seconds (TUM: the colour image's time stamp)
  ImageRgb color;          // linear RGB; same size as depth when both are present
  ImageDepth depth;        // planar z in meters, 0 = no measurement; empty for colour-only views
  CameraIntrinsics intrinsics;
  // Known camera pose (ground truth or given poses), if the source has one for this frame.
  std::optional<Eigen::Isometry3d> world_from_camera;
  std::string color_path;  // where the images came from, for messages (may be empty)
  std::string depth_path;

  // Throws Error naming the files when images and intrinsics disagree in size
  // ("depth 640x480 but intrinsics say 320x240"), colour and depth are both missing, or depth
  // holds NaN, infinite or negative values.
  void Validate() const;
};

}  // namespace genscene
