#include "core/trajectory.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/check.h"
#include "core/file_util.h"
#include "core/se3.h"

namespace genscene {

Trajectory::Trajectory(std::vector<StampedPose> poses) : poses_(std::move(poses)) {
  for (size_t i = 1; i < poses_.size(); ++i) {
    GS_CHECK_LT(poses_[i - 1].timestamp, poses_[i].timestamp);
  }
}

void Trajectory::Add(double timestamp, const Eigen::Isometry3d& world_from_camera) {
  if (!poses_.empty()) GS_CHECK_LT(poses_.back().timestamp, timestamp);
  poses_.push_back({timestamp, world_from_camera});
}

std::optional<StampedPose> Trajectory::Nearest(double t, double max_difference) const {
  if (poses_.empty()) return std::nullopt;
  auto it = std::lower_bound(poses_.begin(), poses_.end(), t,
                             [](const StampedPose& p, double time) { return p.timestamp < time; });
  const StampedPose* best = nullptr;
  if (it != poses_.end()) best = &*it;
  if (it != poses_.begin()) {
    const StampedPose& before = *std::prev(it);
    if (!best || std::abs(before.timestamp - t) <= std::abs(best->timestamp - t)) best = &before;
  }
  if (std::abs(best->timestamp - t) > max_difference) return std::nullopt;
  return *best;
}

std::optional<Eigen::Isometry3d> Trajectory::Interpolate(double t, double max_gap) const {
  auto after =
      std::lower_bound(poses_.begin(), poses_.end(), t,
                       [](const StampedPose& p, double time) { return p.timestamp < time; });
  if (after == poses_.end()) return std::nullopt;
  if (after->timestamp == t) return after->world_from_camera;
  if (after == poses_.begin()) return std::nullopt;
  const StampedPose& before = *std::prev(after);
  const double gap = after->timestamp - before.timestamp;
  if (gap > max_gap) return std::nullopt;
  const double alpha = (t - before.timestamp) / gap;
  return InterpolatePose(before.world_from_camera, after->world_from_camera, alpha);
}

Trajectory ReadTumTrajectory(const std::filesystem::path& path) {
  std::vector<StampedPose> poses;
  for (const TextLine& line : ReadDataLines(path)) {
    const std::string where = Format(path.string(), ":", line.number);
    const auto tokens = SplitWhitespace(line.text);
    if (tokens.size() != 8) {
      throw Error(Format(where, ": expected 'timestamp tx ty tz qx qy qz qw', got ", tokens.size(),
                         " values"));
    }
    double v[8];
    for (int i = 0; i < 8; ++i) v[i] = ParseDouble(tokens[i], where);
    if (!std::isfinite(v[0])) throw Error(Format(where, ": timestamp is not finite"));
    try {
      poses.push_back({v[0], PoseFromTranslationQuaternion(
                                 {v[1], v[2], v[3]}, Eigen::Quaterniond(v[7], v[4], v[5], v[6]))});
    } catch (const Error& e) {
      throw Error(Format(where, ": ", e.what()));
    }
  }
  std::stable_sort(poses.begin(), poses.end(), [](const StampedPose& a, const StampedPose& b) {
    return a.timestamp < b.timestamp;
  });
  for (size_t i = 1; i < poses.size(); ++i) {
    if (poses[i].timestamp == poses[i - 1].timestamp) {
      throw Error(Format(path.string(), ": timestamp ", poses[i].timestamp, " appears twice"));
    }
  }
  return Trajectory(std::move(poses));
}

void WriteTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory) {
  std::ostringstream out;
  out << "# timestamp tx ty tz qx qy qz qw (world_from_camera, OpenCV camera axes)\n";
  char buffer[256];
  for (const StampedPose& p : trajectory.poses()) {
    Eigen::Vector3d t;
    Eigen::Quaterniond q;
    ToTranslationQuaternion(p.world_from_camera, &t, &q);
    std::snprintf(buffer, sizeof(buffer), "%.6f %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", p.timestamp,
                  t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    out << buffer;
  }
  WriteTextFileAtomically(path, out.str());
}

Trajectory ReadRedwoodLog(const std::filesystem::path& path) {
  const auto lines = ReadDataLines(path);
  if (lines.size() % 5 != 0) {
    throw Error(Format(path.string(), ": ", lines.size(),
                       " data lines, expected 5 per frame (a header line and a 4x4 matrix)"));
  }
  Trajectory trajectory;
  for (size_t i = 0; i < lines.size(); i += 5) {
    const std::string header_where = Format(path.string(), ":", lines[i].number);
    const auto header = SplitWhitespace(lines[i].text);
    if (header.size() != 3) throw Error(Format(header_where, ": expected 'id id frame_count'"));
    // Like Open3D, the header ids are metadata only: the pose of the k-th block belongs to frame k.
    const long long frame = static_cast<long long>(i / 5);
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r) {
      const std::string where = Format(path.string(), ":", lines[i + 1 + r].number);
      const auto row = SplitWhitespace(lines[i + 1 + r].text);
      if (row.size() != 4)
        throw Error(Format(where, ": expected 4 matrix values, got ", row.size()));
      for (int c = 0; c < 4; ++c) m(r, c) = ParseDouble(row[c], where);
    }
    if (!IsValidRigidTransform(m)) {
      throw Error(Format(header_where, ": frame ", frame, " is not a rigid transform"));
    }
    Eigen::Isometry3d pose(m);
    // Re-orthonormalise the rotation printed with 6 digits.
    pose.linear() = Eigen::Quaterniond(pose.rotation()).normalized().toRotationMatrix();
    trajectory.Add(static_cast<double>(frame), pose);
  }
  return trajectory;
}

}  // namespace genscene
