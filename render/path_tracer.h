// Forward path tracer on the Embree wrapper: Lambertian surfaces, one-sided area lights, point
// lights and voxel lights; next-event estimation and cosine-weighted BSDF sampling combined by
// multiple importance sampling (power heuristic), Russian roulette, a max-depth option and
// deterministic per-(pixel, sample) random numbers.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/image.h"
#include "core/rng.h"
#include "render/light_visibility.h"
#include "render/ray_tracer.h"
#include "render/scene.h"

namespace genscene::render {

class LightSampler;

struct RenderOptions {
  static constexpr const char* kSection = "render";

  int spp = 64;  // samples per pixel
  // Longest path in segments, as Mitsuba's max_depth: 1 = emitters seen directly, 2 = direct
  // illumination, -1 = unlimited (ended by Russian roulette). Cycles' "max bounces B" is B + 2.
  int max_depth = -1;
  int rr_depth = 5;            // Russian roulette starts at this path depth (segments)
  std::string filter = "box";  // box: samples uniform over the pixel's square footprint;
                               // center: every sample through the pixel centre;
                               // gaussian: Mitsuba's truncated Gaussian (radius 4 stddev)
  double filter_stddev = 0.5;  // gaussian filter standard deviation, pixels
  bool hide_emitters = false;  // camera rays that hit an emitter return black
  // Next-event estimation's choice among the lights: "contribution" (point and voxel lights by
  // their unshadowed contribution at the shading point, LightSampler::ChooseAt) or "power" (by
  // power alone). The differentiable tracer of vertex refinement chooses as this one does.
  std::string light_selection = "contribution";
  // Lights sampled per path vertex (next-event estimation), combined with the BSDF's hits on area
  // lights by the power heuristic over both counts.
  int light_samples = 1;
  // With light_selection "contribution" and only point and voxel lights: at a path's first
  // vertex the lights with this many largest unshadowed contributions there are taken each with
  // a shadow ray, and one of the others is sampled (per light sample); 0: every light sampled.
  int exact_lights = 4;
  // With light_selection "contribution": each point and voxel light's weight is also multiplied
  // by how much of it reaches the shading point's surroundings (LightVisibility, a cache of shadow
  // rays from the surfaces built on first use), so that bright lights behind walls are rarely
  // chosen where they are blocked. Changes only the noise, never the expected image.
  bool light_visibility = true;
  // A pixel averages only the samples whose camera ray meets a surface (black where none does):
  // the colour of the covered part of a pixel on a silhouette against empty space, which a scan's
  // model has wherever the room was not scanned. The held-out evaluation renders so, its mask and
  // baselines being the pixel centre's hit. Not a user setting: no key in Visit.
  bool surface_only = false;

  // The stages that trace paths hold their path settings as one RenderOptions and list them under
  // these keys, saying in `spp_help` what one of their samples is.
  static RenderOptions Paths(int spp, int max_depth = -1, int rr_depth = 5) {
    RenderOptions r;
    r.spp = spp;
    r.max_depth = max_depth;
    r.rr_depth = rr_depth;
    return r;
  }
  template <typename V>
  void VisitPaths(V&& v, const char* spp_help = "samples per pixel") {
    v("spp", spp, "", spp_help);
    v("max_depth", max_depth, "segments", "longest path (Mitsuba convention; -1 = unlimited)");
    v("rr_depth", rr_depth, "segments", "depth at which Russian roulette starts");
  }

