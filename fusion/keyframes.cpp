#include "fusion/keyframes.h"

#include <cmath>

#include "core/color.h"
#include "core/options.h"
#include "core/se3.h"

namespace genscene::fusion {

void KeyframeOptions::Validate() const {
  RequireRange("keyframe_translation", translation, 0.0, 100.0);
  RequireRange("keyframe_rotation", rotation, 0.0, 180.0);
  RequireRange("keyframe_window", window, 1, 1000);
  RequireRange("max_keyframes", max_keyframes, 1, 100000);
}

void KeyframeSelector::Offer(const RgbdFrame& frame) {
  if (frame.color.empty() || !frame.world_from_camera) return;
  if (window_left_ == 0) {
    bool due = keyframes_.empty() && !best_;
    if (!due && !keyframes_.empty()) {
      const Eigen::Isometry3d motion = keyframes_.back().world_from_camera->inverse() * *frame.world_from_camera;
      due = motion.translation().norm() >= options_.translation ||
            RotationAngle(motion) * 180.0 / M_PI >= options_.rotation;
    }
    if (!due) return;
    window_left_ = options_.window;
    best_sharpness_ = -1.0;
  }
  const double s = Sharpness(frame.color);
  if (s > best_sharpness_) {
    best_sharpness_ = s;
    best_ = frame;
  }
  if (--window_left_ == 0) Commit();
}

void KeyframeSelector::Finish() {
  if (best_) Commit();
  window_left_ = 0;
}

void KeyframeSelector::Commit() {
  if (static_cast<int>(keyframes_.size()) >= options_.max_keyframes) {
    ++dropped_;
  } else {
    keyframes_.push_back(std::move(*best_));
    sharpness_.push_back(best_sharpness_);
  }
  best_.reset();
  window_left_ = 0;
}

}  // namespace genscene::fusion
