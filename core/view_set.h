// View sets (DESIGN.md §2): a folder with intrinsics.txt, groundtruth.txt (TUM poses) and
// rgb.txt (TUM list of images, EXR = linear or PNG = sRGB), optionally depth.txt. This reads the
// cameras only, so that a view set can be rendered before its images exist; the images are read
// by the frame sources (frame_source.h).
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <vector>

#include "core/camera.h"
#include "core/image.h"

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

// A posed image: the camera and its linear RGB image, of the intrinsics' size (the training views
// of the light estimate, the references of vertex refinement, the held-out frames).
struct PosedImage {
  PosedView view;
  ImageRgb image;
};

// The posed images of a view set or keyframes folder, read through the TUM frame source: EXR as
// linear, PNG as sRGB. Throws Error when the folder is missing, empty, or an image has no pose or
// no colour.
std::vector<PosedImage> ReadPosedImages(const std::filesystem::path& folder);

}  // namespace genscene
