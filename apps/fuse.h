// genscene-fuse as a function: read a source, run the fusion stage frame by frame with progress
// on stderr, evaluate the trajectory against the source's known poses when it has them, and
// write the stage's outputs into the workspace. Shared by genscene-fuse and `genscene run`.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "capture/openni2_source.h"
#include "core/frame_source.h"
#include "core/trajectory_metrics.h"
#include "core/workspace.h"
#include "fusion/kinect_fusion.h"

namespace genscene::apps {

struct FuseSummary {
  std::string source;
  size_t frames = 0, fused = 0, lost = 0, degenerate = 0, blank = 0;
  size_t blocks = 0;
  double megabytes = 0.0;
  size_t keyframes = 0;
  size_t held_out = 0;           // frames kept out of the model (holdout), written to WS/holdout/
  bool live = false;             // read from a live camera (no frame count known in advance)
  size_t skipped = 0;            // live camera frames that arrived while fusion was busy, unfused
  double seconds = 0.0;          // processing time of all frames (reading excluded)
  std::optional<AteResult> ate;  // against the source's known poses (tracking = icp only)
  std::vector<std::string> warnings;  // also logged with spdlog::warn as they arise
};

// Throws Error, before writing anything, when ICP tracking lost or could not constrain most
// frames: the message says how many and what to try.
// `camera`: the stream mode of a live camera.
FuseSummary FuseSequence(const std::string& input, const SourceOptions& source_options,
                         const fusion::FusionOptions& options, const Workspace& workspace,
                         const capture::CaptureOptions& camera = capture::CaptureOptions());

// One line per field for the console.
std::string ToString(const FuseSummary& summary);

}  // namespace genscene::apps
