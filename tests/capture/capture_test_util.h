// Shared fixtures of the capture tests: a small TUM folder rendered from the analytic Cornell
// scene, with TUM-like (large) time stamps, read back through core's folder reader.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <vector>

#include "core/frame_source.h"
#include "core/sequence_writer.h"
#include "core/synthetic.h"
#include "core/trajectory.h"

namespace genscene::test {

// Writes `count` frames of width x height into `folder` (TUM layout) and returns them as the folder
// reader gives them back (depth quantised to 1/5000 m, colour to 8-bit sRGB).
inline std::vector<RgbdFrame> MakeTumFolder(const std::filesystem::path& folder, int count,
                                            int width = 64, int height = 48) {
  CameraIntrinsics k;
  k.width = width, k.height = height;
  k.fx = k.fy = 0.9 * width;
  k.cx = 0.5 * (width - 1) + 0.75;  // off-centre on purpose: the .oni field of view cannot carry it
  k.cy = 0.5 * (height - 1) - 0.5;
  const SyntheticScene scene = MakeCornellScene();
  const Trajectory orbit = MakeOrbitTrajectory({0, 0, 0.6}, 0.9, 1.0, 40.0, count);
  std::vector<RgbdFrame> frames;
  for (const auto& p : orbit.poses()) {
    // A TUM-like time stamp (seconds since 1970, microsecond resolution).
    frames.push_back(
        RenderSyntheticFrame(scene, k, p.world_from_camera, 1305031102.175304 + p.timestamp));
  }
  WriteTumSequence(folder, frames);
  auto source = OpenFrameSource(folder.string(), SourceOptions());
  return ReadAllFrames(*source);
}

}  // namespace genscene::test
