#include "fusion/loop_closure.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>

#include "core/check.h"
#include "core/color.h"
#include "core/options.h"
#include "core/parallel.h"
#include "core/se3.h"

namespace genscene::fusion {

namespace {

// The pose graph's information (of e = [rotation; translation]) from a covariance of a right
// perturbation [translation; rotation].
Matrix6d GraphInformation(const Matrix6d& covariance) {
  Eigen::PermutationMatrix<6> swap;
  swap.indices() << 3, 4, 5, 0, 1, 2;  // [t; r] -> [r; t]
  Matrix6d information = covariance.inverse();
  information = swap * information * swap.transpose();
  return 0.5 * (information + information.transpose());
}

// The pose with its rotation made exactly orthonormal (poses read from text files, e.g. a
// recording's first pose, carry rounding that the pose graph's rigidity check refuses).
Eigen::Isometry3d Orthonormalized(const Eigen::Isometry3d& pose) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::Quaterniond(pose.linear()).normalized().toRotationMatrix();
  out.translation() = pose.translation();
  return out;
}

double Degrees(const Eigen::Isometry3d& motion) {
  return RotationAngle(motion) * 180.0 / M_PI;
}

}  // namespace

Matrix6d Adjoint(const Eigen::Isometry3d& t) {
  const Eigen::Matrix3d r = t.linear();
  Matrix6d a = Matrix6d::Zero();
  a.topLeftCorner<3, 3>() = r;
  a.topRightCorner<3, 3>() = Skew(t.translation()) * r;
  a.bottomRightCorner<3, 3>() = r;
  return a;
}

Matrix6d RightCovarianceFromLeftInformation(const Eigen::Isometry3d& m,
                                            const Matrix6d& information) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(information);
  const double floor = 1e-6 * std::max(eig.eigenvalues().maxCoeff(), 1e-300);
  const Vector6d inverse = eig.eigenvalues().cwiseMax(floor).cwiseInverse();
  const Matrix6d covariance =
      eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
  const Matrix6d a = Adjoint(m.inverse());
  return a * covariance * a.transpose();
}

Matrix6d ComposeRightCovariance(const Matrix6d& covariance, const Eigen::Isometry3d& step,
                                const Matrix6d& step_covariance) {
  const Matrix6d a = Adjoint(step.inverse());
  return a * covariance * a.transpose() + step_covariance;
}

RaycastResult ModelFromDepth(const PyramidLevel& level) {
  RaycastResult model;
  model.depth = level.depth;
  model.points = level.vertices;
  model.normals = level.normals;
  return model;
}

void LoopClosureOptions::Validate() const {
  RequireRange("loop_node_translation", node_translation, 0.01, 100.0);
  RequireRange("loop_node_rotation", node_rotation, 1.0, 180.0);
  RequireRange("loop_min_separation", min_separation, 1, 1000000);
  RequireRange("loop_search_radius", search_radius, 0.0, 100.0);
  RequireRange("loop_search_angle", search_angle, 0.0, 180.0);
  RequireRange("loop_max_candidates", max_candidates, 0, 100);
  RequireRange("loop_min_correction", min_correction, 0.0, 10.0);
  RequireRange("loop_frame_memory", frame_memory, 0.0, 1e6);
}