  template <typename V>
  void Visit(V&& v) {
    VisitPaths(v);
    v("filter", filter, "",
      "pixel filter: box (pixel footprint), center (pixel-centre rays) or gaussian");
    v("filter_stddev", filter_stddev, "px", "standard deviation of the gaussian filter");
    v("hide_emitters", hide_emitters, "", "camera rays that hit an emitter return black");
    v("light_selection", light_selection, "",
      "choice of light per shading point: contribution (point and voxel lights by their "
      "unshadowed contribution there) or power");
    v("light_samples", light_samples, "", "lights sampled per path vertex");
    v("exact_lights", exact_lights, "",
      "at the first vertex, the lights of this many largest contributions each get a shadow ray "
      "(point and voxel lights; 0: all sampled)");
    v("light_visibility", light_visibility, "",
      "contribution selection also weighs each light by how much of it reaches the surface there "
      "(a cache of shadow rays from the surfaces)");
  }
  void Validate() const;
};

// Rays traced, for speed reports.
struct RayCounts {
  uint64_t intersect = 0;  // nearest-hit rays (camera and BSDF-sampled)
  uint64_t occluded = 0;   // shadow rays
  uint64_t total() const { return intersect + occluded; }
};

// What a render produces; depth, normal and object come from the pixel-centre ray.
struct RenderOutput {
  ImageRgb radiance;  // linear RGB, mean over the samples
  ImageDepth depth;   // planar z in meters, 0 where the ray escapes
  ImageRgb normal;    // world-space shading normal facing the camera, 0 where the ray escapes
  Image<int> object;  // mesh index, -1 where the ray escapes
  RayCounts rays;     // traced for the radiance (not for the geometry buffers)
};

// Which voxel lights a path vertex connects to when light estimation splits. Vertices up
// to depth `all_until_depth` (1 = the first surface hit) connect to every voxel with
// `enabled[j]` (empty = all of them); deeper vertices draw `samples` voxels with probabilities
// `pmf` (sum 1), each connection weighted 1 / (samples * pmf[j]); with samples = 0 they connect
// to every voxel too.
struct VoxelSplitting {
  std::vector<bool> enabled;
  // Every vertex (as the voxels' first_vertex_weight says) connects to the grid's distant light,
  // when it has one and `distant`, as light VoxelCount(): `distant_rays` cosine-distributed
  // shadow rays to infinity, w the direction of each unblocked one.
  bool distant = true;
  int distant_rays = 8;
  int all_until_depth = 1 << 30;
  int samples = 0;
  std::vector<double> pmf;
  std::vector<double> cdf;  // running sum of pmf (filled by SetPmf)
  // Filled by Prepare for one grid: every voxel's centre and the voxels the shallow vertices
  // connect to. Without them VoxelCoefficients works them out per path.
  std::vector<Eigen::Vector3f> centres;
  std::vector<int> connected;
  void SetPmf(std::vector<double> probabilities, int samples_per_vertex);
  int Choose(double u) const;
  void Prepare(const VoxelLightGrid& grid);
};

// The unblocked connections of one path vertex to voxels. Connection i reaches voxel[i]; w[i] is
// the unit direction from the voxel to the surface point and base[i] the RGB throughput x BRDF x
// cosine / r^2 x weight. The coefficient of the product L_j lambda_jk is
// c_k = base[i] max(0, w[i] . d_k), with the faces d_k = +x, -x, +y, -y, +z, -z (k = 2 axis, plus
// 1 on the negative side): one face per axis at most, the one VoxelFace gives. The vertex's
// contribution to the pixel is sum_i sum_k c_k (*) L_j lambda_jk.
struct VoxelConnections {
  int count = 0;
  const int* voxel = nullptr;
  const Eigen::Vector3f* w = nullptr;
  const Eigen::Vector3f* base = nullptr;
};
// The face k on `axis` that a connection with direction component w_axis lights (w_axis != 0).
inline int VoxelFace(int axis, float w_axis) {
  return 2 * axis + (w_axis < 0.0f ? 1 : 0);
}
using VoxelCoefficientSink = std::function<void(const VoxelConnections& connections)>;

class PathTracer {
 public:
  // Copies what it needs from the scene (validated) and builds the ray tracer.
  explicit PathTracer(const Scene& scene);
  ~PathTracer();

  // Renders one view; `seed` keys every random number (same seed, same image, any thread count).
  RenderOutput Render(const PosedView& view, const RenderOptions& options, uint64_t seed) const;

