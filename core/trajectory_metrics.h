// Absolute trajectory error (Sturm et al. 2012): each estimated pose is paired with the ground
// truth at its time stamp, the estimated positions are aligned to the ground truth by the rigid
// transform of least squares (Horn 1987, no scale), and the ATE is the RMSE of the remaining
// translational differences.
//
// Pairing (AteAssociation):
//   kInterpolate (default): the ground truth at the estimate's own time, interpolated between
//     the two ground-truth poses that bracket it when they are at most 2 max_time_difference
//     apart (an exact time stamp takes its pose); otherwise the nearest ground-truth pose within
//     max_time_difference. A motion-capture trajectory at 100 Hz is up to 5 ms from a frame:
//     on TUM fr1/desk (about 0.4 m/s) that is up to 2 mm, as much as the tracker's error there
//     (9 frames: 1.20 mm interpolated, 1.64 mm nearest).
//   kNearest: as TUM's evaluate_ate.py: all pairs at most max_time_difference apart, closest
//     first, each pose used once (the figures published with TUM's benchmark).
#pragma once

#include <Eigen/Geometry>

#include "core/trajectory.h"

namespace genscene {

struct AteResult {
  size_t pairs = 0;   // associated poses
  double rmse = 0.0;  // metres
  double mean = 0.0;
  double median = 0.0;
  double max = 0.0;
  // Aligns the estimate onto the ground truth: gt ~ alignment * estimated.
  Eigen::Isometry3d alignment = Eigen::Isometry3d::Identity();
};

enum class AteAssociation { kInterpolate, kNearest };

// Throws Error when fewer than 3 poses can be associated (no alignment is defined).
AteResult ComputeAte(const Trajectory& estimated, const Trajectory& ground_truth,
                     double max_time_difference = 0.02,
                     AteAssociation association = AteAssociation::kInterpolate);

}  // namespace genscene
