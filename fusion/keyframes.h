// Keyframe selection for texturing: a new keyframe is due when the camera has moved or turned
// enough since the last one; of the next `window` tracked frames the sharpest (variance of the
// Laplacian of luminance, Pech-Pacheco et al. 2000) is kept, so motion-blurred frames lose.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "core/image.h"
#include "core/rgbd_frame.h"

namespace genscene::fusion {

struct KeyframeOptions {
  double translation = 0.15;  // m moved since the last keyframe that makes a new one due
  double rotation = 15.0;     // degrees turned since the last keyframe that makes one due
  int window = 5;             // frames among which the sharpest becomes the keyframe
  int max_keyframes = 500;    // hard limit; exceeding it is reported, never silent

  void Validate() const;
};

class KeyframeSelector {
 public:
  explicit KeyframeSelector(const KeyframeOptions& options) : options_(options) {}

  // Offers a tracked frame (its world_from_camera set). Frames without colour are ignored.
  void Offer(const RgbdFrame& frame);
  // Closes an open window (end of the sequence).
  void Finish();

  const std::vector<RgbdFrame>& keyframes() const { return keyframes_; }
  std::vector<double> sharpness() const { return sharpness_; }
  size_t dropped() const { return dropped_; }  // due keyframes beyond max_keyframes

 private:
  void Commit();

  KeyframeOptions options_;
  std::vector<RgbdFrame> keyframes_;
  std::vector<double> sharpness_;
  std::optional<RgbdFrame> best_;
  double best_sharpness_ = -1.0;
  int window_left_ = 0;
  size_t dropped_ = 0;
};

}  // namespace genscene::fusion
