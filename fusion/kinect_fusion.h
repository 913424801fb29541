// The fusion stage (DESIGN.md §2): RGB-D frames in, camera trajectory, sparse TSDF volume and
// keyframes out. Per frame (KinectFusion, Newcombe et al. 2011):
//   1. mask invalid depth (0, NaN, inf, out of range) and build the filtered pyramid;
//   2. track frame-to-model: ICP against the model raycast at the last good pose;
//   3. judge the result: a blank frame, a lost frame (few inliers, large residual or an
//      implausible jump) or a degenerate one (the scene leaves directions unconstrained) is
//      reported and NOT fused, so the model is never corrupted; tracking resumes from the last
//      good pose, i.e. recovers when the camera comes back;
//   3b. a frame ICP loses from the last pose (a jump, or a sparse recording's next view) or
//      leaves degenerate starts again from colour features matched against the last fused frame
//      (feature_align.h); ICP from that start, against the model raycast there, must agree with
//      it, and the features then fix the directions the geometry leaves free;
//   4. fuse the masked raw depth and colour into the TSDF and raycast the model for the next frame;
//   5. offer the frame to the keyframe selector.
#pragma once

#include <Eigen/Geometry>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/rgbd_frame.h"
#include "core/trajectory.h"
#include "core/trajectory_metrics.h"
#include "core/tsdf_volume.h"
#include "core/workspace.h"
#include "fusion/feature_align.h"
#include "fusion/icp.h"
#include "fusion/integrate.h"
#include "fusion/keyframes.h"
#include "fusion/loop_closure.h"
#include "fusion/preprocess.h"
#include "fusion/raycast.h"

namespace genscene::fusion {

struct FusionOptions {
  static constexpr const char* kSection = "fusion";

