// Step 1 of light estimation: the pixels it fits. A pixel is valid when its camera ray hits a
// reflecting surface, it is not saturated and it does not see an emitter directly.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "core/image.h"
#include "inverse/lights/light_options.h"
#include "render/path_tracer.h"

namespace genscene::inverse {

struct SampledPixel {
  int view = 0;
  int u = 0, v = 0;
  Eigen::Vector3f observed = Eigen::Vector3f::Zero();
};

struct PixelMaskCounts {
  size_t valid = 0, miss = 0, emitter = 0, saturated = 0;
};

// Random valid pixels (up to pixels_per_view per view, without replacement; every valid pixel
// when there are fewer), in view order then raster order. Throws Error when a view's image does
// not match its intrinsics or holds a non-finite value, and when no pixel at all is valid.
std::vector<SampledPixel> SamplePixels(const render::PathTracer& tracer,
                                       const std::vector<PosedImage>& views,
                                       const LightEstimationOptions& options, uint64_t seed,
                                       std::vector<PixelMaskCounts>* counts = nullptr);

// Which pixels of a view light estimation uses (1) and why the others are left out.
Image<uint8_t> ValidPixels(const render::PathTracer& tracer, const PosedImage& view,
                           const LightEstimationOptions& options,
                           PixelMaskCounts* counts = nullptr);

}  // namespace genscene::inverse