void FrameStore::Add(double timestamp, const ImageDepth& depth, const ImageRgb& color) {
  Frame f;
  f.timestamp = timestamp;
  f.width = depth.width();
  f.height = depth.height();
  f.depth.resize(depth.size());
  if (!color.empty()) {
    GS_CHECK(color.SameSize(depth));
    f.color.resize(3 * color.size());
  }
  const float inv_step = static_cast<float>(1.0 / depth_step_);
  const size_t width = static_cast<size_t>(depth.width());
  // Linear [0, 1] to 8-bit sRGB through a table (clamped; NaN black).
  const uint8_t* srgb8 = Srgb8Table();
  ParallelFor(0, static_cast<size_t>(depth.height()), [&](size_t row) {
    for (size_t i = row * width; i < (row + 1) * width; ++i) {
      const float z = depth.pixels()[i];
      f.depth[i] = std::isfinite(z) && z > 0.0f
                       ? static_cast<uint16_t>(std::min(65535.0f, std::round(z * inv_step)))
                       : 0;
      if (f.color.empty()) continue;
      for (int c = 0; c < 3; ++c)
        f.color[3 * i + static_cast<size_t>(c)] = srgb8[SrgbTableIndex(color.pixels()[i][c])];
    }
  });
  bytes_ += f.depth.size() * sizeof(uint16_t) + f.color.size();
  frames_.push_back(std::move(f));
}

ImageDepth FrameStore::Depth(size_t i) const {
  const Frame& f = frames_.at(i);
  ImageDepth depth(f.width, f.height, 0.0f);
  for (size_t p = 0; p < f.depth.size(); ++p)
    depth.pixels()[p] = static_cast<float>(f.depth[p] * depth_step_);
  return depth;
}

ImageRgb FrameStore::Color(size_t i) const {
  const Frame& f = frames_.at(i);
  if (f.color.empty()) return ImageRgb();
  static const std::array<float, 256> kLinear = [] {
    std::array<float, 256> table{};
    for (int v = 0; v < 256; ++v) table[static_cast<size_t>(v)] = SrgbToLinear(v / 255.0f);
    return table;
  }();
  ImageRgb color(f.width, f.height, Eigen::Vector3f::Zero());
  for (size_t p = 0; p < color.size(); ++p) {
    color.pixels()[p] = Eigen::Vector3f(kLinear[f.color[3 * p]], kLinear[f.color[3 * p + 1]],
                                        kLinear[f.color[3 * p + 2]]);
  }
  return color;
}

LoopClosure::LoopClosure(const LoopClosureOptions& options, const CameraIntrinsics& intrinsics,
                         const PreprocessOptions& preprocess, const IcpOptions& icp,
                         const FeatureAlignOptions& features)
    : options_(options),
      intrinsics_(intrinsics),
      preprocess_(preprocess),
      icp_(icp),
      features_(features),
      store_(preprocess.max_depth) {
  options_.Validate();
}

void LoopClosure::Advance(const Eigen::Isometry3d& world_from_camera, const Matrix6d* information) {
  const Eigen::Isometry3d pose = Orthonormalized(world_from_camera);
  if (chain_pose_) {
    const Eigen::Isometry3d step = chain_pose_->inverse() * pose;
    Matrix6d step_covariance;
    if (information != nullptr && information->allFinite() && information->trace() > 0.0) {
      step_covariance = RightCovarianceFromLeftInformation(step, *information);
    } else {
      const double sigma_r = kStepSigmaDegrees * M_PI / 180.0;
      Vector6d diagonal;
      diagonal << Eigen::Vector3d::Constant(kStepSigmaTranslation * kStepSigmaTranslation),
          Eigen::Vector3d::Constant(sigma_r * sigma_r);
      step_covariance = diagonal.asDiagonal();
    }
    chain_covariance_ = ComposeRightCovariance(chain_covariance_, step, step_covariance);
  }
  chain_pose_ = pose;
}

void LoopClosure::Anchor(double timestamp, const Eigen::Isometry3d& world_from_camera) {
  AnchorPose a;
  a.node = static_cast<int>(nodes_.size()) - 1;
  a.node_from_frame =
      a.node < 0 ? world_from_camera
                 : graph_.poses()[static_cast<size_t>(a.node)].inverse() * world_from_camera;
  anchors_[timestamp] = a;
}

std::optional<Eigen::Isometry3d> LoopClosure::PoseOf(double timestamp) const {
  const auto it = anchors_.find(timestamp);
  if (it == anchors_.end()) return std::nullopt;
  if (it->second.node < 0) return it->second.node_from_frame;
  return Eigen::Isometry3d(graph_.poses()[static_cast<size_t>(it->second.node)] *
                           it->second.node_from_frame);
}

