// Visibility of the near-field lights from the scene's surfaces, for light selection (internal to
// render/).
//
// Choosing a light by its unshadowed contribution (LightSampler::ChooseAt) goes wrong where a
// bright light is blocked: an estimated model often holds strong voxel lights behind a wall or
// outside the scanned part of a room, which the selection keeps choosing at shading points they
// cannot reach, while the light that does reach is chosen rarely and then counts with a large
// weight: salt noise. This cache holds, on a sparse grid of cells over the surfaces, the share of
// shadow rays from surface points in the cell that reach each near-field light. The selection
// multiplies a light's weight by floor + (1 - floor) x that share: a light never drops to
// probability zero, so the estimate stays unbiased whatever the cache says; only its variance
// changes.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "render/scene.h"

namespace genscene::render {

class LightSampler;
class RayTracer;

struct LightVisibilityOptions {
  double cell_fraction = 1.0 / 48.0;  // cell side as a share of the surfaces' bounding-box diagonal
  int points_per_cell = 8;            // surface points per cell, each a shadow ray to every light
  float floor = 0.1f;                 // a light's factor where no point of the cell sees it
  size_t max_entries = 16u << 20;     // cells x lights at most (coarser cells beyond)
};

class LightVisibility {
 public:
  // Surface points of every non-emitting mesh of `scene` (traced by `tracer`) against the light
  // positions `lights`. Deterministic: the same scene gives the same cache for any thread count.
  LightVisibility(const Scene& scene, const RayTracer& tracer,
                  const std::vector<Eigen::Vector3f>& lights,
                  const LightVisibilityOptions& options = {});

  // The factors of the lights at p (one per light, in the constructor's order), or nullptr when
  // no surface point fell into p's cell.
  const float* At(const Eigen::Vector3f& p) const {
    if (lights_ == 0) return nullptr;
    const auto it = cells_.find(Key(p));
    return it == cells_.end() ? nullptr : factors_.data() + it->second;
  }

  size_t cells() const { return cells_.size(); }
  double cell_size() const { return 1.0 / inverse_cell_; }

 private:
  uint64_t Key(const Eigen::Vector3f& p) const {
    const Eigen::Vector3f c = (p - origin_) * static_cast<float>(inverse_cell_);
    const auto cell = [](float x) {
      return static_cast<uint64_t>(static_cast<int64_t>(std::floor(x)) & 0x1FFFFF);
    };
    return (cell(c.x()) << 42) | (cell(c.y()) << 21) | cell(c.z());
  }

  size_t lights_ = 0;
  Eigen::Vector3f origin_ = Eigen::Vector3f::Zero();
  double inverse_cell_ = 1.0;
  std::unordered_map<uint64_t, size_t> cells_;  // cell key -> offset of its factors
  std::vector<float> factors_;
};

// A tracer's LightVisibility for its light sampler's near-field lights, built on the first Get
// (thread-safe: the renders' workers may ask at once); nullptr when there are fewer than two,
// nothing to choose between. The path tracer and the differentiable tracer each hold one.
class LazyLightVisibility {
 public:
  const LightVisibility* Get(const Scene& scene, const RayTracer& tracer,
                             const LightSampler& lights) const;

 private:
  mutable std::once_flag once_;
  mutable std::unique_ptr<LightVisibility> cache_;
};

}  // namespace genscene::render
