// The first stage of the chain while fusion is being built: read every frame of a source through
// the readers, check it, and summarise it (sequence.json in the workspace).
#pragma once

#include <filesystem>
#include <string>

#include "core/frame_source.h"

namespace genscene::apps {

struct IngestSummary {
  std::string description;
  size_t frames = 0;
  int width = 0, height = 0;
  double min_depth = 0.0, max_depth = 0.0;  // meters, over valid pixels of all frames
  double valid_depth_fraction = 0.0;        // valid depth pixels / all depth pixels
  size_t frames_with_pose = 0;
};

// Reads and validates every frame (progress on stderr). When `summary_json` is not empty, writes
// the per-frame summary there atomically.
IngestSummary IngestSequence(const std::string& input, const SourceOptions& options,
                             const std::filesystem::path& summary_json);

}  // namespace genscene::apps
