// Step 2 of light estimation: the path-coefficient cache. Camera paths through the sampled pixels
// are traced once; at every path vertex a shadow ray goes to every voxel (or to voxels drawn in
// proportion to the current estimate), and the cache records the coefficient a_ijk that
// multiplies each product x_jk = L_j lambda_jk, so that the predicted pixel is
//     P_i = sum_jk a_ijk (*) x_jk
// (per channel; path throughput x BRDF x cosine / r^2 x visibility x the voxel's face projection
// max(0, w . d_k)).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/light_set.h"
#include "inverse/lights/light_options.h"
#include "inverse/lights/pixel_sampling.h"
#include "render/path_tracer.h"

namespace genscene::inverse {

// Per sampled pixel, the coefficients of the parameters p = 6 j + k (sorted, RGB), compressed;
// light j = VoxelCount() is the grid's distant light when it has one.
struct LightCache {
  int parameters = 0;  // 6 x lights (VoxelLightGrid::LightCount)
  std::vector<SampledPixel> pixels;
  std::vector<size_t> row_begin;  // pixels + 1 entries into index / coefficient
  std::vector<int32_t> index;
  std::vector<Eigen::Vector3f> coefficient;
  render::RayCounts rays;

  // Predicted radiance of every sampled pixel for the lights `grid` (same layout).
  std::vector<Eigen::Vector3f> Predict(const VoxelLightGrid& grid) const;
  size_t NonZeros() const { return index.size(); }
  // Adds the entries of `other`, a cache of the same pixels over other parameters (no parameter in
  // both). Traces of the same paths (same seed and options, every voxel connected at every vertex)
  // that connect to two sets of voxels give, merged, the trace that connects to both.
  void Merge(const LightCache& other);
  // Heap bytes held by the rows (index, coefficient, row_begin).
  size_t Bytes() const;
};

// Traces `options.paths.spp` paths per pixel (random numbers keyed by seed, view, pixel, sample)
// and splits at every vertex as `splitting` says. Throws Error when the cache's rows would take
// more than `cap_bytes` (0: no cap), with a message that says which options lower it.
LightCache TraceLightCache(const render::PathTracer& tracer, const VoxelLightGrid& grid,
                           const render::VoxelSplitting& splitting,
                           const std::vector<PosedImage>& views,
                           const std::vector<SampledPixel>& pixels,
                           const LightEstimationOptions& options, uint64_t seed,
                           double cap_bytes = 0.0);

// Two independent caches of the same pixels with half of `options.paths.spp` each (keys seed_a and
// seed_b): the normal equations' noise correction takes their product
// (NormalEquations::FromCaches). The second cache gets what the first leaves of `cap_bytes` (0: no
// cap).
std::pair<LightCache, LightCache> TraceLightCacheHalves(
    const render::PathTracer& tracer, const VoxelLightGrid& grid,
    const render::VoxelSplitting& splitting, const std::vector<PosedImage>& views,
    const std::vector<SampledPixel>& pixels, const LightEstimationOptions& options, uint64_t seed_a,
    uint64_t seed_b, double cap_bytes = 0.0);

// The radiance of one sampled pixel for the lights `grid`, by the same walk and the same random
// numbers as TraceLightCache (a fresh render, for checking the cache).
Eigen::Vector3f RenderSampledPixel(const render::PathTracer& tracer, const VoxelLightGrid& grid,
                                   const render::VoxelSplitting& splitting,
                                   const SampledPixel& pixel, const std::vector<PosedImage>& views,
                                   const LightEstimationOptions& options, uint64_t seed);

}  // namespace genscene::inverse
