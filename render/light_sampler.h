// Light selection for next-event estimation, shared by the path tracer and the differentiable
// path tracer of vertex refinement (internal to render/).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
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
    PrepareLocal(scene, power);
  }

  bool empty() const { return entries_.empty() || cdf_.back() <= 0.0; }

  // Index of the chosen entry for a uniform u in [0, 1).
  size_t Choose(double u) const {
    return Pick(cdf_, u, [](size_t k) { return k; });
  }
  // A light for the shading point p with normal n (facing the incoming ray), chosen by its
  // contribution there (RenderOptions::light_selection "contribution"). The point and voxel
  // lights with at least kNearFieldPower of the strongest one's power, at most kMaxNearField of
  // them ("near-field" lights), together keep their share of the power pmf, but among them the
  // choice follows each light's unshadowed contribution I(w) max(0, n . wi) falloff(d) at p; the
  // rest (area lights, the faintest voxels) are chosen by power as Choose does. Every light that
  // can contribute keeps a non-zero probability, so the estimate stays unbiased. `scratch` holds
  // the weights.
  struct Choice {
    size_t entry = 0;
    float pmf = 0.0f;
  };
  // `visibility`, when given, holds a factor in (0, 1] per near-field light (in LocalPoints()'s
  // order) that multiplies its weight: how much of it reaches p (LightVisibility).
  Choice ChooseAt(const Eigen::Vector3f& p, const Eigen::Vector3f& n, double u,
                  std::vector<double>* scratch, const float* visibility = nullptr) const {
    if (local_.empty()) {
      const size_t i = Choose(u);
      return {i, pmf_[i]};
    }
    if (u >= local_share_) return ChooseInOrder(u);  // the rest, by power
    std::vector<double>& w = *scratch;
    w.resize(local_.size());
    double total = 0.0;
    for (size_t k = 0; k < local_.size(); ++k) {
      total += LocalWeight(k, p, n, visibility);
      w[k] = total;
    }
    if (!(total > 0.0)) return ChooseInOrder(u);  // nothing lights p: the near field by power
    const double target = u / local_share_ * total;
    size_t k = std::upper_bound(w.begin(), w.end(), target) - w.begin();
    k = std::min(k, local_.size() - 1);
    while (k > 0 && w[k] == w[k - 1]) --k;  // never a light with zero weight
    const double weight = w[k] - (k > 0 ? w[k - 1] : 0.0);
    return {local_[k], static_cast<float>(local_share_ * weight / total)};
  }

  // The lights of the shading point p split in two (SampleLights's first vertex): `exact` the
  // near-field lights with the `count` largest unshadowed contributions there (each to be taken
  // with probability 1), and `rest` one of all the other lights, chosen from u as ChooseAt would
  // choose among them, its probability renormalised over them (rest.pmf = 0: none is left).
  // The sum of the exact lights plus the rest's sample over its pmf is unbiased. `scratch` holds
  // the weights.
  void SplitAt(const Eigen::Vector3f& p, const Eigen::Vector3f& n, int count, double u,
               std::vector<double>* scratch, std::vector<size_t>* exact, Choice* rest,
               const float* visibility = nullptr) const {
    exact->clear();
    *rest = Choice{};
    if (local_.empty()) {
      const size_t i = Choose(u);
      *rest = {i, pmf_[i]};
      return;
    }
    std::vector<double>& w = *scratch;
    w.resize(local_.size());
    double total = 0.0;
    for (size_t k = 0; k < local_.size(); ++k) total += (w[k] = LocalWeight(k, p, n, visibility));
    if (!(total > 0.0)) {
      *rest = ChooseInOrder(u);
      return;
    }
    // The `count` largest weights (ties by index), marked by negating them.
    double removed = 0.0;
    for (int c = 0; c < count; ++c) {
      size_t best = local_.size();
      for (size_t k = 0; k < local_.size(); ++k) {
        if (w[k] > 0.0 && (best == local_.size() || w[k] > w[best])) best = k;
      }
      if (best == local_.size()) break;
      exact->push_back(local_[best]);
      removed += w[best];
      w[best] = -w[best];
    }
    // What is left: the other near-field lights by contribution (share local_share_ w / total),
    // then every other light by power.
    const double remaining = 1.0 - local_share_ * removed / total;
    if (remaining <= 1e-9) return;
    double target = u * remaining, acc = 0.0;
    for (size_t k = 0; k < local_.size(); ++k) {
      if (w[k] <= 0.0) continue;
      const double mass = local_share_ * w[k] / total;
      if (target < acc + mass) {
        *rest = {local_[k], static_cast<float>(mass / remaining)};
        return;
      }
      acc += mass;
    }
    if (order_.size() == local_.size()) {
      // Every light is near-field; round-off past the last one: the last one with weight.
      for (size_t k = local_.size(); k-- > 0;) {
        if (w[k] > 0.0) {
          *rest = {local_[k], static_cast<float>(local_share_ * w[k] / total / remaining)};
          return;
        }
      }
      return;
    }
    const double v = std::min(local_share_ + (target - acc), std::nextafter(1.0, 0.0));
    const Choice c = ChooseInOrder(std::max(v, local_share_));
    *rest = {c.entry, static_cast<float>(c.pmf / remaining)};
  }
  // The positions of the near-field lights, in the order ChooseAt's `visibility` follows.
  std::vector<Eigen::Vector3f> LocalPoints() const {
    std::vector<Eigen::Vector3f> points;
    for (const LocalLight& l : local_lights_) points.push_back(l.point);
    return points;
  }
  static constexpr double kNearFieldPower = 1e-6;
  static constexpr size_t kMaxNearField = 256;

  bool HasTriangles() const {
    for (int first : first_triangle_) {
      if (first >= 0) return true;
    }
    return false;
  }

  const Entry& entry(size_t i) const { return entries_[i]; }
  float pmf(size_t i) const { return pmf_[i]; }
  // Selection probability of triangle `face` of emitting mesh `mesh`.
  float TrianglePmf(int mesh, int face) const {
    const int first = first_triangle_[mesh];
    return first < 0 ? 0.0f : pmf_[first + face];
  }

 private:
  // ChooseAt's weight of near-field light k at p with normal n: its unshadowed contribution's
  // luminance I(w) cos falloff, times visibility[k] when given.
  double LocalWeight(size_t k, const Eigen::Vector3f& p, const Eigen::Vector3f& n,
                     const float* visibility) const {
    const LocalLight& l = local_lights_[k];
    const Eigen::Vector3f to = l.point - p;
    const float d2 = to.squaredNorm();
    const float along = n.dot(to);
    if (!(along > 0.0f && d2 > 0.0f)) return 0.0;
    // Luminance of I(w), w = -to / |to| from the light to p: the faces facing w.
    const float i = l.isotropic ? l.lum[0]
                                : (to.x() < 0 ? -to.x() * l.lum[0] : to.x() * l.lum[1]) +
                                      (to.y() < 0 ? -to.y() * l.lum[2] : to.y() * l.lum[3]) +
                                      (to.z() < 0 ? -to.z() * l.lum[4] : to.z() * l.lum[5]);
    // I(w) cos falloff with cos = n . to / d, the falloff 1 / (d^2 + e^2) and the face terms'
    // own 1 / d: along / (d^2 (d^2 + e^2)) (or along / d^3 for an isotropic light).
    const float inv_d2 = 1.0f / d2;
    return static_cast<double>(i * along * inv_d2 / (d2 + l.softening2)) *
           (l.isotropic ? std::sqrt(d2) : 1.0) * (visibility ? visibility[k] : 1.0f);
  }

  // The entry at u of a power cdf whose position k holds entry entry_of(k): the first position
  // with cdf > u, past zero-power entries (at u == cdf).
  template <typename EntryOf>
  size_t Pick(const std::vector<double>& cdf, double u, EntryOf entry_of) const {
    size_t k = std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin();
    k = std::min(k, cdf.size() - 1);
    while (pmf_[entry_of(k)] <= 0.0f && k + 1 < cdf.size()) ++k;
    return entry_of(k);
  }

  // The entry at u of the power pmf laid out in order_ (near-field lights first).
  Choice ChooseInOrder(double u) const {
    const size_t i = Pick(order_cdf_, u, [this](size_t k) { return order_[k]; });
    return {i, pmf_[i]};
  }

  void PrepareLocal(const Scene& scene, const std::vector<double>& power) {
    double strongest = 0.0;
    for (size_t i = 0; i < entries_.size(); ++i) {
      if (entries_[i].kind != Kind::kTriangle) strongest = std::max(strongest, power[i]);
    }
    // The near-field lights: the kMaxNearField strongest point and voxel lights with at least
    // kNearFieldPower of the strongest one's power (ties by entry). Faint is not far: a voxel
    // light of a thousandth of the strongest one's power can outshine it on the wall beside it,
    // and chosen by power there it would be drawn once in thousands of samples with a weight
    // in the thousands (salt noise).
    std::vector<size_t> candidates;
    for (size_t i = 0; i < entries_.size(); ++i) {
      if (entries_[i].kind != Kind::kTriangle && strongest > 0.0 &&
          power[i] >= kNearFieldPower * strongest)
        candidates.push_back(i);
    }
    if (candidates.size() > kMaxNearField) {
      std::stable_sort(candidates.begin(), candidates.end(),
                       [&](size_t a, size_t b) { return power[a] > power[b]; });
      candidates.resize(kMaxNearField);
    }
    std::vector<uint8_t> near(entries_.size(), 0);
    for (size_t i : candidates) near[i] = 1;
    // The power pmf laid out with the near-field lights first: they own u in [0, local_share_).
    std::vector<size_t> local, rest;
    for (size_t i = 0; i < entries_.size(); ++i) (near[i] ? local : rest).push_back(i);
    if (local.empty()) return;
    order_ = local;
    order_.insert(order_.end(), rest.begin(), rest.end());
    double running = 0.0;
    for (size_t k = 0; k < order_.size(); ++k) {
      running += pmf_[order_[k]];
      order_cdf_.push_back(running);
      if (k + 1 == local.size()) local_share_ = running;
    }
    order_cdf_.back() = 1.0;
    local_ = local;
    for (size_t i : local_) {
      const Entry& e = entries_[i];
      LocalLight l;
      if (e.kind == Kind::kVoxel) {
        const VoxelLightGrid& grid = *scene.voxel_lights;
        l.point = grid.VoxelCenter(e.index).cast<float>();
        l.softening2 = static_cast<float>(grid.softening * grid.softening);
        const float lum = Luminance(grid.intensity[e.index]);
        for (int k = 0; k < 6; ++k) l.lum[k] = lum * grid.weights[e.index][k];
      } else {
        l.point = scene.point_lights[e.index].position.cast<float>();
        l.isotropic = true;
        l.lum[0] = Luminance(scene.point_lights[e.index].intensity);
      }
      local_lights_.push_back(l);
    }
  }

  std::vector<Entry> entries_;
  std::vector<float> pmf_;
  std::vector<double> cdf_;
  std::vector<int> first_triangle_;  // per mesh: its first entry, -1 when it does not emit
  // ChooseAt's near-field lights: each its point and the luminance of L lambda_k per face
  // (voxels), or of its intensity in lum[0] (isotropic point lights); their entries and share of
  // the power pmf; every entry with the near-field ones first, and that order's cdf.
  struct LocalLight {
    Eigen::Vector3f point;
    std::array<float, 6> lum{};
    float softening2 = 0.0f;  // voxels: e^2 of the grid's falloff
    bool isotropic = false;
  };
  std::vector<size_t> local_;
  std::vector<LocalLight> local_lights_;
  double local_share_ = 0.0;
  std::vector<size_t> order_;
  std::vector<double> order_cdf_;
};

}  // namespace genscene::render
