#include "fusion/kinect_fusion.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "core/options.h"
#include "core/options_json.h"
#include "core/se3.h"
#include "core/sequence_writer.h"

namespace genscene::fusion {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The lattice origin: the first camera position snapped to the block grid of the world, so that
// volumes of the same scene line up, and voxel arithmetic stays near the cameras; then shifted by
// half a voxel, so that lattice points sit at voxel centres ((i + 1/2) voxel_size, as Open3D's
// do), not on the round coordinates where walls and floors of modelled scenes lie. A surface
// through lattice points leaves those voxels' sdf at noise level: their signs flip at random and
// marching cubes makes a rough sheet with about twice the triangles (measured on the synthetic
// room: 688,683 triangles, 1.70 mm RMS, against 378,426 and 1.48 mm for Open3D on the same frames).
Eigen::Vector3d SnappedOrigin(const Eigen::Vector3d& position, double voxel_size) {
  const double block = kTsdfBlockSide * voxel_size;
  return (position / block).array().round().matrix() * block +
         Eigen::Vector3d::Constant(0.5 * voxel_size);
}

}  // namespace

void FusionOptions::Validate() const {
  RequireRange("voxel_size", voxel_size, 1e-3, 1.0);
  RequireRange("truncation", truncation, 2.0 * voxel_size, 50.0 * voxel_size);
  RequireRange("max_weight", max_weight, 1.0, 1e6);
  RequireRange("memory_cap", memory_cap, 1.0, 1e7);
  RequireOneOf("tracking", tracking, {"icp", "known"});
  RequireRange("min_valid_fraction", min_valid_fraction, 0.0, 1.0);
  RequireRange("model_subsample", model_subsample, 0, 8);
  RequireRange("allocation_stride", allocation_stride, 0, 16);
  if (tracking_subsample != 0 && tracking_subsample != 1 && tracking_subsample != 2 &&
      tracking_subsample != 4) {
    throw Error(Format("option tracking_subsample = ", tracking_subsample,
                       " is not 0 (by the width), 1, 2 or 4"));
  }
  RequireOneOf("weighting", weighting, {"noise", "uniform"});
  if (holdout == 1 || holdout < 0 || holdout > 100000) {
    throw Error(Format("option holdout = ", holdout, " is not 0 (none) or in [2, 100000]"));
  }
  preprocess.Validate();
  icp.Validate();
  features.Validate();
  keyframes.Validate();
  loop.Validate();
}

TsdfVolumeParams FusionOptions::VolumeParams(const Eigen::Vector3d& origin) const {
  TsdfVolumeParams p;
  p.voxel_size = voxel_size;
  p.truncation = truncation;
  p.max_weight = static_cast<float>(max_weight);
  p.origin = origin;
  p.memory_cap_bytes = memory_cap * 1e6;
  return p;
}

const char* ToString(FrameStatus status) {
  switch (status) {
    case FrameStatus::kInitial:
      return "initial";
    case FrameStatus::kTracked:
      return "tracked";
    case FrameStatus::kKnownPose:
      return "known_pose";
    case FrameStatus::kDegenerate:
      return "degenerate";
    case FrameStatus::kLost:
      return "lost";
    case FrameStatus::kBlank:
      return "blank";
    case FrameStatus::kHeldOut:
      return "held_out";
  }
  return "?";
}

int FusionOptions::AllocationStride(int width) const {
  if (allocation_stride > 0) return allocation_stride;
  return std::max(1, static_cast<int>(std::lround(width / 160.0)));
}

int FusionOptions::ModelSubsample(int width) const {
  if (model_subsample > 0) return model_subsample;
  return std::clamp(static_cast<int>(std::lround(width / 160.0)), 2, 8);
}

int FusionOptions::TrackingSubsample(int width) const {
  if (tracking_subsample > 0) return tracking_subsample;
  int s = 1;
  while (s < 4 && width / (2 * s) >= 320) s *= 2;
  return s;
}

