// Loop closure for fusion: a pose graph over nodes placed along the tracked trajectory, revisits
// found by colour features between a new node and the old nodes near it and verified by ICP
// between their depth images, the graph optimised (pose_graph.h), and every frame moved with the
// node it hangs from. The fused frames are kept, compactly, so that the volume can be made again
// from the corrected poses (re-integration: KinectFusion does it when a loop moves a frame by
// more than LoopClosureOptions::min_correction).
//
// Every pose that fusion reports (tracked, degenerate and held-out frames) is anchored to the
// newest node at or before it: pose = node pose * node_from_frame. Moving the nodes moves them.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "core/camera.h"
#include "core/image.h"
#include "fusion/feature_align.h"
#include "fusion/icp.h"
#include "fusion/pose_graph.h"
#include "fusion/preprocess.h"

namespace genscene::fusion {

// The ICP that verifies a revisit starts from the features' pose, which can be centimetres off:
// its pyramid has this many levels more than tracking's. With tracking's 3 levels at 640x480,
// ICP from 3 cm / 2 degrees off ended 1-5 cm off on 7 of 80 pairs of the textured room, all of
// which the verification's tests accepted; with 4 levels on 2 (bench_pcl_registration,
// fusion/README.md).
inline constexpr int kLoopVerifyExtraLevels = 1;

// Uncertainty of relative poses for the pose graph, with twists [translation (m); rotation (rad)]
// (as IcpReport::information) and exp of core/se3.h:
// the adjoint of `t`, exp(Ad(t) xi) = t exp(xi) t^-1;
Matrix6d Adjoint(const Eigen::Isometry3d& t);
// the covariance of a right perturbation of `m` (m exp(eps)) from the information of a left one
// (exp(xi) m): eps = Ad(m^-1) xi; directions the information leaves (nearly) free get a variance
// 1e6 times the best-measured direction's;
Matrix6d RightCovarianceFromLeftInformation(const Eigen::Isometry3d& m,
                                            const Matrix6d& information);
// and the covariance of the right perturbation of a x step, from that of a (`covariance`) and of
// step (`step_covariance`), independent, to first order.
Matrix6d ComposeRightCovariance(const Matrix6d& covariance, const Eigen::Isometry3d& step,
                                const Matrix6d& step_covariance);

// The view of a depth image's pyramid level as a model for TrackFrameToModel (depth, points and
// normals; no colour): how loop closure aligns one kept frame to another.
RaycastResult ModelFromDepth(const PyramidLevel& level);

struct LoopClosureOptions {
  bool enabled = true;
  // A new node once the camera has moved this far from the last node (either test).
  double node_translation = 0.3;  // m
  double node_rotation = 20.0;    // degrees
  // A node is matched against nodes at least this many frames older (not the recent past, which
  // tracking already ties to it), whose pose lies within search_radius and whose viewing
  // direction within search_angle of its own, nearest first, at most max_candidates of them.
  int min_separation = 50;
  double search_radius = 1.0;  // m
  double search_angle = 60.0;  // degrees
  int max_candidates = 2;
  // A closed loop that moves no frame farther than this leaves the volume as it is.
  double min_correction = 0.005;  // m
  // Fused frames kept for re-integration, at most this much memory (640x480: 1.5 MB a frame);
  // beyond it no frame is kept and no further loop is closed.
  double frame_memory = 2048.0;  // MB
  void Validate() const;
};

// Fused frames kept for re-integration: depth as 16-bit integers (steps of max_depth / 65000,
// 0.09 mm for a 6 m range), colour as 8-bit sRGB (values above 1 are clipped: an HDR frame
// re-integrated has its highlights at 1).
class FrameStore {
 public:
  explicit FrameStore(double max_depth = 6.0) : depth_step_(max_depth / 65000.0) {}
  void Add(double timestamp, const ImageDepth& depth, const ImageRgb& color);
  size_t size() const { return frames_.size(); }
  double timestamp(size_t i) const { return frames_[i].timestamp; }
  ImageDepth Depth(size_t i) const;
  ImageRgb Color(size_t i) const;  // empty when the frame had none
  size_t bytes() const { return bytes_; }