  double voxel_size = 0.01;      // m between TSDF lattice points
  double truncation = 0.04;      // m; TSDF truncation band (>= 2 voxels; KinectFusion-like 4)
  double max_weight = 128.0;     // running-average weight limit (in measurements at 1 m)
  double memory_cap = 4000.0;    // MB the TSDF may allocate; exceeding it is an error
  std::string tracking = "icp";  // icp (estimate the poses) or known (fuse with the source's poses)
  double min_valid_fraction = 0.05;  // frames with fewer valid depth pixels are blank (skipped)
  // The model is raycast at 1/N of the depth's resolution for ICP (normals over +-1 pixel of it,
  // +-2 at full resolution). 0 = by the image's width: 2 up to 320 pixels wide, beyond that width /
  // 160 rounded (4 at 640x480), at most 8 (ModelSubsample). Measured with tracking at full
  // resolution on the synthetic room, 150 frames: N = 2 gives ATE 0.521 cm against 0.515 at full
  // resolution (320x240) and 0.337 against 0.338 (640x480), TUM fr1/desk 0.1773 against 0.1774 cm,
  // for a third of the raycast time; N = 3: 0.581 / 0.359 cm. At 640x480 with tracking at 320x240
  // (tracking_subsample), N = 2 / 3 / 4: raycast 19.8 / 10.6 / 7.0 ms a frame on 7-Scenes,
  // ATE 7-Scenes 0.778 / 0.795 / 0.808 cm, TUM fr1/desk 0.169 / 0.166 / 0.164 cm, the
  // path-traced room (Kinect noise) 0.435 / 0.495 / 0.507 cm (bench_fusion --set
  // model_subsample=N).
  int model_subsample = 0;
  // Tracking's pyramid starts at 1/N of the depth's resolution (the masked depth reduced by
  // edge-aware 2x2 averaging; BuildPyramid): 1, 2 or 4; 0 = by the image's width, the largest
  // power of two that leaves the finest level at least 320 pixels wide (1 at 320x240, 2 at
  // 640x480; TrackingSubsample). Integration, keyframes and loop closure keep the full resolution.
  // At 640x480, full resolution / 320x240 (with the model at 1/2): tracking 27.6 / 7.4 ms and
  // preprocessing 14.6 / 3.8 ms a frame on 7-Scenes, ATE 7-Scenes 0.792 / 0.778 cm, TUM fr1/desk
  // 0.176 / 0.169 cm, the path-traced room 0.358 / 0.435 cm.
  int tracking_subsample = 0;
  // Blocks are allocated along the truncation band of every Nth pixel in each direction; every
  // pixel still updates the voxels of the allocated blocks (integrate.h). A block that only a
  // lone pixel's band reaches (the rim of an observed region, a flying pixel) then waits until
  // more of the surface is seen. 0 = by the image's width, the same angular spacing at every
  // resolution: width / 160 rounded, at least 1 (2 at 320x240, 4 at 640x480; AllocationStride).
  // Measured on the synthetic room 150 frames with Kinect noise, known poses, uniform weights
  // (bench/compare_open3d_fusion.py; Open3D samples every 4th pixel):
  //   320x240: N = 1: 8301 blocks, mesh RMS 4.77 mm, 93 fps; N = 2: 7959, 4.68 mm, 127 fps;
  //            N = 3: 7664, 4.60 mm, 140 fps; Open3D 4.72 mm; tracked ATE 0.521 / 0.531 / 0.528 cm;
  //   640x480: N = 1: 8644 blocks, 4.27 mm, 55 fps; N = 2: 8304, 4.28 mm, 91 fps; N = 4: 7966,
  //            4.23 mm, 93-111 fps; Open3D 4.27 mm; ATE 0.337 / 0.337 / 0.340 cm;
  // the share of the true surface within 1 cm of the mesh moved by less than 0.05 % throughout.
  int allocation_stride = 0;
  // Measurements weighted by the inverse variance of a structured-light sensor's depth noise
  // ("noise", integrate.h's ObservationWeight) or all alike ("uniform", as Open3D does).
  std::string weighting = "noise";
  // Every holdout-th frame (the 2nd, ... of each holdout; 0 = none) is tracked for its pose but
  // neither fused nor offered as a keyframe: the real views the model is judged on (the first
  // kMaxHeldOut of them are kept, HeldOut()).
  int holdout = 0;
  static constexpr int kMaxHeldOut = 50;
  // A frame ICP loses from the last pose is started again from ORB features matched against the
  // last fused frame (needs colour). On the 5 far-apart frames of slambook's joinMap (0.3-0.7 m,
  // 15-25 deg between frames) ICP alone loses 4; on recordings it tracks nothing changes.
  bool feature_tracking = true;
  PreprocessOptions preprocess;
  IcpOptions icp;
  LoopClosureOptions loop;
  FeatureAlignOptions features;
  KeyframeOptions keyframes;