KinectFusion::KinectFusion(const FusionOptions& options, const CameraIntrinsics& intrinsics)
    : options_(options),
      intrinsics_(intrinsics),
      volume_(options.VolumeParams(Eigen::Vector3d::Zero())),
      keyframe_selector_(options.keyframes) {
  options_.Validate();
  intrinsics_.Validate();
  model_subsample_ = options_.ModelSubsample(intrinsics_.width);
  integration_.allocation_stride = options_.AllocationStride(intrinsics_.width);
  integration_.noise_weights = options_.weighting == "noise";
  if (options_.loop.enabled && options_.tracking != "known")
    loops_.emplace(options_.loop, intrinsics_, options_.preprocess, options_.icp,
                   options_.features);
}

FrameReport KinectFusion::ProcessFrame(const RgbdFrame& frame) {
  FrameReport report;
  report.index = reports_.size();
  report.timestamp = frame.timestamp;
  const CameraIntrinsics& k = intrinsics_;
  if (!frame.depth.SameSize(k.width, k.height)) {
    throw Error(Format(frame.depth_path.empty() ? "frame" : frame.depth_path, ": depth ",
                       frame.depth.width(), "x", frame.depth.height(), " but intrinsics say ",
                       k.width, "x", k.height));
  }
  if (!frame.color.empty() && !frame.color.SameSize(frame.depth)) {
    throw Error(Format(frame.color_path.empty() ? "frame" : frame.color_path, ": colour ",
                       frame.color.width(), "x", frame.color.height(), " but depth ",
                       frame.depth.width(), "x", frame.depth.height()));
  }
  auto start = std::chrono::steady_clock::now();
  const ImageDepth depth = MaskInvalidDepth(frame.depth, options_.preprocess.min_depth,
                                            options_.preprocess.max_depth, &report.mask);
  const double valid_fraction =
      static_cast<double>(report.mask.valid) / static_cast<double>(depth.size());
  auto finish = [&](FrameReport r) {
    reports_.push_back(r);
    return r;
  };
  if (valid_fraction < options_.min_valid_fraction) {
    report.status = FrameStatus::kBlank;
    report.reason = Format(report.mask.valid, " valid depth pixels (", 100.0 * valid_fraction,
                           " %) < ", 100.0 * options_.min_valid_fraction, " %");
    report.seconds_preprocess = SecondsSince(start);
    return finish(report);
  }

  Eigen::Isometry3d pose;
  std::vector<IntensityLevel> live_intensity;  // for the photometric term (tracked frames)
  if (options_.tracking == "known") {
    if (!frame.world_from_camera) {
      throw Error(Format("frame ", report.index, " (t = ", frame.timestamp,
                         "): tracking = known but the source has no pose for it"));
    }
    pose = *frame.world_from_camera;
    report.status = FrameStatus::kKnownPose;
    report.seconds_preprocess = SecondsSince(start);
    if (started_ && HeldOut(report.index)) return finish(HoldOut(frame, depth, pose, report));
  } else if (!started_) {
    // The first frame defines the world: its known pose when the source has one (so that the
    // model lines up with the ground truth), else the identity.
    pose = frame.world_from_camera.value_or(Eigen::Isometry3d::Identity());
    report.status = FrameStatus::kInitial;
    report.seconds_preprocess = SecondsSince(start);
  } else {
    const int subsample = options_.TrackingSubsample(k.width);
    const std::vector<PyramidLevel> pyramid =
        BuildPyramid(depth, k, options_.preprocess, subsample);
    if (options_.icp.color_weight > 0.0)
      live_intensity = BuildIntensityPyramid(frame.color, options_.preprocess.levels, subsample);
    report.seconds_preprocess = SecondsSince(start);
    start = std::chrono::steady_clock::now();
    // Predict no motion since the last pose: the last fused frame's, or a held-out frame's after it
    // (with a held-out frame between them, two frames' motion would start from the identity).
    // Not the last frame's motion repeated (constant velocity): in a direction the scene
    // constrains weakly ICP keeps the prediction, the next prediction doubles it, and tracking
    // ran away (the path-traced room: lost from frame 39 on).
    Eigen::Isometry3d model_from_live =
        held_out_pose_ ? Eigen::Isometry3d(last_good_.inverse() * *held_out_pose_)
                       : Eigen::Isometry3d::Identity();
    report.icp =
        TrackFrameToModel(pyramid, model_, intrinsics_.Scaled(1.0 / model_subsample_), options_.icp,
                          &model_from_live, &live_intensity, &model_intensity_);
    report.seconds_track = SecondsSince(start);
    const double moved = model_from_live.translation().norm();
    const double turned = RotationAngle(model_from_live) * 180.0 / M_PI;
    const IcpReport& icp = report.icp;
    if (icp.inlier_ratio < options_.icp.min_inlier_ratio) {
      report.reason =
          Format("inlier ratio ", icp.inlier_ratio, " < ", options_.icp.min_inlier_ratio);
    } else if (icp.rms_residual > options_.icp.max_rms_residual) {
      report.reason =
          Format("RMS residual ", icp.rms_residual, " m > ", options_.icp.max_rms_residual, " m");
    } else if (moved > options_.icp.max_translation || turned > options_.icp.max_rotation) {
      report.reason = Format("jump of ", moved, " m and ", turned, " deg from the last good pose");
    }
    // A lost frame, and a degenerate one (ICP kept the predicted pose along the directions the
    // geometry leaves free), start again from the features, which fix all six.
    std::optional<Eigen::Isometry3d> feature_pose;
    if ((!report.reason.empty() || icp.degenerate) && options_.feature_tracking) {
      start = std::chrono::steady_clock::now();
      std::string why;
      feature_pose = TrackFromFeatures(pyramid, frame, &report, &why);
      report.seconds_track += SecondsSince(start);
      if (!feature_pose && !report.reason.empty()) report.reason += "; features: " + why;
    }
    if (!report.reason.empty() && !feature_pose) {
      report.status = FrameStatus::kLost;
      return finish(report);
    }
    if (feature_pose) {
      report.reason.clear();
      report.feature_start = true;
    }
    pose = feature_pose ? *feature_pose : Eigen::Isometry3d(last_good_ * model_from_live);
    if (HeldOut(report.index)) return finish(HoldOut(frame, depth, pose, report));
    if (icp.degenerate && !feature_pose) {
      // The pose is kept along the unconstrained directions; fusing would smear the model along
      // them if the camera did move that way, so the frame is not fused.
      report.status = FrameStatus::kDegenerate;
      report.reason = Format("only ", icp.constrained_directions,
                             " of 6 pose directions constrained (condition ", icp.condition, ")");
      report.world_from_camera = pose;
      // The next frame tracks from this pose: against the model as seen from here.
      UpdateModel(pose, &report);
      last_good_ = pose;
      model_intensity_ = std::move(live_intensity);
      held_out_pose_.reset();
      trajectory_.Add(frame.timestamp, pose);
      if (loops_) {
        loops_->Advance(pose, &report.icp.information);
        loops_->Anchor(frame.timestamp, pose);
      }
      return finish(report);
    }
    report.status = FrameStatus::kTracked;
  }
  if (!started_) {
    volume_ =
        TsdfVolume(options_.VolumeParams(SnappedOrigin(pose.translation(), options_.voxel_size)));
    started_ = true;
  }
  start = std::chrono::steady_clock::now();
  report.integration = IntegrateFrame(volume_, depth, frame.color, k, pose, integration_);
  report.fused = true;
  report.seconds_integrate = SecondsSince(start);
  if (options_.tracking != "known") {  // with known poses nothing tracks against the model
    UpdateModel(pose, &report);
    if (options_.feature_tracking && !frame.color.empty()) {
      relocalise_next_ = 0;  // a later lost frame tries the newest keyframes first
      last_fused_.timestamp = frame.timestamp;
      last_fused_.color = frame.color;
      last_fused_.depth =
          frame.depth;  // unmasked: features far beyond range_max still fix the pose
      last_fused_.world_from_camera = pose;
    }
  }
  last_good_ = pose;
  if (options_.tracking != "known" && options_.icp.color_weight > 0.0) {
    // The first frame's pyramid is made here (no tracking built it).
    model_intensity_ = live_intensity.empty()
                           ? BuildIntensityPyramid(frame.color, options_.preprocess.levels,
                                                   options_.TrackingSubsample(k.width))
                           : std::move(live_intensity);
  }
  held_out_pose_.reset();
  report.world_from_camera = pose;
  trajectory_.Add(frame.timestamp, pose);
  if (loops_) {
    start = std::chrono::steady_clock::now();
    // The step from the last good pose as ICP measured it (a frame started from features has its
    // check's information, PoseFromReference); none for the first frame.
    const bool icp_step = report.status == FrameStatus::kTracked;
    report.loop_closure = loops_->AddFused(frame.timestamp, pose, depth, frame.color,
                                           icp_step ? &report.icp.information : nullptr);
    if (report.loop_closure) {
      ApplyLoopClosure(&report);
      pose = *report.world_from_camera;
    }
    report.seconds_loop = SecondsSince(start);
    if (report.loop_closure) {
      // The model again from the corrected pose (and volume): raycast time, not loop time.
      const double first_raycast = report.seconds_raycast;
      UpdateModel(last_good_, &report);
      report.seconds_raycast += first_raycast;
    }
  }
  keyframe_selector_.Offer(frame, depth, pose, intrinsics_);
  return finish(report);
}

