// What the path tracer, its light-estimation walk and the differentiable tracer share at every
// path vertex: the ray-origin offset, the MIS power heuristic, the cosine-weighted direction and
// the path continuation (direction, throughput, Russian roulette). The continuation is one
// template over float vectors and dual vectors, so that the tracers draw their random numbers in
// lockstep by construction. Internal to render/.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "core/rng.h"
#include "render/path_tracer.h"
#include "render/sparse_dual.h"

namespace genscene::render::path {

// Offset of a ray origin along the geometric normal, scaled with the magnitude of the position
// so that it stays above float round-off in large scenes (Mitsuba scenes in centimetres).
inline float OffsetScale(const Eigen::Vector3f& p) {
  return 2e-5f * (1.0f + p.cwiseAbs().maxCoeff());
}
inline double OffsetScale(const Eigen::Vector3d& p) {
  return 2e-5 * (1.0 + p.cwiseAbs().maxCoeff());
}

// Power heuristic (beta = 2) of Veach's multiple importance sampling: a^2 / (a^2 + b^2).
inline float PowerHeuristic(float pdf_a, float pdf_b) {
  const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
  return a + b > 0.0f ? a / (a + b) : 0.0f;
}
inline SparseDual PowerHeuristic(const SparseDual& pdf_a, const SparseDual& pdf_b) {
  const SparseDual a = pdf_a * pdf_a, b = pdf_b * pdf_b;
  const SparseDual sum = a + b;
  return sum.value() > 0.0 ? a / sum : SparseDual(0.0);
}

// Cosine-weighted direction around unit n (pdf = cos / pi): (sqrt(u1) cos(2 pi u2),
// sqrt(u1) sin(2 pi u2), sqrt(1 - u1)) in the orthonormal basis of Duff et al. 2017. The dual
// version is the same mapping in double precision, so that the direction's derivative follows the
// normal's.
inline Eigen::Vector3f SampleCosine(const Eigen::Vector3f& n, float u1, float u2) {
  const float r = std::sqrt(u1), phi = 2.0f * static_cast<float>(M_PI) * u2;
  const float x = r * std::cos(phi), y = r * std::sin(phi),
              z = std::sqrt(std::max(0.0f, 1.0f - u1));
  const float sign = std::copysign(1.0f, n.z());
  const float a = -1.0f / (sign + n.z()), b = n.x() * n.y() * a;
  const Eigen::Vector3f t(1.0f + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
  const Eigen::Vector3f s(b, sign + n.y() * n.y() * a, -n.y());
  return (x * t + y * s + z * n).normalized();
}
inline DualVec3 SampleCosine(const DualVec3& n, float u1, float u2) {
  const double r = std::sqrt(static_cast<double>(u1)), phi = 2.0 * M_PI * u2;
  const double x = r * std::cos(phi), y = r * std::sin(phi), z = std::sqrt(std::max(0.0, 1.0 - u1));
  const double sign = std::copysign(1.0, n.z.value());
  const SparseDual a = -1.0 / (sign + n.z);
  const SparseDual b = n.x * n.y * a;
  const DualVec3 t(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
  const DualVec3 s(b, sign + n.y * n.y * a, -n.y);
  return Normalized(x * t + y * s + z * n);
}

inline const Eigen::Vector3f& ValueOf(const Eigen::Vector3f& v) {
  return v;
}
inline Eigen::Vector3d ValueOf(const DualVec3& v) {
  return v.value();
}

// Whether a path may have `segments` segments (max_depth < 0: any number).
inline bool DepthAllowed(const RenderOptions& options, int segments) {
  return options.max_depth < 0 || segments <= options.max_depth;
}

// Continues a path past its vertex at `depth` segments on a Lambertian surface of `albedo`, with
// shading normal `ns` and geometric normal `ng` both facing the incoming ray:
//   wi ~ cos / pi around ns (u2 drawn first, then u1); the path ends when wi is below the
//   geometric surface (smooth shading);
//   beta <- beta (*) albedo (f cos / pdf = albedo for cosine sampling);
//   from depth >= rr_depth on, Russian roulette: q = min(0.95, max_c beta_c), the path ends
//   with probability 1 - q (one more number drawn), else beta <- beta / q.
// Returns false when the path ends; `wi` and `beta` are then not to be used.
template <typename Vec3, typename Rgb>
bool ContinuePath(const Vec3& ns, const Vec3& ng, const Rgb& albedo, int depth,
                  const RenderOptions& options, CounterRng& rng, Vec3* wi, Rgb* beta) {
  const float u2 = rng.Uniform();
  const float u1 = rng.Uniform();
  *wi = SampleCosine(ns, u1, u2);
  if (ValueOf(ng).dot(ValueOf(*wi)) <= 0) return false;
  *beta = beta->cwiseProduct(albedo);
  if (depth >= options.rr_depth) {
    const float q = std::min(0.95f, static_cast<float>(beta->maxCoeff()));
    if (rng.Uniform() >= q) return false;
    *beta /= q;
  }
  return true;
}

// The distant light (VoxelLightGrid::distant) at a path vertex: n cosine-distributed directions
// about the shading normal `ns`, the points (i / n, i phi) of a rank-1 lattice shifted by two
// uniform numbers drawn here (so each direction is cosine-distributed and the estimate unbiased),
// each traced to infinity; with f = albedo / pi, f cos / pdf = albedo, the vertex reflects
// albedo x mean over the n directions of visible x E(w). Every tracer estimates it so: the
// renders, the light-estimation cache and the differentiable tracer. Writes the directions above
// the geometric surface (normal `ng`) to `out` (room for n) and returns their count.
constexpr int kDistantRays = 8;
template <typename Vec3>
int DistantDirections(const Vec3& ns, const Vec3& ng, int n, CounterRng& rng, Vec3* out) {
  const float shift1 = rng.Uniform(), shift2 = rng.Uniform();
  int count = 0;
  for (int i = 0; i < n; ++i) {
    float u1 = shift1 + static_cast<float>(i) / static_cast<float>(n);
    float u2 = shift2 + 0.618034f * static_cast<float>(i);
    u1 -= std::floor(u1);
    u2 -= std::floor(u2);
    const Vec3 w = SampleCosine(ns, std::min(u1, 0.99999994f), std::min(u2, 0.99999994f));
    if (ValueOf(ng).dot(ValueOf(w)) > 0) out[count++] = w;
  }
  return count;
}

// The numbers of a pixel's samples that are stratified over them: the position in the pixel
// (dimensions 0, 1) and the first vertex's light choice (dimension 2), on Roberts' R3 lattice
// (the additive recurrence s / phi3^d, phi3 the positive root of x^4 = x + 1) shifted per pixel
// by a random offset keyed by (seed, pixel) (a Cranley-Patterson rotation): every number is
// uniform, so the estimate stays unbiased, while a pixel's samples cover [0, 1)^3 evenly for any
// sample count. Both tracers draw their samples through it.
class PixelLattice {
 public:
  PixelLattice(uint64_t seed, uint64_t pixel) {
    CounterRng rng(seed, pixel, ~0ull);
    for (double& s : shift_) s = rng.UniformDouble();
  }
  double operator()(int sample, int dimension) const {
    static constexpr double kPhi3 = 1.2207440845105186;
    static constexpr double kAlpha[3] = {1.0 / kPhi3, 1.0 / (kPhi3 * kPhi3),
                                         1.0 / (kPhi3 * kPhi3 * kPhi3)};
    const double x = shift_[dimension] + kAlpha[dimension] * sample;
    return x - std::floor(x);
  }

 private:
  double shift_[3];
};

}  // namespace genscene::render::path
