// Frame-to-model tracking (KinectFusion §3.5): projective data association of the live frame's
// vertex map with the model raycast at the previous pose, point-to-plane Gauss-Newton, coarse to
// fine over the depth pyramid. Every iteration solves the 6x6 normal equations only in the
// directions the scene constrains: a direction whose eigenvalue is below
// `degenerate_eigen_ratio` of the largest (a plane slides along itself and turns about its
// normal) keeps the previous estimate instead of taking a wild step, and the frame is reported
// as degenerate.
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "core/camera.h"
#include "fusion/preprocess.h"
#include "fusion/raycast.h"

namespace genscene::fusion {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct IcpOptions {
  int iterations_fine = 10;   // Gauss-Newton iterations at full resolution (KinectFusion: 10)
  int iterations_middle = 5;  // at half resolution (5)
  int iterations_coarse = 4;  // at quarter resolution (4)
  double max_distance = 0.1;  // m; correspondences farther apart are rejected
  double max_angle = 30.0;    // degrees between normals; larger is rejected
  double huber_delta = 0.01;  // m; robust (Huber) weight beyond this point-to-plane residual
  // A level's iterations stop once a step moves the pose less than this (|xi|: metres and
  // radians). On the 150-frame synthetic room (Kinect-like noise) 1e-5 took 14 instead of 19
  // steps a frame (tracking 17.6 -> 10.7 ms) for the same ATE (5.13 mm); 1e-7 ran every
  // iteration. Measured: 5e-5 takes 11.7 steps (tracking -20 %) for ATE 5.149 mm against 5.141
  // (2e-4: 9.7 steps, 5.19 mm); TUM fr1/desk 9 frames 1.774 mm against 1.773.
  double min_step = 5e-5;
  // Eigenvalue / largest below this = unconstrained direction (rotation scaled to metres).
  // Measured at full resolution: a pure plane's three free directions reach 4.1e-4 (noise of
  // the raycast normals); the weakest direction of the small Cornell room at 160x120 is 1.3e-3,
  // of TUM fr1/desk 7.3e-3. The default sits between, a factor ~2 from each.
  double degenerate_eigen_ratio = 7e-4;
  double min_inlier_ratio =
      0.3;  // fraction of valid live pixels with a correspondence; below = lost
  double max_rms_residual = 0.02;  // m; above = lost
  double max_translation = 0.3;    // m between consecutive frames; above = lost (a jump)
  double max_rotation = 30.0;      // degrees between consecutive frames; above = lost
  // The photometric term (when both frames have colour): each live pixel's brightness against
  // that of the frame the model was raycast from, where its point lands there (Steinbruecker et
  // al. 2011; ElasticFusion and Open3D's hybrid odometry add it to point-to-plane ICP likewise),
  // in metres per unit of brightness: the residual and its derivative are scaled by it to sit
  // beside the point-to-plane residual in metres. It fixes the directions a wall or a floor
  // leaves free to the geometry where the surface has texture. 0 = geometry only.
  double color_weight = 0.1;
  double color_huber = 0.05;  // brightness; Huber threshold of the photometric residual

  void Validate() const;
};

struct IcpReport {
  int iterations = 0;         // Gauss-Newton steps taken over all levels
  size_t valid_pixels = 0;    // live pixels with a vertex and a normal, full resolution
  size_t inliers = 0;         // of which with an accepted correspondence (last iteration)
  double inlier_ratio = 0.0;  // inliers / valid_pixels
  double rms_residual = 0.0;  // m, point-to-plane, over the inliers
  size_t color_pixels = 0;    // pixels with a photometric residual (last pass, full resolution)
  double color_rms = 0.0;     // their RMS brightness difference
  double condition = 0.0;     // largest / smallest eigenvalue of J^T J (rotation scaled to metres)
  int constrained_directions = 0;  // of 6
  bool degenerate = false;         // some direction was unconstrained
  // Information (inverse covariance) of the result: J^T J of the final pass (Huber weights, both
  // terms) over the variance of the point-to-plane residual (its RMS, at least 1 mm), for a left
  // perturbation xi = [translation (m); rotation (rad)] of model_from_live (the pose moves to
  // exp(xi) model_from_live). Zero with fewer than 6 inliers.
  Matrix6d information = Matrix6d::Zero();
};

// Refines `model_from_live` (the live camera in the frame of the camera the model was raycast
// from; start: the motion prediction, e.g. identity) in place. `model` is the raycast at full
// resolution with intrinsics `model_intrinsics`; `live` the live frame's pyramid (level 0 finest).
// With `live_intensity` and `model_intensity` (BuildIntensityPyramid of the live frame and of the
// frame whose pose the model was raycast at, as many levels as `live`) and color_weight > 0, the
// photometric term joins the point-to-plane one at every level, on the pixels whose point has a
// model correspondence (within max_distance and max_angle: a point the model's frame saw). A
// tighter gate (3 Huber thresholds) left half the pixels of a noisy far view out at the
// coarsest level, whose first step then slid 10 cm along a wall.
IcpReport TrackFrameToModel(const std::vector<PyramidLevel>& live, const RaycastResult& model,
                            const CameraIntrinsics& model_intrinsics, const IcpOptions& options,
                            Eigen::Isometry3d* model_from_live,
                            const std::vector<IntensityLevel>* live_intensity = nullptr,
                            const std::vector<IntensityLevel>* model_intensity = nullptr);

}  // namespace genscene::fusion