void KinectFusion::ApplyLoopClosure(FrameReport* report) {
  std::vector<StampedPose> poses = trajectory_.poses();
  for (StampedPose& p : poses) {
    if (auto moved = loops_->PoseOf(p.timestamp)) p.world_from_camera = *moved;
  }
  trajectory_ = Trajectory(std::move(poses));
  const auto pose_of = [&](double t) { return loops_->PoseOf(t); };
  keyframe_selector_.Repose(pose_of);
  for (RgbdFrame& f : held_out_) {
    if (auto moved = pose_of(f.timestamp)) f.world_from_camera = *moved;
  }
  if (last_fused_.world_from_camera) {
    if (auto moved = pose_of(last_fused_.timestamp)) last_fused_.world_from_camera = *moved;
  }
  last_good_ = *pose_of(report->timestamp);
  report->world_from_camera = last_good_;
  if (report->loop_closure->largest_move >= options_.loop.min_correction) {
    // The volume again from every fused frame at its corrected pose.
    const FrameStore& store = loops_->frames();
    volume_ = TsdfVolume(volume_.params());
    for (size_t i = 0; i < store.size(); ++i) {
      IntegrateFrame(volume_, store.Depth(i), store.Color(i), intrinsics_,
                     *pose_of(store.timestamp(i)), integration_);
    }
    report->reintegrated = store.size();
  }
}

