#include "core/trajectory_metrics.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>

#include "core/check.h"

namespace genscene {

namespace {

// (estimated index, ground-truth position) pairs, sorted by the estimated index.
std::vector<std::pair<size_t, Eigen::Vector3d>> NearestPairs(const Trajectory& estimated,
                                                             const Trajectory& ground_truth,
                                                             double max_time_difference) {
  // As TUM's associate.py: all candidate pairs within the limit, closest first, each used once.
  std::vector<std::tuple<double, size_t, size_t>> candidates;
  const auto& est = estimated.poses();
  const auto& gt = ground_truth.poses();
  for (size_t i = 0; i < est.size(); ++i) {
    const double t = est[i].timestamp;
    const auto first =
        std::lower_bound(gt.begin(), gt.end(), t - max_time_difference,
                         [](const StampedPose& p, double x) { return p.timestamp < x; });
    for (auto it = first; it != gt.end() && it->timestamp <= t + max_time_difference; ++it) {
      candidates.emplace_back(std::abs(it->timestamp - t), i, static_cast<size_t>(it - gt.begin()));
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::set<size_t> used_est, used_gt;
  std::vector<std::pair<size_t, Eigen::Vector3d>> pairs;
  for (const auto& [dt, i, j] : candidates) {
    if (used_est.count(i) || used_gt.count(j)) continue;
    used_est.insert(i);
    used_gt.insert(j);
    pairs.emplace_back(i, gt[j].world_from_camera.translation());
  }
  std::sort(pairs.begin(), pairs.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  return pairs;
}

std::vector<std::pair<size_t, Eigen::Vector3d>> InterpolatedPairs(const Trajectory& estimated,
                                                                  const Trajectory& ground_truth,
                                                                  double max_time_difference) {
  std::vector<std::pair<size_t, Eigen::Vector3d>> pairs;
  const auto& est = estimated.poses();
  for (size_t i = 0; i < est.size(); ++i) {
    const double t = est[i].timestamp;
    if (auto p = ground_truth.Interpolate(t, 2.0 * max_time_difference)) {
      pairs.emplace_back(i, p->translation());
    } else if (auto q = ground_truth.Nearest(t, max_time_difference)) {
      pairs.emplace_back(i, q->world_from_camera.translation());
    }
  }
  return pairs;
}

}  // namespace

AteResult ComputeAte(const Trajectory& estimated, const Trajectory& ground_truth,
                     double max_time_difference, AteAssociation association) {
  const auto& est = estimated.poses();
  const auto pairs = association == AteAssociation::kNearest
                         ? NearestPairs(estimated, ground_truth, max_time_difference)
                         : InterpolatedPairs(estimated, ground_truth, max_time_difference);
  if (pairs.size() < 3) {
    throw Error(Format("ATE: only ", pairs.size(), " of ", est.size(),
                       " estimated poses have a ground-truth pose within ", max_time_difference,
                       " s; need at least 3"));
  }
  // Positions relative to their first pair, so that 1 km from the origin loses no precision.
  const Eigen::Vector3d est_ref = est[pairs[0].first].world_from_camera.translation();
  const Eigen::Vector3d gt_ref = pairs[0].second;
  Eigen::Matrix3Xd src(3, pairs.size()), dst(3, pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    src.col(static_cast<Eigen::Index>(k)) =
        est[pairs[k].first].world_from_camera.translation() - est_ref;
    dst.col(static_cast<Eigen::Index>(k)) = pairs[k].second - gt_ref;
  }
  const Eigen::Matrix4d m = Eigen::umeyama(src, dst, /*with_scaling=*/false);
  Eigen::Isometry3d local = Eigen::Isometry3d::Identity();
  local.matrix() = m;
  std::vector<double> errors(pairs.size());
  double sum = 0.0, sum_sq = 0.0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    errors[k] =
        (local * src.col(static_cast<Eigen::Index>(k)) - dst.col(static_cast<Eigen::Index>(k)))
            .norm();
    sum += errors[k];
    sum_sq += errors[k] * errors[k];
  }
  AteResult result;
  result.pairs = pairs.size();
  result.rmse = std::sqrt(sum_sq / static_cast<double>(pairs.size()));
  result.mean = sum / static_cast<double>(pairs.size());
  result.max = *std::max_element(errors.begin(), errors.end());
  std::nth_element(errors.begin(), errors.begin() + static_cast<long>(errors.size() / 2),
                   errors.end());
  result.median = errors[errors.size() / 2];
  // gt = gt_ref + L (est - est_ref)  =>  alignment = T(gt_ref) L T(-est_ref).
  result.alignment = Eigen::Translation3d(gt_ref) * local * Eigen::Translation3d(-est_ref);
  return result;
}

}  // namespace genscene
