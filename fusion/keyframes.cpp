#include "fusion/keyframes.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/color.h"
#include "core/options.h"
#include "core/se3.h"

namespace genscene::fusion {

void KeyframeOptions::Validate() const {
  RequireRange("keyframe_translation", translation, 0.0, 100.0);
  RequireRange("keyframe_rotation", rotation, 0.0, 180.0);
  RequireRange("keyframe_new_surface", new_surface, 0.0, 1.0);
  RequireRange("keyframe_window", window, 1, 1000);
  RequireRange("min_keyframes", min_keyframes, 1, 100);
  RequireRange("max_keyframes", max_keyframes, 1, 100000);
  if (min_keyframes > max_keyframes) {
    throw Error(Format("option min_keyframes = ", min_keyframes,
                       " exceeds max_keyframes = ", max_keyframes));
  }
}

bool KeyframeSelector::MovedEnough(const Eigen::Isometry3d& from,
                                   const Eigen::Isometry3d& to) const {
  const Eigen::Isometry3d motion = from.inverse() * to;
  return motion.translation().norm() >= options_.translation ||
         RotationAngle(motion) * 180.0 / M_PI >= options_.rotation;
}

double KeyframeSelector::NewSurfaceFraction(const ImageDepth& depth,
                                            const Eigen::Isometry3d& world_from_camera,
                                            const CameraIntrinsics& k) const {
  if (depth.empty() || k.width <= 0 || !depth.SameSize(k.width, k.height)) return 0.0;
  // The keyframes with depth, newest first (most points end there), and the frame in each.
  std::vector<const RgbdFrame*> seen_by;
  std::vector<Eigen::Isometry3d> keyframe_from_frame;
  for (auto it = keyframes_.rbegin(); it != keyframes_.rend(); ++it) {
    if (it->depth.empty() || it->intrinsics.width <= 0) continue;
    seen_by.push_back(&*it);
    keyframe_from_frame.push_back(it->world_from_camera->inverse() * world_from_camera);
  }
  const int step = std::max(1, k.width / 40);
  size_t samples = 0, unseen = 0;
  for (int v = step / 2; v < k.height; v += step) {
    for (int u = step / 2; u < k.width; u += step) {
      const float z = depth(u, v);
      if (!(z > 0.0f)) continue;
      ++samples;
      const Eigen::Vector3d p = k.Unproject(u, v, z);
      bool seen = false;
      for (size_t i = 0; i < seen_by.size() && !seen; ++i) {
        const Eigen::Vector3d q = keyframe_from_frame[i] * p;
        const auto px = seen_by[i]->intrinsics.Project(q);
        if (!px) continue;
        const int ku = static_cast<int>(std::lround(px->x())),
                  kv = static_cast<int>(std::lround(px->y()));
        if (ku < 0 || kv < 0 || ku >= seen_by[i]->depth.width() || kv >= seen_by[i]->depth.height())
          continue;
        const float kz = seen_by[i]->depth(ku, kv);
        seen = kz > 0.0f && std::abs(kz - q.z()) < std::max(0.03, 0.05 * q.z());
      }
      unseen += !seen;
    }
  }
  return samples == 0 ? 0.0 : static_cast<double>(unseen) / static_cast<double>(samples);
}

void KeyframeSelector::Offer(const RgbdFrame& frame) {
  if (!frame.world_from_camera) return;
  Offer(frame, frame.depth, *frame.world_from_camera, frame.intrinsics);
}

void KeyframeSelector::Offer(const RgbdFrame& frame, const ImageDepth& depth,
                             const Eigen::Isometry3d& world_from_camera,
                             const CameraIntrinsics& intrinsics) {
  if (frame.color.empty()) return;
  const size_t index = offered_++;
  // The sharpness (a pass over the colour image) and the copy only for a frame that may be held.
  std::optional<double> sharpness;
  auto sharpness_of_frame = [&] {
    if (!sharpness) sharpness = Sharpness(frame.color);
    return *sharpness;
  };
  auto posed = [&] {
    RgbdFrame copy = frame;
    copy.depth = depth;
    copy.world_from_camera = world_from_camera;
    copy.intrinsics = intrinsics;
    return copy;
  };
  // Held for min_keyframes while too few are chosen: every candidate_stride_-th offered frame.
  if (static_cast<int>(keyframes_.size()) < options_.min_keyframes &&
      index >= candidates_.size() * candidate_stride_) {
    bool hold = true;
    if (static_cast<int>(candidates_.size()) == kCandidates) {  // full: every other, twice apart
      std::vector<Candidate> kept;
      for (size_t i = 0; i < candidates_.size(); i += 2) kept.push_back(std::move(candidates_[i]));
      candidates_ = std::move(kept);
      candidate_stride_ *= 2;
      hold = index >= candidates_.size() * candidate_stride_;
    }
    if (hold) candidates_.push_back({index, sharpness_of_frame(), posed()});
  }
  // A frame as far from the window's start as a keyframe must be from the last one closes the
  // window: it is a view of its own.
  if (window_left_ > 0 && MovedEnough(*window_start_, world_from_camera)) Commit();
  if (window_left_ == 0) {
    bool due = keyframes_.empty() && !best_;
    if (!due && !keyframes_.empty())
      due = MovedEnough(*keyframes_.back().world_from_camera, world_from_camera);
    if (!due && !keyframes_.empty() && options_.new_surface > 0.0)
      due = NewSurfaceFraction(depth, world_from_camera, intrinsics) >= options_.new_surface;
    if (!due) return;
    window_left_ = options_.window;
    window_start_ = world_from_camera;
    best_sharpness_ = -1.0;
  }
  const double s = sharpness_of_frame();
  if (s > best_sharpness_) {
    best_sharpness_ = s;
    best_ = posed();
    best_index_ = index;
  }
  if (--window_left_ == 0) Commit();
}

void KeyframeSelector::Finish() {
  if (best_) Commit();
  window_left_ = 0;
  TopUp();
  candidates_.clear();
}

void KeyframeSelector::TopUp() {
  while (static_cast<int>(keyframes_.size()) < options_.min_keyframes) {
    // The candidate farthest (in offered frames) from every keyframe; among those within one
    // candidate spacing of the farthest, the sharpest.
    std::vector<size_t> gap(candidates_.size(), 0);
    size_t farthest = 0;
    for (size_t c = 0; c < candidates_.size(); ++c) {
      size_t d = std::numeric_limits<size_t>::max();
      for (size_t k : offered_index_) {
        d = std::min(d, candidates_[c].offered > k ? candidates_[c].offered - k
                                                   : k - candidates_[c].offered);
      }
      gap[c] = d;
      farthest = std::max(farthest, d);
    }
    if (farthest == 0) return;  // every held frame is a keyframe already
    int pick = -1;
    for (size_t c = 0; c < candidates_.size(); ++c) {
      if (gap[c] == 0 || gap[c] + candidate_stride_ <= farthest) continue;
      if (pick < 0 || candidates_[c].sharpness > candidates_[pick].sharpness)
        pick = static_cast<int>(c);
    }
    const Candidate& c = candidates_[pick];
    const auto at = std::upper_bound(offered_index_.begin(), offered_index_.end(), c.offered) -
                    offered_index_.begin();
    keyframes_.insert(keyframes_.begin() + at, c.frame);
    sharpness_.insert(sharpness_.begin() + at, c.sharpness);
    offered_index_.insert(offered_index_.begin() + at, c.offered);
  }
}

void KeyframeSelector::Commit() {
  if (static_cast<int>(keyframes_.size()) >= options_.max_keyframes) {
    ++dropped_;
  } else {
    keyframes_.push_back(std::move(*best_));
    sharpness_.push_back(best_sharpness_);
    offered_index_.push_back(best_index_);
  }
  best_.reset();
  window_left_ = 0;
}

void KeyframeSelector::Repose(
    const std::function<std::optional<Eigen::Isometry3d>(double)>& pose_of) {
  auto repose = [&](RgbdFrame& f) {
    if (auto moved = pose_of(f.timestamp)) f.world_from_camera = *moved;
  };
  for (RgbdFrame& f : keyframes_) repose(f);
  if (best_) repose(*best_);
  for (Candidate& c : candidates_) repose(c.frame);
}

}  // namespace genscene::fusion