std::optional<LoopClosureEvent> LoopClosure::AddFused(double timestamp,
                                                      const Eigen::Isometry3d& tracked_pose,
                                                      const ImageDepth& masked_depth,
                                                      const ImageRgb& color,
                                                      const Matrix6d* information) {
  const Eigen::Isometry3d pose = Orthonormalized(tracked_pose);
  Advance(pose, information);
  const size_t fused_index = fused_++;
  if (storing_) {
    const size_t frame_bytes = masked_depth.size() * (sizeof(uint16_t) + (color.empty() ? 0 : 3));
    if (static_cast<double>(store_.bytes() + frame_bytes) > options_.frame_memory * 1e6) {
      storing_ = false;
    } else {
      store_.Add(timestamp, masked_depth, color);
    }
  }
  bool due = nodes_.empty();
  if (!due) {
    const Eigen::Isometry3d motion = graph_.poses().back().inverse() * pose;
    due = motion.translation().norm() > options_.node_translation ||
          Degrees(motion) > options_.node_rotation;
  }
  if (!due || !storing_) {
    Anchor(timestamp, pose);
    return std::nullopt;
  }
  const int id = graph_.AddNode(pose);
  if (id > 0) {
    PoseGraphEdge odometry;
    odometry.from = id - 1;
    odometry.to = id;
    odometry.measured =
        Orthonormalized(graph_.poses()[static_cast<size_t>(id - 1)].inverse() * pose);
    odometry.information = GraphInformation(chain_covariance_);
    graph_.AddEdge(odometry);
  }
  chain_covariance_.setZero();
  Node node;
  node.timestamp = timestamp;
  node.fused_index = fused_index;
  node.stored = store_.size() - 1;
  if (!color.empty()) node.features = FeatureFrame(color, features_.max_features);
  nodes_.push_back(std::move(node));
  Anchor(timestamp, pose);
  if (!options_.enabled || nodes_.back().features.empty()) return std::nullopt;

  // Candidates: old nodes near this one, nearest first.
  const Node& live = nodes_.back();
  std::vector<std::pair<double, int>> candidates;
  for (int j = 0; j + 1 < id; ++j) {
    const Node& old = nodes_[static_cast<size_t>(j)];
    if (live.fused_index - old.fused_index < static_cast<size_t>(options_.min_separation) ||
        old.features.empty()) {
      continue;
    }
    const Eigen::Isometry3d relative = graph_.poses()[static_cast<size_t>(j)].inverse() * pose;
    const double distance = relative.translation().norm();
    if (distance > options_.search_radius || Degrees(relative) > options_.search_angle) continue;
    candidates.push_back({distance, j});
  }
  std::sort(candidates.begin(), candidates.end());
  if (candidates.size() > static_cast<size_t>(options_.max_candidates))
    candidates.resize(static_cast<size_t>(options_.max_candidates));
  for (const auto& [distance, j] : candidates) {
    LoopClosureEvent event;
    const Node& old = nodes_[static_cast<size_t>(j)];
    Matrix6d loop_information;
    const auto old_from_live = MatchNodes(old, live, &event, &loop_information);
    if (!old_from_live) continue;
    event.node_timestamp = live.timestamp;
    event.against_timestamp = old.timestamp;
    const Eigen::Isometry3d tracked = graph_.poses()[static_cast<size_t>(j)].inverse() * pose;
    const Eigen::Isometry3d discrepancy = tracked.inverse() * *old_from_live;
    event.discrepancy_translation = discrepancy.translation().norm();
    event.discrepancy_degrees = Degrees(discrepancy);
    PoseGraphEdge loop;
    loop.from = j;
    loop.to = id;
    loop.measured = Orthonormalized(*old_from_live);
    loop.information =
        GraphInformation(RightCovarianceFromLeftInformation(*old_from_live, loop_information));
    graph_.AddEdge(loop);
    const std::vector<Eigen::Isometry3d> before = graph_.poses();
    std::vector<Eigen::Isometry3d> frames_before;
    frames_before.reserve(anchors_.size());
    for (const auto& [t, anchor] : anchors_) frames_before.push_back(*PoseOf(t));
    event.graph = graph_.Optimize();
    if (!(event.graph.final_cost <= event.graph.initial_cost)) {
      // The solver made it worse (it failed): the graph as it was, without the edge.
      graph_.RemoveLastEdge();
      graph_.SetPoses(before);
      continue;
    }
    // How far each frame moved: its camera, or the point kSceneDepth in front of it (a turn
    // moves the surfaces a frame saw by their distance times the angle).
    constexpr double kSceneDepth = 2.0;  // m
    size_t f = 0;
    for (const auto& [t, anchor] : anchors_) {
      const Eigen::Isometry3d& a = frames_before[f++];
      const Eigen::Isometry3d b = *PoseOf(t);
      const Eigen::Vector3d ahead(0.0, 0.0, kSceneDepth);
      event.largest_move = std::max({event.largest_move, (b.translation() - a.translation()).norm(),
                                     (b * ahead - a * ahead).norm()});
      event.largest_turn_degrees = std::max(event.largest_turn_degrees, Degrees(a.inverse() * b));
    }
    chain_pose_ = graph_.poses()[static_cast<size_t>(id)];  // the chain goes on from here
    events_.push_back(event);
    return event;
  }
  return std::nullopt;
}