void KinectFusion::UpdateModel(const Eigen::Isometry3d& pose, FrameReport* report) {
  const auto start = std::chrono::steady_clock::now();
  // After a frame started from features (ICP lost it: a jump, or a recording whose frames lie far
  // apart) the next frame is likely far from this one too: its model at no coarser than half
  // resolution, as the feature start's own check uses. slambook joinMap at 640x480 (every frame
  // started from features): the model at 1/4 throughout, ATE 2.22 cm; the check at 1/2 alone 4.56;
  // the check and the model after a feature start at 1/2 (this) 1.18, as with 1/2 throughout.
  const int auto_subsample = options_.ModelSubsample(intrinsics_.width);
  model_subsample_ = report->feature_start ? std::min(2, auto_subsample) : auto_subsample;
  model_ = RaycastModel(pose, model_subsample_);
  report->seconds_raycast = SecondsSince(start);
  report->raycast_chunks = model_.chunks_tested;
  report->raycast_blocks = model_.blocks_projected;
}

RaycastResult KinectFusion::RaycastModel(const Eigen::Isometry3d& pose, int subsample) const {
  // Normals over +-2 pixels at full resolution, +-1 for a subsampled model (at half resolution
  // the same baseline in metres, at 1/4 twice it: +-2 at half resolution smoothed the model's
  // normals and raised the room's ATE from 0.52 to 0.66 cm).
  const int normal_step = std::max(1, 2 / subsample);
  return RaycastVolume(volume_, intrinsics_.Scaled(1.0 / subsample), pose,
                       options_.preprocess.min_depth, options_.preprocess.max_depth,
                       /*with_color=*/false, normal_step);
}

