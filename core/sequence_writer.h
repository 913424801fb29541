// Writes RGB-D frames as a TUM-layout folder (rgb/, depth/, rgb.txt, depth.txt, intrinsics.txt,
// groundtruth.txt when the frames carry poses) that every reader of core/frame_source.h opens.
// The folder appears complete or not at all: it is written under a temporary name and renamed.
#pragma once

#include <filesystem>
#include <functional>
#include <vector>

#include "core/color.h"
#include "core/rgbd_frame.h"

namespace genscene {

struct TumWriteOptions {
  double depth_scale = 5000.0;  // 16-bit depth units per meter (TUM: 5000)
  CameraResponse response;      // encoding of the 8-bit colour PNGs (sRGB)
  bool linear_exr = false;      // also write rgb as linear EXR (listed in rgb_linear.txt)
  // Called with the temporary folder before it is renamed, to add files that must appear
  // together with the sequence (e.g. a ground-truth mesh).
  std::function<void(const std::filesystem::path& tmp_dir)> extra_files;
};

// Throws Error when frames is empty, frames disagree in intrinsics, or `dir` exists and is not a
// folder written by this function before (it never deletes a folder it did not write).
void WriteTumSequence(const std::filesystem::path& dir, const std::vector<RgbdFrame>& frames,
                      const TumWriteOptions& options = TumWriteOptions());

}  // namespace genscene
