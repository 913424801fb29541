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
  RequireRange("keyframe_window", window, 1, 1000);
  RequireRange("min_keyframes", min_keyframes, 1, 100);
  RequireRange("max_keyframes", max_keyframes, 1, 100000);
  if (min_keyframes > max_keyframes) {
    throw Error(Format("option min_keyframes = ", min_keyframes, " exceeds max_keyframes = ", max_keyframes));
  }
}

bool KeyframeSelector::MovedEnough(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to) const {
  const Eigen::Isometry3d motion = from.inverse() * to;
  return motion.translation().norm() >= options_.translation ||
         RotationAngle(motion) * 180.0 / M_PI >= options_.rotation;
}

void KeyframeSelector::Offer(const RgbdFrame& frame) {
  if (frame.color.empty() || !frame.world_from_camera) return;
  const size_t index = offered_++;
  const double s = Sharpness(frame.color);
  if (static_cast<int>(keyframes_.size()) < options_.min_keyframes) HoldCandidate(frame, s);
  // A frame as far from the window's start as a keyframe must be from the last one closes the
  // window: it is a view of its own.
  if (window_left_ > 0 && MovedEnough(*window_start_, *frame.world_from_camera)) Commit();
  if (window_left_ == 0) {
    bool due = keyframes_.empty() && !best_;
    if (!due && !keyframes_.empty()) due = MovedEnough(*keyframes_.back().world_from_camera, *frame.world_from_camera);
    if (!due) return;
    window_left_ = options_.window;
    window_start_ = *frame.world_from_camera;
    best_sharpness_ = -1.0;
  }
  if (s > best_sharpness_) {
    best_sharpness_ = s;
    best_ = frame;
    best_index_ = index;
  }
  if (--window_left_ == 0) Commit();
}

void KeyframeSelector::HoldCandidate(const RgbdFrame& frame, double sharpness) {
  if (offered_ - 1 < candidates_.size() * candidate_stride_) return;  // not the next evenly spaced one
  if (static_cast<int>(candidates_.size()) == kCandidates) {  // full: keep every other, twice the spacing
    std::vector<Candidate> kept;
    for (size_t i = 0; i < candidates_.size(); i += 2) kept.push_back(std::move(candidates_[i]));
    candidates_ = std::move(kept);
    candidate_stride_ *= 2;
    if (offered_ - 1 < candidates_.size() * candidate_stride_) return;
  }
  candidates_.push_back({offered_ - 1, sharpness, frame});
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
        d = std::min(d, candidates_[c].offered > k ? candidates_[c].offered - k : k - candidates_[c].offered);
      }
      gap[c] = d;
      farthest = std::max(farthest, d);
    }
    if (farthest == 0) return;  // every held frame is a keyframe already
    int pick = -1;
    for (size_t c = 0; c < candidates_.size(); ++c) {
      if (gap[c] == 0 || gap[c] + candidate_stride_ <= farthest) continue;
      if (pick < 0 || candidates_[c].sharpness > candidates_[pick].sharpness) pick = static_cast<int>(c);
    }
    const Candidate& c = candidates_[pick];
    const auto at = std::upper_bound(offered_index_.begin(), offered_index_.end(), c.offered) - offered_index_.begin();
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

}  // namespace genscene::fusion
