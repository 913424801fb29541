#include "apps/fuse.h"

#include <spdlog/spdlog.h>

#include <iostream>
#include <sstream>

#include "capture/openni2_source.h"
#include "core/check.h"

namespace genscene::apps {

FuseSummary FuseSequence(const std::string& input, const SourceOptions& source_options,
                         const fusion::FusionOptions& options, const Workspace& workspace,
                         const capture::CaptureOptions& camera) {
  auto source = capture::OpenAnySource(input, source_options, camera);
  FuseSummary summary;
  summary.source = source->Describe();
  fusion::KinectFusion fusion(options, source->Intrinsics());
  const size_t total = source->FrameCount().value_or(0);
  while (auto frame = source->Next()) {
    if (frame->depth.empty()) {
      throw Error(Format(
          input, ": frame at t = ", frame->timestamp, " (", frame->color_path,
          ") has no depth image (a colour-only view set, no depth.txt?): fusion needs depth"));
    }
    const fusion::FrameReport r = fusion.ProcessFrame(*frame);
    ++summary.frames;
    summary.seconds += r.seconds();
    switch (r.status) {
      case fusion::FrameStatus::kLost:
        ++summary.lost;
        break;
      case fusion::FrameStatus::kDegenerate:
        ++summary.degenerate;
        break;
      case fusion::FrameStatus::kBlank:
        ++summary.blank;
        break;
      default:
        break;
    }
    summary.fused += r.fused;
    if (!r.reason.empty()) {
      std::cerr << "\nframe " << r.index << " (t = " << std::fixed << r.timestamp
                << std::defaultfloat << "): " << fusion::ToString(r.status) << ": " << r.reason
                << "\n";
    }
    if (r.relocalised_against) {
      std::cerr << "\nframe " << r.index << " (t = " << std::fixed << r.timestamp
                << "): relocalised against the keyframe at t = " << *r.relocalised_against
                << std::defaultfloat << " (" << r.features.inliers << " feature inliers)\n";
    }
    if (r.loop_closure) {
      const fusion::LoopClosureEvent& e = *r.loop_closure;
      std::cerr << "\nframe " << r.index << " (t = " << std::fixed << r.timestamp
                << "): loop closed against the frame at t = " << e.against_timestamp
                << std::defaultfloat << " (" << e.feature_inliers << " feature inliers; "
                << 100.0 * e.discrepancy_translation << " cm, " << e.discrepancy_degrees
                << " deg off); frames moved up to " << 100.0 * e.largest_move << " cm"
                << (r.reintegrated > 0 ? Format(", ", r.reintegrated, " integrated again")
                                       : std::string())
                << "\n";
    }
    std::cerr << "\rfusing: " << summary.frames;
    if (total) std::cerr << "/" << total;
    std::cerr << " frames, " << summary.frames / std::max(summary.seconds, 1e-9) << " fps, "
              << fusion.volume().num_blocks() << " blocks   " << std::flush;
  }
  std::cerr << "\n";
  if (summary.frames == 0) throw Error(Format(input, ": the sequence has no frames"));
  fusion.Finish();
  const size_t failed = summary.lost + summary.degenerate, tried = summary.frames - summary.blank;
  if (options.tracking == "icp" && tried >= 2 && 2 * failed > tried) {
    const CameraIntrinsics& k = source->Intrinsics();
    std::string advice =
        source->KnownPoses().empty()
            ? ""
            : "; the recording has its own poses: --tracking known fuses with them";
    throw Error(Format(input, ": ICP tracking failed on ", failed, " of ", tried, " frames (",
                       summary.lost, " lost, ", summary.degenerate, " degenerate; ", summary.fused,
                       " fused), too few for a model", advice,
                       "; or check the intrinsics (--intrinsics; now fx ", k.fx, " fy ", k.fy,
                       " cx ", k.cx, " cy ", k.cy, ") and the depth scale (--depth-scale)"));
  }
  if (options.tracking == "icp" && source->KnownPoses().size() >= 3 &&
      fusion.trajectory().size() >= 3) {
    try {  // an accuracy figure: a run never stops for it
      summary.ate = ComputeAte(fusion.trajectory(), source->KnownPoses());
    } catch (const Error& e) {
      summary.warnings.push_back(
          Format("no trajectory error against the recording's poses: ", e.what()));
      spdlog::warn("{}", summary.warnings.back());
    }
  }
  summary.live = !source->FrameCount().has_value();
  summary.skipped = source->SkippedFrames();
  fusion::SaveFusionOutputs(fusion, workspace, summary.ate,
                            summary.live ? std::optional<size_t>(summary.skipped) : std::nullopt);
  summary.blocks = fusion.volume().num_blocks();
  summary.megabytes = fusion.volume().allocated_bytes() / 1e6;
  summary.keyframes = fusion.keyframes().size();
  summary.held_out = fusion.held_out().size();
  return summary;
}

std::string ToString(const FuseSummary& s) {
  std::ostringstream out;
  out << "source:     " << s.source << "\n"
      << "frames:     " << s.frames << " (fused " << s.fused << ", lost " << s.lost
      << ", degenerate " << s.degenerate << ", blank " << s.blank << ")\n"
      << "speed:      " << s.frames / std::max(s.seconds, 1e-9) << " frames/s (" << s.seconds
      << " s)\n"
      << "volume:     " << s.blocks << " blocks, " << s.megabytes << " MB\n"
      << "keyframes:  " << s.keyframes << "\n";
  if (s.live) {
    out << "camera:     " << s.frames + s.skipped << " frames sent while fusing, " << s.skipped
        << " skipped (they arrived while fusion was busy, or the camera dropped them)\n";
  }
  if (s.held_out > 0)
    out << "held out:   " << s.held_out << " frames (tracked only, to judge the model on)\n";
  if (s.ate) {
    out << "ATE:        RMSE " << 100.0 * s.ate->rmse << " cm, max " << 100.0 * s.ate->max
        << " cm over " << s.ate->pairs
        << " poses (against the source's known poses at each frame's time, Horn-aligned)\n";
  }
  return out.str();
}

}  // namespace genscene::apps