 private:
  struct Frame {
    double timestamp = 0.0;
    int width = 0, height = 0;
    std::vector<uint16_t> depth;
    std::vector<uint8_t> color;  // sRGB, 3 per pixel; empty without colour
  };
  double depth_step_;
  std::vector<Frame> frames_;
  size_t bytes_ = 0;
};

// A revisit found, verified and closed.
struct LoopClosureEvent {
  double node_timestamp = 0.0;     // the new node (a frame of this recording)
  double against_timestamp = 0.0;  // the old node it was matched to
  int feature_inliers = 0;
  double icp_inlier_ratio = 0.0, icp_rms = 0.0;
  // The loop's discrepancy: how far the measured relative pose lies from the tracked one.
  double discrepancy_translation = 0.0, discrepancy_degrees = 0.0;
  PoseGraphReport graph;
  // The largest move by the optimisation of a frame's camera, or of the point 2 m in front of it
  // (a turn moves what the frame saw), and the largest turn of a frame.
  double largest_move = 0.0, largest_turn_degrees = 0.0;
};

class LoopClosure {
 public:
  LoopClosure(const LoopClosureOptions& options, const CameraIntrinsics& intrinsics,
              const PreprocessOptions& preprocess, const IcpOptions& icp,
              const FeatureAlignOptions& features);

  // A frame fusion gave a pose (tracked, degenerate or held out): anchored to the newest node.
  void Anchor(double timestamp, const Eigen::Isometry3d& world_from_camera);
  // The next pose of the chain tracking follows (a fused or a degenerate frame: the pose the next
  // frame is tracked from), with the information of its ICP relative to the previous one
  // (IcpReport::information), or null where there is none (the first frame, poses handed in): such
  // a step counts as measured to kStepSigmaTranslation / kStepSigmaDegrees. The steps' covariances,
  // carried along the chain, give the odometry edge between two nodes its information, so that a
  // loop's discrepancy goes where tracking was weakest.
  void Advance(const Eigen::Isometry3d& world_from_camera, const Matrix6d* information);
  static constexpr double kStepSigmaTranslation = 0.01;  // m
  static constexpr double kStepSigmaDegrees = 1.0;
  // A fused frame (anchored by this call too, and advanced with `information`): kept for
  // re-integration; a node when the camera moved enough, which is then matched against the old
  // nodes near it. Returns the closure when one was found and the graph optimised (the poses of
  // PoseOf have moved then).
  std::optional<LoopClosureEvent> AddFused(double timestamp, const Eigen::Isometry3d& pose,
                                           const ImageDepth& masked_depth, const ImageRgb& color,
                                           const Matrix6d* information = nullptr);

  // The current pose of an anchored frame (moved by every closed loop).
  std::optional<Eigen::Isometry3d> PoseOf(double timestamp) const;
  const FrameStore& frames() const { return store_; }
  const PoseGraph& graph() const { return graph_; }
  bool storing() const { return storing_; }  // false once frame_memory was reached
  const std::vector<LoopClosureEvent>& events() const { return events_; }

 private:
  struct Node {
    double timestamp = 0.0;
    size_t fused_index = 0;  // among the fused frames
    size_t stored = 0;       // its frame in the store (depth and colour)
    FeatureFrame features;
  };
  struct AnchorPose {
    int node = -1;  // -1: before the first node (the pose as given)
    Eigen::Isometry3d node_from_frame = Eigen::Isometry3d::Identity();
  };
  // The pose of `live` in the frame of `old`, from features and verified by ICP; `information`
  // (optional) receives that of the ICP (IcpReport::information).
  std::optional<Eigen::Isometry3d> MatchNodes(const Node& old, const Node& live,
                                              LoopClosureEvent* event,
                                              Matrix6d* information = nullptr) const;

  LoopClosureOptions options_;
  CameraIntrinsics intrinsics_;
  PreprocessOptions preprocess_;
  IcpOptions icp_;
  FeatureAlignOptions features_;
  PoseGraph graph_;
  std::vector<Node> nodes_;
  std::map<double, AnchorPose> anchors_;
  FrameStore store_;
  size_t fused_ = 0;  // fused frames offered
  // The chain since the newest node: its last pose and the covariance of the newest node's
  // relative pose to it (right perturbation [translation; rotation]).
  std::optional<Eigen::Isometry3d> chain_pose_;
  Matrix6d chain_covariance_ = Matrix6d::Zero();
  bool storing_ = true;
  std::vector<LoopClosureEvent> events_;
};

}  // namespace genscene::fusion