std::optional<Eigen::Isometry3d> KinectFusion::TrackFromFeatures(
    const std::vector<PyramidLevel>& pyramid, const RgbdFrame& frame, FrameReport* report,
    std::string* why) const {
  if (frame.color.empty()) {
    *why = "the frame has no colour";
    return std::nullopt;
  }
  if (!last_fused_.world_from_camera) {
    *why = "no fused frame with colour to match against";
    return std::nullopt;
  }
  const int max_features = options_.features.max_features;
  const FeatureFrame live(frame.color, max_features);
  auto pose =
      PoseFromReference(pyramid, FeatureFrame(last_fused_.color, max_features), last_fused_.depth,
                        *last_fused_.world_from_camera, live, report, why);
  if (pose) return pose;
  // Relocalisation: the camera may have jumped to a place a keyframe saw (a recording that starts
  // over, a camera carried back). Newest first; the first whose features and ICP agree wins. A
  // lost frame tries at most kKeyframesPerFrame of them (a try matches the features both ways and
  // runs PnP: 0.1-0.2 s at 640x480 on slambook), the next lost frame the ones after those, so that
  // a long recording's keyframes are all tried within a few frames without stalling any one.
  constexpr size_t kKeyframesPerFrame = 12;
  const FeatureAlignReport last_fused_features = report->features;
  const std::vector<RgbdFrame>& keyframes = keyframe_selector_.keyframes();
  const size_t n = keyframes.size();
  for (size_t tried = 0; tried < std::min(n, kKeyframesPerFrame); ++tried) {
    const size_t newest_first = relocalise_next_++ % n;
    const RgbdFrame& key = keyframes[n - 1 - newest_first];
    if (key.timestamp == last_fused_.timestamp || !key.world_from_camera) continue;  // tried
    auto [features, fresh] = keyframe_features_.try_emplace(key.timestamp);
    if (fresh) features->second = FeatureFrame(key.color, max_features);
    std::string ignored;
    pose = PoseFromReference(pyramid, features->second, key.depth, *key.world_from_camera, live,
                             report, &ignored);
    if (pose) {
      report->relocalised_against = key.timestamp;
      return pose;
    }
  }
  report->features = last_fused_features;  // the figures of the first try
  if (n > 0) *why += Format("; nor do ", std::min(n, kKeyframesPerFrame), " of ", n, " keyframes");
  return std::nullopt;
}

