#include "render/light_visibility.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/parallel.h"
#include "render/light_sampler.h"
#include "render/path_continuation.h"
#include "render/ray_tracer.h"

namespace genscene::render {

namespace {

struct SurfaceSample {
  Eigen::Vector3f p, n;  // point and unit face normal
};

}  // namespace

LightVisibility::LightVisibility(const Scene& scene, const RayTracer& tracer,
                                 const std::vector<Eigen::Vector3f>& lights,
                                 const LightVisibilityOptions& options) {
  GS_CHECK_GT(options.points_per_cell, 0);
  GS_CHECK(options.floor > 0.0f && options.floor <= 1.0f);
  lights_ = lights.size();
  Eigen::AlignedBox3f box;
  for (const SceneMesh& m : scene.meshes) {
    if (m.IsEmitter()) continue;
    for (const Eigen::Vector3f& v : m.mesh.vertices) box.extend(v);
  }
  if (lights_ == 0 || box.isEmpty()) {
    lights_ = 0;
    return;
  }
  origin_ = box.min();
  double cell = std::max(1e-6, options.cell_fraction * static_cast<double>(box.diagonal().norm()));

  // Surface points, four per cell area of every face (at least one per face), on a rank-1
  // lattice over the triangle; each cell keeps points_per_cell of its own, evenly spaced in the
  // order they were made. Cells grow until cells x lights fits max_entries.
  std::vector<std::vector<SurfaceSample>> per_cell;
  for (;;) {
    inverse_cell_ = 1.0 / cell;
    cells_.clear();
    per_cell.clear();
    const double cell_area = cell * cell;
    for (const SceneMesh& m : scene.meshes) {
      if (m.IsEmitter()) continue;
      for (size_t f = 0; f < m.mesh.faces.size(); ++f) {
        const Eigen::Vector3f scaled = m.mesh.FaceNormalScaled(f);
        const double area = 0.5 * static_cast<double>(scaled.norm());
        if (!(area > 0.0)) continue;
        const Eigen::Vector3f n = scaled.normalized();
        const int count =
            static_cast<int>(std::clamp(std::ceil(4.0 * area / cell_area), 1.0, 65536.0));
        for (int i = 0; i < count; ++i) {
          const float u1 = (static_cast<float>(i) + 0.5f) / static_cast<float>(count);
          float u2 = 0.5f + 0.618034f * static_cast<float>(i);
          u2 -= std::floor(u2);
          const Eigen::Vector3f p = UniformPointOnTriangle(m.mesh, static_cast<int>(f), u1, u2);
          const auto [it, added] = cells_.emplace(Key(p), per_cell.size());
          if (added) per_cell.emplace_back();
          per_cell[it->second].push_back({p, n});
        }
      }
    }
    if (per_cell.size() * lights_ <= options.max_entries) break;
    cell *= 2.0;
  }

  const size_t k_max = static_cast<size_t>(options.points_per_cell);
  factors_.assign(per_cell.size() * lights_, 1.0f);
  ParallelFor(
      0, per_cell.size(),
      [&](size_t c) {
        const std::vector<SurfaceSample>& all = per_cell[c];
        const size_t k = std::min(k_max, all.size());
        float* out = factors_.data() + c * lights_;
        std::vector<int> seen(lights_, 0);
        for (size_t j = 0; j < k; ++j) {
          const SurfaceSample& s = all[(2 * j + 1) * all.size() / (2 * k)];
          const float offset = path::OffsetScale(s.p);
          for (size_t l = 0; l < lights_; ++l) {
            // From the side of the surface that faces the light (surfaces reflect on both).
            const float side = s.n.dot(lights[l] - s.p) >= 0.0f ? 1.0f : -1.0f;
            if (!tracer.SegmentOccluded(s.p + side * offset * s.n, lights[l])) ++seen[l];
          }
        }
        for (size_t l = 0; l < lights_; ++l) {
          const float share = static_cast<float>(seen[l]) / static_cast<float>(k);
          out[l] = options.floor + (1.0f - options.floor) * share;
        }
      },
      16);
  // Offsets into factors_ by cell index.
  for (auto& [key, index] : cells_) index *= lights_;
}

const LightVisibility* LazyLightVisibility::Get(const Scene& scene, const RayTracer& tracer,
                                                const LightSampler& lights) const {
  std::call_once(once_, [&] {
    const std::vector<Eigen::Vector3f> points = lights.LocalPoints();
    if (points.size() > 1) cache_ = std::make_unique<LightVisibility>(scene, tracer, points);
  });
  return cache_.get();
}

}  // namespace genscene::render
