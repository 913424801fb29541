#include "core/view_set.h"

#include "core/check.h"
#include "core/file_util.h"
#include "core/frame_source.h"
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

std::vector<PosedImage> ReadPosedImages(const std::filesystem::path& folder) {
  if (!std::filesystem::is_directory(folder))
    throw Error(Format(folder.string(), ": no such view set folder"));
  std::vector<PosedImage> views;
  auto source = OpenFrameSource(folder.string(), SourceOptions());
  while (auto frame = source->Next()) {
    if (!frame->world_from_camera) {
      throw Error(Format(frame->color_path.empty() ? folder.string() : frame->color_path,
                         ": the image has no pose"));
    }
    if (frame->color.empty()) throw Error(Format(folder.string(), ": a frame has no colour image"));
    views.push_back(
        {PosedView{frame->intrinsics, *frame->world_from_camera, frame->timestamp}, frame->color});
  }
  if (views.empty()) throw Error(Format(folder.string(), ": no images"));
  return views;
}

}  // namespace genscene
