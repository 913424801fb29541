// How well lights explain images: the relative error of a render of them against a reference
// image with the Monte Carlo noise of both taken out, and the ambient baseline an estimate must
// beat. Both judge the pixels light estimation uses (ValidPixels).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "core/image.h"
#include "inverse/lights/light_options.h"
#include "render/path_tracer.h"

namespace genscene::inverse {

// Relative RMSE sqrt(sum |P - R|^2 / sum |R|^2) of a render against a reference over the valid
// pixels (masked as SamplePixels does), and the part of it that is Monte Carlo noise of the
// render (from two half renders) and of the reference (given as its RMS noise per channel).
// With `block` > 1 the images are compared as means over block x block tiles (of their valid
// pixels, each tile weighted by its count): the noise variance of a tile mean is that of a pixel
// over the count (pixels are sampled independently), so subtracting it is far steadier when the
// per-pixel noise is much larger than the error being measured; errors finer than a tile are
// averaged away.
struct ViewError {
  size_t pixels = 0;
  double rmse = 0.0;       // raw
  double noise = 0.0;      // sqrt(render noise^2 + reference noise^2) on the same scale
  double rmse_bias = 0.0;  // sqrt(max(0, rmse^2 - noise^2)): the error of the expected images
};
// `lit`: the scene with the lights to judge (rendered with next-event estimation, `spp` in total).
ViewError CompareRender(const render::PathTracer& lit, const PosedImage& reference,
                        const LightEstimationOptions& options, int spp, uint64_t seed,
                        double reference_noise_rms = 0.0, ImageRgb* render = nullptr,
                        int block = 1);

// The baseline a light estimate must beat: each valid pixel (as CompareRender masks them)
// predicted as its camera ray's first hit's albedo times one ambient radiance per channel, fitted
// by least squares over all the views (no shadows, no bounces). `rmse` per view as ViewError::rmse.
struct AmbientBaseline {
  Eigen::Vector3d radiance = Eigen::Vector3d::Zero();
  std::vector<double> rmse;
  double mean_rmse = 0.0;
};
AmbientBaseline FitAmbientBaseline(const render::PathTracer& tracer,
                                   const std::vector<PosedImage>& views,
                                   const LightEstimationOptions& options);

}  // namespace genscene::inverse
