#include "core/view_set.h"

#include "core/check.h"
#include "core/file_util.h"
#include "core/trajectory.h"

namespace genscene {

namespace fs = std::filesystem;

std::vector<PosedView> ReadViewSet(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw Error(Format(dir.string(), ": not a folder (expected a view set)"));
  const CameraIntrinsics intrinsics = ReadIntrinsicsFile(dir / "intrinsics.txt");
  const Trajectory poses = ReadTumTrajectory(dir / "groundtruth.txt");
  if (poses.empty()) throw Error(Format((dir / "groundtruth.txt").string(), ": no poses"));
  std::vector<PosedView> views;
  if (fs::exists(dir / "rgb.txt", ec)) {
    for (const TextLine& line : ReadDataLines(dir / "rgb.txt")) {
      const std::string where = Format((dir / "rgb.txt").string(), ":", line.number);
      const auto tokens = SplitWhitespace(line.text);
      if (tokens.empty()) continue;
      const double t = ParseDouble(tokens[0], where);
      const auto pose = poses.Nearest(t, 1e-6);
      if (!pose) throw Error(Format(where, ": no pose in groundtruth.txt for timestamp ", t));
      views.push_back({intrinsics, pose->world_from_camera, t});
    }
  } else {
    for (const StampedPose& p : poses.poses())
      views.push_back({intrinsics, p.world_from_camera, p.timestamp});
  }
  if (views.empty()) throw Error(Format(dir.string(), ": view set has no views"));
  return views;
}

}  // namespace genscene
