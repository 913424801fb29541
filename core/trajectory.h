// Camera trajectories in TUM format (DESIGN.md §1): one line per frame,
// `timestamp tx ty tz qx qy qz qw`, each pose world_from_camera. Our output is accepted as it is
// by TUM's evaluate_ate.py / evaluate_rpe.py.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <optional>
#include <vector>

namespace genscene {

struct StampedPose {
  double timestamp = 0.0;  // seconds
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
};

class Trajectory {
 public:
  Trajectory() = default;
  explicit Trajectory(std::vector<StampedPose> poses);

  const std::vector<StampedPose>& poses() const { return poses_; }
  size_t size() const { return poses_.size(); }
  bool empty() const { return poses_.empty(); }
  // Appends a pose; timestamps must be strictly increasing.
  void Add(double timestamp, const Eigen::Isometry3d& world_from_camera);

  // The pose whose timestamp is nearest to t, if it is within max_difference seconds.
  std::optional<StampedPose> Nearest(double t, double max_difference) const;
  // Pose at time t interpolated between the two bracketing poses (translation linear, rotation
  // slerp), if both exist and are at most max_gap seconds apart; exact match returns that pose.
  std::optional<Eigen::Isometry3d> Interpolate(double t, double max_gap) const;

 private:
  std::vector<StampedPose> poses_;  // sorted by timestamp, strictly increasing
};

// Reads a TUM trajectory. Lines are sorted by timestamp on read (TUM files are, but hand-made
// ones may not be); duplicate timestamps, malformed lines and zero quaternions are Errors naming
// the file and line.
Trajectory ReadTumTrajectory(const std::filesystem::path& path);
// Writes a TUM trajectory atomically, timestamps with 6 decimals, values with 9 significant digits.
void WriteTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);

// Redwood / Open3D `.log` trajectory: per frame a line "id id frame_count" then a row-major 4x4
// world_from_camera. Timestamps are the block indices 0, 1, 2, ... (the header ids are ignored).
Trajectory ReadRedwoodLog(const std::filesystem::path& path);

}  // namespace genscene
