// Trajectory error as TUM's evaluate_ate.py computes it (Sturm et al. 2012): estimated and
// ground-truth poses are associated by timestamp (each pair at most max_time_difference apart,
// closest pairs first, each pose used once), the estimated positions are aligned to the ground
// truth by the rigid transform of least squares (Horn 1987, no scale), and the absolute
// trajectory error is the RMSE of the remaining translational differences.
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

// Throws Error when fewer than 3 poses can be associated (no alignment is defined).
AteResult ComputeAte(const Trajectory& estimated, const Trajectory& ground_truth,
                     double max_time_difference = 0.02);

}  // namespace genscene