std::optional<Eigen::Isometry3d> KinectFusion::PoseFromReference(
    const std::vector<PyramidLevel>& pyramid, const FeatureFrame& reference,
    const ImageDepth& reference_depth, const Eigen::Isometry3d& world_from_reference,
    const FeatureFrame& live, FrameReport* report, std::string* why) const {
  const auto reference_from_live = AlignByFeatures(reference, reference_depth, live, intrinsics_,
                                                   options_.features, &report->features);
  if (!reference_from_live) {
    *why = Format(report->features.inliers, " of ", report->features.matches,
                  " matches agree with one pose (", options_.features.min_inliers, " needed)");
    return std::nullopt;
  }
  const Eigen::Isometry3d start = world_from_reference * *reference_from_live;
  // ICP against the model as seen from the features' pose: it must converge (the residual test)
  // on enough of the frame and stay near that pose (the two agree), else the frame stays lost.
  // A frame far from the last one overlaps the model less than tracking's min_inlier_ratio asks
  // (slambook joinMap: 5-10 % of frame 1's pixels); ICP's corrections of PnP poses there were
  // 1.5-12 cm and 0.2-1.6 deg, its wrong convergences 40 cm and 10 deg.
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
  // The model at no coarser than half resolution (this runs on lost and degenerate frames only).
  const int subsample = std::min(2, options_.ModelSubsample(intrinsics_.width));
  const IcpReport icp =
      TrackFrameToModel(pyramid, RaycastModel(start, subsample),
                        intrinsics_.Scaled(1.0 / subsample), options_.icp, &correction);
  constexpr double kMinOverlap = 0.05;
  constexpr double kMaxCorrection = 0.15, kMaxCorrectionDeg = 5.0;  // m, degrees
  const double corrected = correction.translation().norm();
  const double turned = RotationAngle(correction) * 180.0 / M_PI;
  if (icp.inlier_ratio < kMinOverlap || icp.rms_residual > options_.icp.max_rms_residual ||
      corrected > kMaxCorrection || turned > kMaxCorrectionDeg) {
    *why =
        Format(report->features.inliers, " of ", report->features.matches,
               " matches agree, but ICP from that pose does not (overlap ", icp.inlier_ratio,
               ", RMS ", icp.rms_residual, " m, correction ", corrected, " m / ", turned, " deg)");
    return std::nullopt;
  }
  report->icp = icp;
  // Its information as tracking's has it, for a left perturbation of the step from last_good_
  // (last_good_^-1 start correction, with correction perturbed on the left by xi: the step by
  // Ad(last_good_^-1 start) xi), so that loop closure weighs this step as it does the others.
  const Matrix6d to_step = Adjoint(start.inverse() * last_good_);  // Ad(last_good_^-1 start)^-1
  report->icp.information = to_step.transpose() * icp.information * to_step;
  return start * correction;
}

FrameReport KinectFusion::HoldOut(const RgbdFrame& frame, const ImageDepth& depth,
                                  const Eigen::Isometry3d& pose, FrameReport report) {
  report.status = FrameStatus::kHeldOut;
  report.world_from_camera = pose;
  held_out_pose_ = pose;
  if (loops_) loops_->Anchor(frame.timestamp, pose);
  if (held_out_.size() < static_cast<size_t>(FusionOptions::kMaxHeldOut) && !frame.color.empty()) {
    RgbdFrame kept = frame;
    kept.depth = depth;
    kept.world_from_camera = pose;
    held_out_.push_back(std::move(kept));
  }
  return report;
}

