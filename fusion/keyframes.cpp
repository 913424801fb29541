#include "fusion/keyframes.h"

#include <cmath>

#include "core/options.h"
#include "core/se3.h"

namespace genscene::fusion {

void KeyframeOptions::Validate() const {
  RequireRange("keyframe_translation", translation, 0.0, 100.0);
  RequireRange("keyframe_rotation", rotation, 0.0, 180.0);
  RequireRange("keyframe_window", window, 1, 1000);
  RequireRange("max_keyframes", max_keyframes, 1, 100000);
}

double Sharpness(const ImageRgb& color) {
  const int w = color.width(), h = color.height();
  if (w < 3 || h < 3) return 0.0;
  auto luma = [&](int u, int v) {
    const Eigen::Vector3f& c = color(u, v);
    return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z();
  };
  double sum = 0.0, sum_sq = 0.0;
  size_t n = 0;
  for (int v = 1; v + 1 < h; ++v) {
    for (int u = 1; u + 1 < w; ++u) {
      const double lap = luma(u - 1, v) + luma(u + 1, v) + luma(u, v - 1) + luma(u, v + 1) - 4.0 * luma(u, v);
      sum += lap;
      sum_sq += lap * lap;
      ++n;
    }
  }
  const double mean = sum / static_cast<double>(n);
  return sum_sq / static_cast<double>(n) - mean * mean;
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
