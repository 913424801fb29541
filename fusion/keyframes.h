// Keyframe selection for texturing and the inverse stages. A keyframe is due when the camera has
// moved or turned enough since the last one, or when enough of what it sees is surface no
// keyframe has seen (close-range scanning adds new surface long before the camera has moved
// 15 cm: at 0.3 m a 10 cm slide shows a third of a new view); of the next `window` tracked frames
// the sharpest (variance of the Laplacian of luminance, Pech-Pacheco et al. 2000) is kept, so
// motion-blurred frames lose. The window closes early at a frame that has itself moved or turned
// the due amount from where the window opened, so a sparse recording (frames far apart) keeps every
// view instead of the sharpest of five distant ones. A short recording whose motion never makes a
// second keyframe due still gets min_keyframes views: an evenly spaced sample of the tracked frames
// (held while fewer than min_keyframes are chosen, at most kCandidates of them) fills in the
// frames farthest in time from the chosen ones, the sharpest of near-equals first.
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <optional>
#include <vector>

#include "core/image.h"
#include "core/rgbd_frame.h"

namespace genscene::fusion {

struct KeyframeOptions {
  double translation = 0.15;  // m moved since the last keyframe that makes a new one due
  double rotation = 15.0;     // degrees turned since the last keyframe that makes one due
  // Share of a frame's surface (its depth pixels, on a grid of about 40x30) that no keyframe saw
  // (none has a depth within 3 cm or 5 % at its projection) that makes a keyframe due; 0 = off.
  double new_surface = 0.3;
  int window = 5;           // frames among which the sharpest becomes the keyframe
  int min_keyframes = 3;    // at least this many keyframes when the recording has the frames
  int max_keyframes = 500;  // hard limit; exceeding it is reported, never silent

  void Validate() const;
};

class KeyframeSelector {
 public:
  static constexpr int kCandidates = 16;  // frames held for min_keyframes (evenly spaced in time)

  explicit KeyframeSelector(const KeyframeOptions& options) : options_(options) {}

  // Offers a tracked frame (its world_from_camera set). Frames without colour are ignored.
  void Offer(const RgbdFrame& frame);
  // The same for `frame` with `depth`, `world_from_camera` and `intrinsics` in place of its own
  // (a frame is copied only when it is held).
  void Offer(const RgbdFrame& frame, const ImageDepth& depth,
             const Eigen::Isometry3d& world_from_camera, const CameraIntrinsics& intrinsics);
  // Closes an open window and tops the keyframes up to min_keyframes (end of the sequence).
  void Finish();

  // Moves every frame held (keyframes, the open window's best, the top-up candidates) to
  // pose_of(its time stamp) where that gives a pose (a closed loop moved the trajectory).
  void Repose(const std::function<std::optional<Eigen::Isometry3d>(double)>& pose_of);
  // In the order of the recording.
  const std::vector<RgbdFrame>& keyframes() const { return keyframes_; }
  std::vector<double> sharpness() const { return sharpness_; }
  size_t dropped() const { return dropped_; }  // due keyframes beyond max_keyframes

 private:
  struct Candidate {
    size_t offered;  // index among the offered frames
    double sharpness;
    RgbdFrame frame;
  };
  bool MovedEnough(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to) const;
  // The share of the depth samples of a frame at `world_from_camera` that no keyframe saw (0
  // without depth or intrinsics).
  double NewSurfaceFraction(const ImageDepth& depth, const Eigen::Isometry3d& world_from_camera,
                            const CameraIntrinsics& k) const;
  void Commit();
  void TopUp();

  KeyframeOptions options_;
  std::vector<RgbdFrame> keyframes_;
  std::vector<double> sharpness_;
  std::vector<size_t> offered_index_;  // of each keyframe
  std::optional<RgbdFrame> best_;
  size_t best_index_ = 0;
  double best_sharpness_ = -1.0;
  std::optional<Eigen::Isometry3d> window_start_;
  int window_left_ = 0;
  size_t dropped_ = 0;
  size_t offered_ = 0;
  size_t candidate_stride_ = 1;  // every candidate_stride_-th offered frame is held
  std::vector<Candidate> candidates_;
};

}  // namespace genscene::fusion