std::optional<Eigen::Isometry3d> LoopClosure::MatchNodes(const Node& old, const Node& live,
                                                         LoopClosureEvent* event,
                                                         Matrix6d* information) const {
  const ImageDepth old_depth = store_.Depth(old.stored);
  FeatureAlignReport features;
  const auto pnp =
      AlignByFeatures(old.features, old_depth, live.features, intrinsics_, features_, &features);
  event->feature_inliers = features.inliers;
  if (!pnp) return std::nullopt;
  // ICP of the live frame against the old frame's depth (and brightness), from the features'
  // pose: it must converge on most of the frame and stay near that pose. Its pyramid has
  // kLoopVerifyExtraLevels more levels than tracking's (loop_closure.h).
  PreprocessOptions verify = preprocess_;
  verify.levels += kLoopVerifyExtraLevels;
  const std::vector<PyramidLevel> old_pyramid = BuildPyramid(old_depth, intrinsics_, verify);
  const std::vector<PyramidLevel> live_pyramid =
      BuildPyramid(store_.Depth(live.stored), intrinsics_, verify);
  const std::vector<IntensityLevel> old_intensity =
      BuildIntensityPyramid(store_.Color(old.stored), verify.levels);
  const std::vector<IntensityLevel> live_intensity =
      BuildIntensityPyramid(store_.Color(live.stored), verify.levels);
  Eigen::Isometry3d old_from_live = *pnp;
  const IcpReport icp = TrackFrameToModel(live_pyramid, ModelFromDepth(old_pyramid[0]), intrinsics_,
                                          icp_, &old_from_live, &live_intensity, &old_intensity);
  event->icp_inlier_ratio = icp.inlier_ratio;
  event->icp_rms = icp.rms_residual;
  constexpr double kMaxCorrection = 0.15, kMaxCorrectionDeg = 5.0;  // m, degrees (as relocalising)
  const Eigen::Isometry3d correction = pnp->inverse() * old_from_live;
  if (icp.inlier_ratio < icp_.min_inlier_ratio || icp.rms_residual > icp_.max_rms_residual ||
      icp.degenerate || correction.translation().norm() > kMaxCorrection ||
      Degrees(correction) > kMaxCorrectionDeg) {
    return std::nullopt;
  }
  if (information != nullptr) *information = icp.information;
  return old_from_live;
}

}  // namespace genscene::fusion