  template <typename V>
  void Visit(V&& v) {
    v("voxel_size", voxel_size, "m", "distance between TSDF voxels");
    v("truncation", truncation, "m", "TSDF truncation distance");
    v("max_weight", max_weight, "", "limit of the per-voxel running-average weight");
    v("memory_cap", memory_cap, "MB", "memory the TSDF may allocate (error beyond)");
    v("tracking", tracking, "", "icp (estimate poses) or known (use the source's poses)");
    v("min_valid_fraction", min_valid_fraction, "",
      "frames with fewer valid depth pixels are skipped as blank");
    v("model_subsample", model_subsample, "",
      "raycast the model for tracking at 1/N of the depth's resolution (1 = full; 0 = 2 up to "
      "320 px wide, else width / 160 rounded, at most 8)");
    v("tracking_subsample", tracking_subsample, "",
      "track on a depth pyramid starting at 1/N of the depth's resolution (1, 2 or 4; 0 = the "
      "largest that keeps it >= 320 pixels wide)");
    v("allocation_stride", allocation_stride, "px",
      "allocate TSDF blocks along the band of every Nth pixel (1 = all, 0 = width / 160)");
    v("weighting", weighting, "",
      "TSDF measurement weights: noise (1 / sigma(z)^2 of Kinect-like depth noise) or uniform");
    v("holdout", holdout, "frames",
      "keep every Nth frame out of the model (tracked for its pose only) to judge the model on it "
      "(0 = none)");
    v("range_min", preprocess.min_depth, "m", "depth nearer than this is invalid (sensor range)");
    v("range_max", preprocess.max_depth, "m", "depth farther than this is invalid (sensor range)");
    v("bilateral_radius", preprocess.bilateral_radius, "px",
      "bilateral filter half-width for tracking at full resolution (0 = off; a subsampled "
      "pyramid is not filtered)");
    v("bilateral_sigma_space", preprocess.bilateral_sigma_space, "px", "bilateral spatial sigma");
    v("bilateral_sigma_depth", preprocess.bilateral_sigma_depth, "m", "bilateral range sigma");
    v("icp_iterations_fine", icp.iterations_fine, "", "ICP iterations at full resolution");
    v("icp_iterations_middle", icp.iterations_middle, "", "ICP iterations at half resolution");
    v("icp_iterations_coarse", icp.iterations_coarse, "", "ICP iterations at quarter resolution");
    v("icp_max_distance", icp.max_distance, "m", "largest point distance of a correspondence");
    v("icp_max_angle", icp.max_angle, "deg", "largest normal angle of a correspondence");
    v("icp_huber_delta", icp.huber_delta, "m", "Huber threshold of the point-to-plane residual");
    v("icp_min_step", icp.min_step, "m or rad",
      "a resolution level stops iterating when a pose update is smaller");
    v("icp_color_weight", icp.color_weight, "m",
      "weight of the photometric term beside point-to-plane ICP, per unit of brightness "
      "(0 = geometry only)");
    v("icp_color_huber", icp.color_huber, "",
      "Huber threshold of the photometric residual (brightness in [0, 1])");
    v("degenerate_eigen_ratio", icp.degenerate_eigen_ratio, "",
      "eigenvalue ratio below which a pose direction counts as unconstrained");
    v("min_inlier_ratio", icp.min_inlier_ratio, "", "tracking is lost below this inlier fraction");
    v("max_rms_residual", icp.max_rms_residual, "m", "tracking is lost above this RMS residual");
    v("max_translation", icp.max_translation, "m", "tracking is lost when a frame moves farther");
    v("max_rotation", icp.max_rotation, "deg", "tracking is lost when a frame turns more");
    v("feature_tracking", feature_tracking, "",
      "a frame ICP loses starts again from ORB features matched against the last fused frame, "
      "else against the keyframes (relocalisation)");
    v("feature_max", features.max_features, "", "ORB keypoints per image for feature tracking");
    v("feature_min_inliers", features.min_inliers, "",
      "feature matches consistent with one pose needed to start ICP from it");
    v("loop_closure", loop.enabled, "",
      "find revisits (features between pose-graph nodes, verified by ICP), optimise the pose "
      "graph and re-integrate the volume at the corrected poses (tracking = icp only)");
    v("loop_node_translation", loop.node_translation, "m",
      "camera motion that places a new pose-graph node");
    v("loop_node_rotation", loop.node_rotation, "deg",
      "camera rotation that places a new pose-graph node");
    v("loop_min_separation", loop.min_separation, "frames",
      "a node is matched only against nodes at least this many fused frames older");
    v("loop_search_radius", loop.search_radius, "m",
      "old nodes within this distance of a new node are loop candidates");
    v("loop_search_angle", loop.search_angle, "deg",
      "old nodes turned by less than this from a new node are loop candidates");
    v("loop_max_candidates", loop.max_candidates, "", "loop candidates tried per new node");
    v("loop_min_correction", loop.min_correction, "m",
      "a closed loop moving no frame farther leaves the volume as it is (no re-integration)");
    v("loop_frame_memory", loop.frame_memory, "MB",
      "memory for the fused frames kept for re-integration; beyond it loop closure stops");
    v("keyframe_translation", keyframes.translation, "m",
      "camera motion that makes a new keyframe due");
    v("keyframe_rotation", keyframes.rotation, "deg",
      "camera rotation that makes a new keyframe due");
    v("keyframe_new_surface", keyframes.new_surface, "",
      "share of a frame's surface no keyframe saw that makes a new keyframe due (0 = off)");
    v("keyframe_window", keyframes.window, "frames",
      "the sharpest of this many frames becomes the keyframe");
    v("min_keyframes", keyframes.min_keyframes, "",
      "at least this many keyframes, spread over the recording, when it has the frames");
    v("max_keyframes", keyframes.max_keyframes, "", "keyframe limit");
  }
  void Validate() const;
  // allocation_stride for images `width` pixels wide (0 resolved: width / 160 rounded, >= 1).
  int AllocationStride(int width) const;
  // model_subsample for images `width` pixels wide (0 resolved).
  int ModelSubsample(int width) const;
  // tracking_subsample for images `width` pixels wide (0 resolved).
  int TrackingSubsample(int width) const;
  TsdfVolumeParams VolumeParams(const Eigen::Vector3d& origin) const;
};

enum class FrameStatus {
  kInitial,     // first frame: defines the world (or its known pose does)
  kTracked,     // ICP converged, fused
  kKnownPose,   // tracking = known: fused at the source's pose
  kDegenerate,  // ICP left directions unconstrained: pose kept along them, not fused
  kLost,        // ICP failed: not fused, pose not updated
  kBlank,       // too few valid depth pixels: skipped
  kHeldOut,     // tracked (or at its known pose) for judging the model: not fused, not a keyframe
};
const char* ToString(FrameStatus status);

struct FrameReport {
  size_t index = 0;
  double timestamp = 0.0;
  FrameStatus status = FrameStatus::kInitial;
  bool fused = false;
  std::string reason;  // why a frame was lost, blank or degenerate
  MaskStats mask;
  IcpReport icp;
  FeatureAlignReport features;  // when ICP lost the frame and features were tried
  bool feature_start = false;   // tracked by ICP from the features' pose
  // The time stamp of the keyframe the features' pose came from when the last fused frame gave
  // none: the camera was relocalised.
  std::optional<double> relocalised_against;
  IntegrationStats integration;
  // A loop closed at this frame (loop_closure.h), and the fused frames re-integrated for it.
  std::optional<LoopClosureEvent> loop_closure;
  size_t reintegrated = 0;
  // The model raycast's pass over the volume: chunks tested against the frustum, blocks of the
  // chunks inside it projected (0 when no model was raycast).
  size_t raycast_chunks = 0, raycast_blocks = 0;
  // The estimate when the frame was processed (none when lost/blank); a later closed loop moves
  // trajectory()'s poses, not this.
  std::optional<Eigen::Isometry3d> world_from_camera;
  double seconds_preprocess = 0.0, seconds_track = 0.0, seconds_integrate = 0.0,
         seconds_raycast = 0.0;
  // Pose-graph upkeep: frame kept, node features, loop search and optimisation, re-integration.
  double seconds_loop = 0.0;
  double seconds() const {
    return seconds_preprocess + seconds_track + seconds_integrate + seconds_raycast + seconds_loop;
  }
};

class KinectFusion {
 public:
  KinectFusion(const FusionOptions& options, const CameraIntrinsics& intrinsics);