  // Radiance along one camera ray (one path sample), for tests and the inverse stages.
  // Adds the rays it traces to `counts` when given. `first_light_u` in [0, 1), when given, is
  // the number that chooses the first vertex's light (Render stratifies it over a pixel's
  // samples); otherwise `rng` draws it. `met_surface`, when given, says whether the ray itself
  // met a surface (RenderOptions::surface_only).
  Eigen::Vector3f Radiance(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                           const RenderOptions& options, CounterRng& rng,
                           RayCounts* counts = nullptr, double first_light_u = -1.0,
                           bool* met_surface = nullptr) const;

  // Light estimation's walk: the same camera path as Radiance() (BSDF sampling,
  // Russian roulette, max_depth), but at every vertex it connects to the voxels of `splitting`
  // (positions from `grid`; its intensities are not read) with a shadow ray each (and, when the
  // grid has a distant light and `splitting.distant`, to it by rays to infinity), and reports
  // the coefficients of the products L_j lambda_jk to `sink` (once per vertex, the connections
  // whose shadow ray is not blocked) instead of adding radiance. Emitters and the
  // scene's own lights are ignored. The predicted radiance is linear in the products L lambda.
  // The connections of the first vertex (direct light) are weighted by `first_vertex_weight`
  // (0: not traced), so that direct and indirect light can be estimated from different numbers
  // of paths.
  void VoxelCoefficients(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                         const VoxelLightGrid& grid, const VoxelSplitting& splitting,
                         const RenderOptions& options, CounterRng& rng,
                         const VoxelCoefficientSink& sink, RayCounts* counts = nullptr,
                         float first_vertex_weight = 1.0f) const;

  // The first surface the ray through the centre of pixel (u, v) of `view` meets: the ray of the
  // geometry buffers, of the pixel masks and of every first-hit lookup (albedo, texture).
  std::optional<RayHit> PixelCentreHit(const PosedView& view, int u, int v) const;

  const Scene& scene() const { return scene_; }
  const RayTracer& tracer() const { return *tracer_; }

 private:
  struct SurfacePoint;
  struct LightSample;

  std::optional<SurfacePoint> Hit(const Eigen::Vector3f& origin,
                                  const Eigen::Vector3f& direction) const;
  // One light sample for next-event estimation at `at`, chosen by power alone or by its
  // contribution there (RenderOptions::light_selection). `choice_u` in [0, 1) chooses the light
  // when given (rng's draw for it is then discarded).
  // `visibility`: the near-field lights' factors at `at` (LightVisibility::At), or nullptr.
  std::optional<LightSample> SampleLight(const SurfacePoint& at, bool by_power, CounterRng& rng,
                                         double choice_u = -1.0,
                                         const float* visibility = nullptr) const;
  // The sample of light entry i (chosen with probability pmf) at `at`.
  std::optional<LightSample> EvaluateLight(const SurfacePoint& at, size_t i, float pmf,
                                           CounterRng& rng) const;
  // Solid-angle pdf with which SampleLight picks the point `p` of emitting face (mesh, face).
  float AreaLightPdf(const SurfacePoint& from, const SurfacePoint& on_light) const;

  Scene scene_;
  std::unique_ptr<RayTracer> tracer_;
  std::unique_ptr<LightSampler> lights_;
  bool has_area_lights_ = false;
  const VoxelLightGrid* distant_ = nullptr;  // the scene's voxel lights when they have one
  LazyLightVisibility visibility_;           // for light choice by contribution
};

// Two independent renders of a view with half the paths each (random numbers keyed by seed_a and
// seed_b): their mean is the render, and their difference measures its Monte Carlo noise, for
// every comparison that takes the noise out (the evaluation, the held-out judge, CompareRender).
struct RenderHalves {
  ImageRgb a, b;  // the two halves
  ImageRgb mean;  // (a + b) / 2
  // RMS per channel of the mean's noise over all pixels: sqrt(sum |a - b|^2 / 4 / (3 pixels)).
  double NoiseRms() const;
};
// `options.spp` is the total (each half gets max(1, spp / 2)).
RenderHalves RenderInHalves(const PathTracer& tracer, const PosedView& view,
                            const RenderOptions& options, uint64_t seed_a, uint64_t seed_b);

}  // namespace genscene::render
