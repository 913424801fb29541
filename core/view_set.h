// View sets (DESIGN.md §2): a folder with intrinsics.txt, groundtruth.txt (TUM poses) and
// rgb.txt (TUM list of images, EXR = linear or PNG = sRGB), optionally depth.txt. This reads the
// cameras only, so that a view set can be rendered before its images exist; the images are read
// by the frame sources (frame_source.h).
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <vector>

#include "core/camera.h"

namespace genscene {

// A posed pinhole camera.
struct PosedView {
  CameraIntrinsics intrinsics;
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  double timestamp = 0.0;  // seconds, or the view index in view sets made of renders
};

// The views of a view set, in the order of rgb.txt when present (else of groundtruth.txt): each
// with the folder's intrinsics and the pose of the same timestamp (within 1e-6 s). Throws Error
// naming the file when intrinsics or poses are missing, or an image has no pose.
std::vector<PosedView> ReadViewSet(const std::filesystem::path& dir);

}  // namespace genscene