  // Processes one frame. Throws Error on frames that do not match the intrinsics, a missing pose
  // with tracking = known, or a TSDF memory cap that is exceeded.
  FrameReport ProcessFrame(const RgbdFrame& frame);
  // Closes the keyframe selection (call after the last frame).
  void Finish() { keyframe_selector_.Finish(); }

  const TsdfVolume& volume() const { return volume_; }
  const Trajectory& trajectory() const { return trajectory_; }  // fused/tracked frames only
  const std::vector<FrameReport>& reports() const { return reports_; }
  const std::vector<RgbdFrame>& keyframes() const { return keyframe_selector_.keyframes(); }
  // The held-out frames with their estimated poses, in order (at most kMaxHeldOut).
  const std::vector<RgbdFrame>& held_out() const { return held_out_; }
  const CameraIntrinsics& intrinsics() const { return intrinsics_; }
  const FusionOptions& options() const { return options_; }
  // The pose graph, its loop closures and the frames kept (null with loop_closure off or
  // tracking = known).
  const LoopClosure* loop_closure() const { return loops_ ? &*loops_ : nullptr; }
  // The model as seen from the last good pose, which ICP tracks against; empty before the first
  // frame and with tracking = known (no raycast is made then).
  const RaycastResult& model() const { return model_; }

