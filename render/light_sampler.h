// Light selection for next-event estimation, shared by the path tracer and the differentiable
// path tracer of vertex refinement (internal to render/).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/color.h"
#include "render/scene.h"

namespace genscene::render {

// Chooses lights in proportion to their (estimated) power.
// The point of face `face` that an area-light sample (u1, u2) picks, uniform over the triangle:
// barycentrics (1 - sqrt(u1), sqrt(u1) (1 - u2), sqrt(u1) u2). Both tracers draw it this way, so
// that they sample the same light points with the same random numbers.
inline Eigen::Vector3f UniformPointOnTriangle(const TriangleMesh& mesh, int face, float u1,
                                              float u2) {
  const Eigen::Vector3i& f = mesh.faces[face];
  const float su = std::sqrt(u1);
  return (1.0f - su) * mesh.vertices[f[0]] + su * (1.0f - u2) * mesh.vertices[f[1]] +
         su * u2 * mesh.vertices[f[2]];
}

class LightSampler {
 public:
  enum class Kind { kTriangle, kPoint, kVoxel };
  struct Entry {
    Kind kind;
    int mesh = -1;  // triangle: mesh and face; point: light index; voxel: voxel index
    int index = -1;
    float area = 0.0f;
  };

  explicit LightSampler(const Scene& scene) {
    first_triangle_.assign(scene.meshes.size(), -1);
    std::vector<double> power;
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
      const SceneMesh& mesh = scene.meshes[m];
      if (!mesh.IsEmitter()) continue;
      first_triangle_[m] = static_cast<int>(entries_.size());
      for (size_t f = 0; f < mesh.mesh.faces.size(); ++f) {
        const float area = 0.5f * mesh.mesh.FaceNormalScaled(f).norm();
        entries_.push_back({Kind::kTriangle, static_cast<int>(m), static_cast<int>(f), area});
        power.push_back(M_PI * area * Luminance(mesh.emission));
      }
    }
    for (size_t i = 0; i < scene.point_lights.size(); ++i) {
      entries_.push_back({Kind::kPoint, -1, static_cast<int>(i), 0.0f});
      power.push_back(4.0 * M_PI * Luminance(scene.point_lights[i].intensity));
    }
    if (scene.voxel_lights) {
      for (int v = 0; v < scene.voxel_lights->VoxelCount(); ++v) {
        const double p = 4.0 * M_PI * scene.voxel_lights->MaxIntensityLuminance(v);
        if (p <= 0.0) continue;
        entries_.push_back({Kind::kVoxel, -1, v, 0.0f});
        power.push_back(p);
      }
    }
    double total = 0.0;
    for (double p : power) total += p;
    pmf_.resize(entries_.size());
    cdf_.resize(entries_.size());
    double running = 0.0;
    for (size_t i = 0; i < entries_.size(); ++i) {
      pmf_[i] = total > 0.0 ? static_cast<float>(power[i] / total) : 0.0f;
      running += total > 0.0 ? power[i] / total : 0.0;
      cdf_[i] = running;
    }
    if (!cdf_.empty()) cdf_.back() = 1.0;
  }

  bool empty() const { return entries_.empty() || cdf_.back() <= 0.0; }

  // Index of the chosen entry for a uniform u in [0, 1).
  size_t Choose(double u) const {
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), u);
    size_t i = std::min(static_cast<size_t>(it - cdf_.begin()), entries_.size() - 1);
    while (pmf_[i] <= 0.0f && i + 1 < entries_.size()) ++i;  // skip zero-power entries at u == cdf
    return i;
  }
  const Entry& entry(size_t i) const { return entries_[i]; }
  float pmf(size_t i) const { return pmf_[i]; }
  // Selection probability of triangle `face` of emitting mesh `mesh`.
  float TrianglePmf(int mesh, int face) const {
    const int first = first_triangle_[mesh];
    return first < 0 ? 0.0f : pmf_[first + face];
  }

 private:
  std::vector<Entry> entries_;
  std::vector<float> pmf_;
  std::vector<double> cdf_;
  std::vector<int> first_triangle_;  // per mesh: its first entry, -1 when it does not emit
};

}  // namespace genscene::render