void SaveFusionOutputs(const KinectFusion& fusion, const Workspace& workspace,
                       const std::optional<AteResult>& ate,
                       std::optional<size_t> camera_frames_skipped) {
  if (fusion.trajectory().empty()) {
    throw Error("fusion: no frame was fused (all blank or lost); nothing to write");
  }
  using nlohmann::json;
  json frames = json::array();
  std::map<std::string, int> counts;
  double total_seconds = 0.0;
  for (const FrameReport& r : fusion.reports()) {
    ++counts[ToString(r.status)];
    total_seconds += r.seconds();
    json j = {{"index", r.index},
              {"timestamp", r.timestamp},
              {"status", ToString(r.status)},
              {"fused", r.fused},
              {"valid_pixels", r.mask.valid},
              {"nan_or_inf_pixels", r.mask.non_finite},
              {"out_of_range_pixels", r.mask.out_of_range},
              {"icp_iterations", r.icp.iterations},
              {"inlier_ratio", r.icp.inlier_ratio},
              {"rms_residual_m", r.icp.rms_residual},
              {"condition", std::isfinite(r.icp.condition) ? json(r.icp.condition) : json("inf")},
              {"constrained_directions", r.icp.constrained_directions},
              {"feature_start", r.feature_start},
              {"relocalised_against_t",
               r.relocalised_against ? json(*r.relocalised_against) : json(nullptr)},
              {"feature_inliers", r.features.inliers},
              {"blocks_touched", r.integration.blocks_touched},
              {"blocks_allocated", r.integration.blocks_allocated},
              {"raycast_chunks", r.raycast_chunks},
              {"raycast_blocks", r.raycast_blocks},
              {"ms_preprocess", 1e3 * r.seconds_preprocess},
              {"ms_track", 1e3 * r.seconds_track},
              {"ms_integrate", 1e3 * r.seconds_integrate},
              {"ms_raycast", 1e3 * r.seconds_raycast}};
    if (!r.reason.empty()) j["reason"] = r.reason;
    j["colour_pixels"] = r.icp.color_pixels;
    j["colour_rms"] = r.icp.color_rms;
    j["ms_loop"] = 1e3 * r.seconds_loop;
    if (r.loop_closure) {
      const LoopClosureEvent& e = *r.loop_closure;
      j["loop_closure"] = {{"against_t", e.against_timestamp},
                           {"feature_inliers", e.feature_inliers},
                           {"icp_inlier_ratio", e.icp_inlier_ratio},
                           {"icp_rms_m", e.icp_rms},
                           {"discrepancy_m", e.discrepancy_translation},
                           {"discrepancy_deg", e.discrepancy_degrees},
                           {"largest_move_m", e.largest_move},
                           {"largest_turn_deg", e.largest_turn_degrees},
                           {"graph_iterations", e.graph.iterations},
                           {"graph_initial_cost", e.graph.initial_cost},
                           {"graph_final_cost", e.graph.final_cost},
                           {"reintegrated_frames", r.reintegrated}};
    }
    frames.push_back(j);
  }
  const TsdfVolume& volume = fusion.volume();
  json summary = {{"frames", fusion.reports().size()},
                  {"status_counts", counts},
                  {"seconds", total_seconds},
                  {"voxel_size_m", volume.voxel_size()},
                  {"truncation_m", volume.truncation()},
                  {"blocks", volume.num_blocks()},
                  {"megabytes", volume.allocated_bytes() / 1e6},
                  {"keyframes", fusion.keyframes().size()},
                  {"held_out", fusion.held_out().size()}};
  if (camera_frames_skipped) summary["camera_frames_skipped"] = *camera_frames_skipped;
  if (const LoopClosure* loops = fusion.loop_closure()) {
    summary["loop_closure"] = {{"graph_nodes", loops->graph().NodeCount()},
                               {"graph_edges", loops->graph().edges().size()},
                               {"loops_closed", loops->events().size()},
                               {"frames_kept", loops->frames().size()},
                               {"frames_kept_megabytes", loops->frames().bytes() / 1e6},
                               {"stopped_at_frame_memory", !loops->storing()}};
  }
  if (ate) {
    summary["ate"] = {{"pairs", ate->pairs},
                      {"rmse_m", ate->rmse},
                      {"mean_m", ate->mean},
                      {"median_m", ate->median},
                      {"max_m", ate->max}};
  }
  const json options = OptionsToJson(fusion.options());

  WriteTumTrajectory(workspace.Trajectory(), fusion.trajectory());
  WriteTsdfVolume(workspace.Tsdf(), volume);
  TumWriteOptions write;
  write.linear_exr = true;
  if (!fusion.keyframes().empty())
    WriteTumSequence(workspace.Keyframes(), fusion.keyframes(), write);
  std::error_code ec;
  std::filesystem::remove_all(workspace.HeldOut(),
                              ec);  // an earlier run's held-out frames are not this run's
  if (!fusion.held_out().empty()) WriteTumSequence(workspace.HeldOut(), fusion.held_out(), write);
  WriteTextFileAtomically(
      workspace.FusionJson(),
      json({{"summary", summary}, {"options", options}, {"frames", frames}}).dump(1) + "\n");
}

}  // namespace genscene::fusion
