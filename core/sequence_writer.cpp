#include "core/sequence_writer.h"

#include <unistd.h>

#include <cstdio>
#include <sstream>

#include "core/camera.h"
#include "core/check.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/trajectory.h"

namespace genscene {

namespace fs = std::filesystem;

namespace {

constexpr const char* kMarker = ".genscene-sequence";  // marks folders this writer owns

std::string StampName(double timestamp) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6f", timestamp);
  return buffer;
}

}  // namespace

void WriteTumSequence(const fs::path& dir, const std::vector<RgbdFrame>& frames,
                      const TumWriteOptions& options) {
  if (frames.empty()) throw Error(Format(dir.string(), ": no frames to write"));
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::exists(dir / kMarker, ec)) {
    throw Error(
        Format(dir.string(), ": exists and was not written by genscene; refusing to replace it"));
  }
  const fs::path tmp = dir.string() + Format(".tmp-", ::getpid());
  fs::remove_all(tmp, ec);
  try {
    fs::create_directories(tmp / "rgb");
    fs::create_directories(tmp / "depth");
    std::ostringstream rgb_list, depth_list, linear_list;
    rgb_list << "# timestamp filename (8-bit " << options.response.ToString() << ")\n";
    depth_list << "# timestamp filename (16-bit PNG, value/" << options.depth_scale << " = m)\n";
    linear_list << "# timestamp filename (linear EXR)\n";
    Trajectory poses;
    const CameraIntrinsics& k = frames.front().intrinsics;
    for (const RgbdFrame& frame : frames) {
      frame.Validate();
      if (frame.intrinsics.ToString() != k.ToString()) {
        throw Error(Format(dir.string(), ": frames have different intrinsics (", k.ToString(),
                           " vs ", frame.intrinsics.ToString(), ")"));
      }
      const std::string stamp = StampName(frame.timestamp);
      if (!frame.color.empty()) {
        WritePng(tmp / "rgb" / (stamp + ".png"), frame.color, options.response);
        rgb_list << stamp << " rgb/" << stamp << ".png\n";
        if (options.linear_exr) {
          WriteExr(tmp / "rgb" / (stamp + ".exr"), frame.color);
          linear_list << stamp << " rgb/" << stamp << ".exr\n";
        }
      }
      if (!frame.depth.empty()) {
        WriteDepthPng(tmp / "depth" / (stamp + ".png"), frame.depth, options.depth_scale);
        depth_list << stamp << " depth/" << stamp << ".png\n";
      }
      if (frame.world_from_camera) poses.Add(frame.timestamp, *frame.world_from_camera);
    }
    WriteTextFileAtomically(tmp / "rgb.txt", rgb_list.str());
    WriteTextFileAtomically(tmp / "depth.txt", depth_list.str());
    if (options.linear_exr) WriteTextFileAtomically(tmp / "rgb_linear.txt", linear_list.str());
    WriteIntrinsicsFile(tmp / "intrinsics.txt", k);
    if (!poses.empty()) WriteTumTrajectory(tmp / "groundtruth.txt", poses);
    if (options.extra_files) options.extra_files(tmp);
    WriteTextFileAtomically(tmp / kMarker, "written by genscene WriteTumSequence\n");
    // Swap in: the old folder (ours, by the marker check) goes only once the new one is complete.
    if (fs::exists(dir, ec)) fs::remove_all(dir);
    fs::rename(tmp, dir);
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace genscene