 private:
  bool HeldOut(size_t index) const {
    return options_.holdout > 0 && index % static_cast<size_t>(options_.holdout) ==
                                       static_cast<size_t>(options_.holdout - 1);
  }
  // Records a held-out frame at `pose` (kept while fewer than kMaxHeldOut are) and its report.
  FrameReport HoldOut(const RgbdFrame& frame, const ImageDepth& depth,
                      const Eigen::Isometry3d& pose, FrameReport report);
  // After a closed loop: every pose from the graph (trajectory, keyframes, held-out frames, the
  // last good pose) and, when a frame moved by min_correction or more, the volume re-integrated
  // (the caller raycasts the model again).
  void ApplyLoopClosure(FrameReport* report);
  // The model seen from `pose` at 1/subsample of the depth's resolution (with intrinsics
  // intrinsics_.Scaled(1 / subsample)).
  RaycastResult RaycastModel(const Eigen::Isometry3d& pose, int subsample) const;
  // model_ = the model raycast at `pose`, its time and its pass over the volume in `report`.
  void UpdateModel(const Eigen::Isometry3d& pose, FrameReport* report);
  // Step 3b: the pose of a frame ICP lost, from features against the last fused frame refined by
  // ICP, when both agree, else against the keyframes, newest first (relocalisation); `report`
  // gets the feature and ICP figures, `why` the reason when none agrees.
  std::optional<Eigen::Isometry3d> TrackFromFeatures(const std::vector<PyramidLevel>& pyramid,
                                                     const RgbdFrame& frame, FrameReport* report,
                                                     std::string* why) const;
  // The pose from features against one reference (its features, depth and pose), verified by
  // ICP against the model from there.
  std::optional<Eigen::Isometry3d> PoseFromReference(const std::vector<PyramidLevel>& pyramid,
                                                     const FeatureFrame& reference,
                                                     const ImageDepth& reference_depth,
                                                     const Eigen::Isometry3d& world_from_reference,
                                                     const FeatureFrame& live, FrameReport* report,
                                                     std::string* why) const;

  FusionOptions options_;
  CameraIntrinsics intrinsics_;
  TsdfVolume volume_;
  bool started_ = false;
  Eigen::Isometry3d last_good_ = Eigen::Isometry3d::Identity();  // pose the model was raycast at
  RaycastResult model_;
  // The brightness pyramid of the frame at last_good_ (the photometric term's reference; empty
  // without colour or with color_weight 0).
  std::vector<IntensityLevel> model_intensity_;
  // model_ is raycast at intrinsics_.Scaled(1 / model_subsample_) (ModelSubsample, or finer after
  // a feature start).
  int model_subsample_ = 2;
  IntegrationOptions integration_;  // allocation stride (resolved by the image width) and weights
  Trajectory trajectory_;
  std::vector<FrameReport> reports_;
  KeyframeSelector keyframe_selector_;
  std::vector<RgbdFrame> held_out_;
  std::optional<Eigen::Isometry3d> held_out_pose_;  // a held-out frame's pose after last_good_
  RgbdFrame last_fused_;  // colour, depth and pose of the last fused frame (feature tracking)
  // The keyframes' features, by time stamp, detected when a lost frame first needs them.
  mutable std::map<double, FeatureFrame> keyframe_features_;
  mutable size_t relocalise_next_ = 0;  // the keyframe a lost frame tries first, newest = 0
  std::optional<LoopClosure> loops_;
};

// Writes the stage's outputs into the workspace, each atomically: trajectory.txt (TUM),
// tsdf.gsv, keyframes/ (a TUM-layout view set with linear EXR colour) and fusion.json (options,
// per-frame reports and totals, with the trajectory error when the caller computed one, and for a
// live camera the frames it sent that fusion had no time for).
void SaveFusionOutputs(const KinectFusion& fusion, const Workspace& workspace,
                       const std::optional<AteResult>& ate = std::nullopt,
                       std::optional<size_t> camera_frames_skipped = std::nullopt);

}  // namespace genscene::fusion
