// A pose from colour features, for a frame that ICP cannot track from the last pose (the camera
// jumped, or a sparse recording's frames lie far apart: ICP's projective association only
// converges within a few centimetres and degrees). ORB keypoints (Rublee et al. 2011) of a
// reference frame with depth and of the live frame are matched by Hamming distance (Lowe's ratio
// test, mutual best matches only); the reference's keypoints are back-projected with its depth,
// and the live camera's pose follows from the 3D-2D matches by PnP in RANSAC (OpenCV's
// solvePnPRansac, refined on its inliers). The result is only a start: the caller refines it by
// ICP against the model and accepts it only if ICP agrees.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <optional>

#include "core/camera.h"
#include "core/image.h"

namespace genscene::fusion {

struct FeatureAlignOptions {
  // ORB keypoints per image. slambook joinMap (5 frames, 0.3-0.7 m and 15-25 deg apart): with
  // 1000 or 1500 frame 1's pose fails the ICP check and frames 2-4 are then too far from frame 0:
  // 4 lost; 2000 tracks all five (ATE 1.9 cm against the book's poses), 3000 and more 1.5 cm
  // (FAST finds about 2000 corners in those 640x480 frames).
  int max_features = 3000;
  double ratio = 0.8;               // best / second-best Hamming distance below this is a match
  int min_inliers = 30;             // fewer PnP inliers = no pose
  double reprojection_error = 3.0;  // px; a match farther from its projection is an outlier

  void Validate() const;
};

struct FeatureAlignReport {
  int reference_keypoints = 0;
  int live_keypoints = 0;
  int matches = 0;  // ratio-tested mutual matches with reference depth
  int inliers = 0;  // of which consistent with the PnP pose
};

// The ORB keypoints and descriptors of one colour image, detected once and matched against many
// (relocalisation matches a lost frame against every keyframe, each keyframe against many lost
// frames). Empty when made from an empty image.
class FeatureFrame {
 public:
  FeatureFrame() = default;
  FeatureFrame(const ImageRgb& color, int max_features);
  bool empty() const { return !data_; }
  struct Data;  // OpenCV's keypoints and descriptors (feature_align.cpp)
  const Data& data() const { return *data_; }

 private:
  std::shared_ptr<const Data> data_;
};

// reference_from_live: the live camera in the reference camera's frame, or nothing when the
// frames share too few features. The reference's keypoints are back-projected with
// `reference_depth` (planar metres, 0 = none; the size of the image its features came from);
// both frames seen through `intrinsics`. Colour for FeatureFrame is linear RGB.
std::optional<Eigen::Isometry3d> AlignByFeatures(const FeatureFrame& reference,
                                                 const ImageDepth& reference_depth,
                                                 const FeatureFrame& live,
                                                 const CameraIntrinsics& intrinsics,
                                                 const FeatureAlignOptions& options,
                                                 FeatureAlignReport* report = nullptr);

}  // namespace genscene::fusion
