// The differentiable path tracer of vertex refinement (the paper's section IV): the path
// tracer's estimator (next-event estimation + cosine BSDF sampling with MIS, Russian roulette) in
// sparse forward-mode AD, giving every path sample's radiance together with its derivatives with
// respect to the positions of the vertices of the refined meshes.
//
// What is differentiated: each hit point is re-intersected exactly (Moller-Trumbore in double
// precision) as a function of the ray and the three vertices of the triangle Embree found; face
// normals, area-weighted vertex normals (through every vertex of the one-ring), cosines, 1 / r^2,
// the MIS weights and the sampled bounce directions follow. What is not: visibility (which
// triangle a ray hits, whether a shadow ray is blocked) and the albedo's dependence on where on a
// face the hit lands (albedo is taken at the hit as a constant), nor the light choice: lights are
// chosen as the path tracer chooses them (RenderOptions::light_selection; by contribution the
// strongest taken exactly at the first vertex), with the choice's probabilities taken at the
// hit's value and held constant, which keeps the derivatives unbiased. With fixed random numbers
// and power selection (or a single light) the estimator is a smooth function of the vertices
// between visibility changes, and the derivatives are exact there; by contribution the chosen
// light can change as the vertices move, and only the expected derivative is exact.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "render/path_tracer.h"
#include "render/sparse_dual.h"

namespace genscene::render {

using DualRgb = std::array<SparseDual, 3>;

class DifferentiablePathTracer {
 public:
  // `refined[m]`: the vertices of scene mesh m are parameters (emitters never are). Vertices are
  // numbered mesh by mesh in scene order: parameter vertex i of the first refined mesh is i.
  DifferentiablePathTracer(const Scene& scene, const std::vector<bool>& refined);
  ~DifferentiablePathTracer();

  int VertexCount() const { return vertex_count_; }  // parameter vertices
  // Parameter vertex of vertex `v` of mesh `mesh`, -1 when that mesh is not refined.
  int ParameterVertex(int mesh, int v) const;
  // Positions of the parameter vertices, (x, y, z) per vertex.
  Eigen::VectorXd Positions() const;
  // Moves the parameter vertices: updates Embree's vertex buffers (refit), the smooth meshes'
  // vertex normals (area-weighted) and, with `derivatives`, the normals' derivatives (without, a
  // later Radiance with derivatives throws).
  void SetPositions(const Eigen::VectorXd& positions, bool derivatives = true);
  // The scene at the current positions (float vertices; smooth refined meshes carry the
  // area-weighted normals).
  const Scene& scene() const { return scene_; }

  // One path sample along a camera ray, as PathTracer::Radiance (`first_light_u` as there).
  // Without `derivatives` only the values are computed (same path, same value).
  DualRgb Radiance(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                   const RenderOptions& options, CounterRng& rng, bool derivatives,
                   RayCounts* counts = nullptr, double first_light_u = -1.0) const;
  // Pixel (u, v) of `view`: the mean of options.spp samples drawn as PathTracer::Render draws
  // them (box filter, centre or gaussian), keyed by (seed, pixel, sample).
  DualRgb Pixel(const PosedView& view, int u, int v, const RenderOptions& options, uint64_t seed,
                bool derivatives, RayCounts* counts = nullptr) const;

 private:
  struct Hit;
  DualVec3 Vertex(int mesh, int v, bool derivatives) const;
  std::optional<Hit> Intersect(const DualVec3& origin, const DualVec3& direction,
                               bool derivatives) const;
  void UpdateNormals(bool derivatives);
  // The MIS weight of emission met at `hit` by a BSDF sample from `previous` with pdf bsdf_pdf.
  SparseDual EmitterWeight(const Hit& hit, const Hit& previous, const SparseDual& bsdf_pdf) const;
  // The distant light at `at` (path::DistantDirections), its contribution (beta (*) albedo =
  // `beta_albedo`) added to `radiance`.
  void DistantLight(const Hit& at, const DualVec3& origin_offset,
                    const Eigen::Vector3d& beta_albedo, CounterRng& rng, DualRgb* radiance,
                    RayCounts* counts) const;
  // How a path's vertices choose their lights (RenderOptions::light_selection, exact_lights,
  // light_visibility), as PathTracer::Radiance chooses them.
  struct LightChoice {
    bool by_contribution = false;
    int exact = 0;  // this vertex: the lights of this many largest contributions taken exactly
    const LightVisibility* visibility = nullptr;
  };
  // Next-event estimation at `at` with one light sample, drawn as PathTracer::Radiance draws it
  // (chosen by `choice_u` when given), the contributions (beta (*) albedo = `beta_albedo`) of the
  // lights taken added to `radiance` when unblocked.
  void NextEvent(const Hit& at, const DualVec3& origin_offset, const Eigen::Vector3d& beta_albedo,
                 CounterRng& rng, DualRgb* radiance, RayCounts* counts, const LightChoice& choice,
                 double choice_u = -1.0) const;
  // Light entry i, chosen with probability pmf, at `at` (as PathTracer::EvaluateLight draws it).
  void Light(const Hit& at, const DualVec3& origin_offset, const Eigen::Vector3d& beta_albedo,
             size_t i, float pmf, CounterRng& rng, DualRgb* radiance, RayCounts* counts) const;

  Scene scene_;
  std::unique_ptr<RayTracer> tracer_;
  std::unique_ptr<LightSampler> lights_;
  std::vector<int> first_vertex_;  // per mesh: first parameter vertex or -1
  int vertex_count_ = 0;
  std::vector<std::vector<Eigen::Vector3d>> positions_;  // per mesh, double precision
  std::vector<std::vector<DualVec3>> dual_normals_;      // per smooth refined mesh: unit normals
  std::vector<std::vector<Eigen::Vector3d>> normals_;    // per smooth mesh: unit normal values
  bool normal_derivatives_ = true;                       // dual_normals_ match the positions
  bool has_area_lights_ = false;
  LazyLightVisibility visibility_;  // for light choice by contribution
};

}  // namespace genscene::render
