#include "apps/ingest.h"

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "capture/openni2_source.h"
#include "core/file_util.h"

namespace genscene::apps {

IngestSummary IngestSequence(const std::string& input, const SourceOptions& options,
                             const std::filesystem::path& summary_json) {
  auto source = capture::OpenAnySource(input, options);
  IngestSummary summary;
  summary.description = source->Describe();
  summary.width = source->Intrinsics().width;
  summary.height = source->Intrinsics().height;
  summary.min_depth = INFINITY;
  const size_t total = source->FrameCount().value_or(0);
  nlohmann::json frames = nlohmann::json::array();
  size_t valid = 0, pixels = 0;
  while (auto frame = source->Next()) {
    double lo = INFINITY, hi = 0.0;
    size_t frame_valid = 0;
    for (float z : frame->depth.pixels()) {
      if (z <= 0.0f) continue;
      ++frame_valid;
      lo = std::min<double>(lo, z);
      hi = std::max<double>(hi, z);
    }
    valid += frame_valid;
    pixels += frame->depth.size();
    if (frame_valid > 0) {
      summary.min_depth = std::min(summary.min_depth, lo);
      summary.max_depth = std::max(summary.max_depth, hi);
    }
    summary.frames_with_pose += frame->world_from_camera ? 1 : 0;
    frames.push_back({{"timestamp", frame->timestamp},
                      {"color", frame->color_path},
                      {"depth", frame->depth_path},
                      {"valid_depth_fraction",
                       frame->depth.empty() ? 0.0 : double(frame_valid) / frame->depth.size()},
                      {"min_depth_m", frame_valid ? lo : 0.0},
                      {"max_depth_m", hi},
                      {"has_pose", frame->world_from_camera.has_value()}});
    ++summary.frames;
    std::cerr << "\rreading frames: " << summary.frames << "/" << total << std::flush;
  }
  std::cerr << "\n";
  if (!std::isfinite(summary.min_depth)) summary.min_depth = 0.0;
  summary.valid_depth_fraction = pixels ? double(valid) / pixels : 0.0;
  if (!summary_json.empty()) {
    nlohmann::json j = {{"source", summary.description},
                        {"input", input},
                        {"width", summary.width},
                        {"height", summary.height},
                        {"intrinsics", source->Intrinsics().ToString()},
                        {"frames", frames}};
    WriteTextFileAtomically(summary_json, j.dump(2) + "\n");
  }
  return summary;
}

}  // namespace genscene::apps
