// The judge on real frames: the model rendered at the poses of frames it never saw (fusion's
// holdout: tracked for their pose, kept out of fusion, keyframes, texturing, lights and
// refinement), against those frames, beside two baselines on the same pixels:
//   - the observed-colour texture shown unlit (what a textured mesh from Open3D or InfiniTAM
//     gives: no lights, cannot relight);
//   - the albedo under a uniform white ambient light.
// Pixels: those whose camera ray hits the model and whose frame colour is finite; the baselines
// take the colour of that ray's hit, the model's render the mean over the samples of the pixel's
// footprint that meet a surface (RenderOptions::surface_only: on the outline of a scan the rest
// of the footprint is unscanned space, which no prediction here claims to know). Each prediction
// P gets its own exposure / white-balance gain g (per channel, least squares over the pixels: real
// cameras adapt per frame), then
//   relative RMSE = sqrt(sum |g P - R|^2 / sum |R|^2) in linear RGB (after the camera response),
//   SSIM (Wang et al. 2004, 11x11 Gaussian window, sigma 1.5) of the sRGB-encoded luminance,
//        averaged over the pixels (elsewhere both images hold the frame),
// and for the model, rendered as two independent halves, the part of its RMSE that is render
// noise (sqrt(sum |g (A - B)|^2 / 4 / sum |R|^2)).
// With a ground truth (a synthetic input's scene), the same scores are also taken against the
// true scene rendered at each held-out pose, and the held-out frame itself is scored against it:
// the floor a perfect model reaches against the frames (their sensor noise and render noise).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "core/image.h"
#include "core/workspace.h"
#include "inverse/lights/light_estimation.h"

namespace genscene::apps {

struct HeldOutScore {
  Eigen::Vector3d gain = Eigen::Vector3d::Zero();
  double rmse = 0.0;
  double ssim = 0.0;
};

// The scores against the true scene's render at a held-out pose.
struct AgainstTruth {
  HeldOutScore model, texture, ambient;
  HeldOutScore frame;  // the held-out frame itself
};

struct HeldOutFrame {
  double timestamp = 0.0;
  size_t pixels = 0;
  double noise = 0.0;  // of the model's relative RMSE
  HeldOutScore model, texture, ambient;
  std::optional<AgainstTruth> truth;
};

struct HeldOutEvaluation {
  std::vector<HeldOutFrame> frames;
  HeldOutScore model, texture, ambient;  // means over the frames (gains: of the model's)
  double noise = 0.0;
  std::optional<AgainstTruth> truth;  // means over the frames, with a ground truth
};

// Judges the workspace's model (refined mesh, albedo, lights; texture.mcol for the unlit
// baseline) on WS/holdout/ with `spp` paths per pixel. Writes WS/evaluation/holdout.json and per
// frame holdout_NN_real.png, _model.png, _texture.png, _ambient.png and _error.png (|g P - R| of
// the model, 4x); with `truth`, rendered at `truth_spp`, also holdout_NN_truth.png and the scores
// against it ("against_truth"). Throws Error when WS/holdout/ holds no frames.
HeldOutEvaluation EvaluateHeldOut(const Workspace& ws,
                                  const inverse::LightEstimationOptions& lights, int spp,
                                  uint64_t seed, const render::Scene* truth = nullptr,
                                  int truth_spp = 128);

// The gain-fitted score of a prediction against a reference over the pixels of `mask`.
HeldOutScore ScorePrediction(const ImageRgb& prediction, const ImageRgb& reference,
                             const Image<uint8_t>& mask);

// Mean SSIM of the sRGB-encoded luminance of a and b over the pixels of `mask` (the window reaches
// outside it: give images that agree there).
double MaskedSsim(const ImageRgb& a, const ImageRgb& b, const Image<uint8_t>& mask);

}  // namespace genscene::apps
