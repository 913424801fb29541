#include "render/path_tracer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/check.h"
#include "core/color.h"
#include "core/options.h"
#include "core/parallel.h"
#include "render/light_sampler.h"
#include "render/light_visibility.h"
#include "render/path_continuation.h"

namespace genscene::render {

namespace {

using path::DepthAllowed;
using path::OffsetScale;
using path::PowerHeuristic;

// Offset from the pixel centre drawn with density proportional to Mitsuba's Gaussian filter
// w(x) = max(0, exp(-x^2 / (2 s^2)) - exp(-r^2 / (2 s^2))), r = 4 s: a normal sample truncated to
// [-r, r], accepted with probability w(x) / exp(-x^2 / (2 s^2)). Drawing sample positions from the
// filter gives each pixel the expected value of Mitsuba's weighted average sum w L / sum w.
double SampleGaussianFilter(double stddev, CounterRng& rng) {
  const double radius = 4.0 * stddev;
  for (;;) {
    const double x = stddev * rng.Normal();
    if (std::abs(x) > radius) continue;
    const double keep = 1.0 - std::exp((x * x - radius * radius) / (2.0 * stddev * stddev));
    if (rng.UniformDouble() < keep) return x;
  }
}

}  // namespace

void RenderOptions::Validate() const {
  RequireRange("spp", spp, 1, 1 << 20);
  if (max_depth == 0 || max_depth < -1)
    throw Error(Format("option max_depth = ", max_depth, " must be -1 or >= 1"));
  RequireRange("rr_depth", rr_depth, 1, 1 << 20);
  RequireOneOf("filter", filter, {"box", "center", "gaussian"});
  RequireRange("filter_stddev", filter_stddev, 0.05, 10.0);
  RequireOneOf("light_selection", light_selection, {"contribution", "power"});
  RequireRange("light_samples", light_samples, 1, 1024);
  RequireRange("exact_lights", exact_lights, 0, 1 << 20);
}

// A surface point as the path tracer uses it.
struct PathTracer::SurfacePoint {
  Eigen::Vector3f p;   // position
  Eigen::Vector3f ng;  // unit geometric normal of the counter-clockwise face (not flipped)
  Eigen::Vector3f ns;  // unit shading normal, on the same side as ng
  float t = 0.0f;      // ray distance to it
  int mesh = -1, face = -1;
  float b1 = 0.0f, b2 = 0.0f;
  float area = 0.0f;  // area of the face
};

// One light sample as seen from a surface point.
struct PathTracer::LightSample {
  Eigen::Vector3f wi;     // unit direction from the surface point to the light
  Eigen::Vector3f point;  // the sampled light point
  Eigen::Vector3f value;  // area lights: emitted radiance; point/voxel lights: intensity / r^2
  float pdf = 0.0f;       // area lights: solid angle pdf; point/voxel lights: selection probability
  bool is_delta = false;  // point and voxel lights cannot be hit by BSDF sampling
};

PathTracer::PathTracer(const Scene& scene) : scene_(scene), tracer_(std::make_unique<RayTracer>()) {
  scene_.Validate();
  for (const SceneMesh& m : scene_.meshes) tracer_->AddMesh(m.mesh);
  tracer_->Commit();
  lights_ = std::make_unique<LightSampler>(scene_);
  has_area_lights_ = lights_->HasTriangles();
  if (scene_.voxel_lights && scene_.voxel_lights->HasDistantLight())
    distant_ = &*scene_.voxel_lights;
}

PathTracer::~PathTracer() = default;

std::optional<PathTracer::SurfacePoint> PathTracer::Hit(const Eigen::Vector3f& origin,
                                                        const Eigen::Vector3f& direction) const {
  const auto hit = tracer_->Intersect(origin, direction);
  if (!hit) return std::nullopt;
  const SceneMesh& m = scene_.meshes[hit->mesh];
  const Eigen::Vector3i& f = m.mesh.faces[hit->face];
  SurfacePoint s;
  s.t = hit->t;
  s.mesh = hit->mesh;
  s.face = hit->face;
  s.b1 = hit->b1;
  s.b2 = hit->b2;
  const float b0 = 1.0f - hit->b1 - hit->b2;
  const auto& v = m.mesh.vertices;
  s.p = b0 * v[f[0]] + hit->b1 * v[f[1]] + hit->b2 * v[f[2]];
  const Eigen::Vector3f n = m.mesh.FaceNormalScaled(hit->face);
  s.area = 0.5f * n.norm();
  // Zero-area triangles have no interior for Embree to hit and no power to sample; should round-off
  // still report one, it faces the ray.
  s.ng = s.area > 0.0f ? Eigen::Vector3f(n / (2.0f * s.area))
                       : Eigen::Vector3f(-direction.normalized());
  s.ns = m.ShadingNormal(static_cast<size_t>(hit->face), hit->b1, hit->b2, s.ng);
  return s;
}

std::optional<PathTracer::LightSample> PathTracer::SampleLight(const SurfacePoint& at,
                                                               bool by_power, CounterRng& rng,
                                                               double choice_u,
                                                               const float* visibility) const {
  if (lights_->empty()) return std::nullopt;
  size_t i = 0;
  float pmf = 0.0f;
  const double drawn = rng.UniformDouble();
  const double u = choice_u >= 0.0 ? choice_u : drawn;
  if (by_power) {
    i = lights_->Choose(u);
    pmf = lights_->pmf(i);
  } else {
    thread_local std::vector<double> scratch;
    const LightSampler::Choice c = lights_->ChooseAt(at.p, at.ns, u, &scratch, visibility);
    i = c.entry;
    pmf = c.pmf;
  }
  return EvaluateLight(at, i, pmf, rng);
}

std::optional<PathTracer::LightSample> PathTracer::EvaluateLight(const SurfacePoint& at, size_t i,
                                                                 float pmf, CounterRng& rng) const {
  const LightSampler::Entry& e = lights_->entry(i);
  const float u1 = rng.Uniform(), u2 = rng.Uniform();
  LightSample s;
  switch (e.kind) {
    case LightSampler::Kind::kTriangle: {
      const SceneMesh& m = scene_.meshes[e.mesh];
      const Eigen::Vector3f q = UniformPointOnTriangle(m.mesh, e.index, u1, u2);
      s.point = q;
      const Eigen::Vector3f to_light = q - at.p;
      const float d2 = to_light.squaredNorm();
      if (d2 <= 0.0f) return std::nullopt;
      s.wi = to_light / std::sqrt(d2);
      // One-sided: the light emits only towards the side its counter-clockwise normal points to.
      const float cos_light = -m.mesh.FaceNormalScaled(e.index).normalized().dot(s.wi);
      if (cos_light <= 0.0f) return std::nullopt;
      s.value = m.emission;
      s.pdf = pmf * d2 / (e.area * cos_light);
      return s;
    }
    case LightSampler::Kind::kPoint: {
      const PointLight& light = scene_.point_lights[e.index];
      s.point = light.position.cast<float>();
      const Eigen::Vector3f to_light = s.point - at.p;
      const float d2 = to_light.squaredNorm();
      if (d2 <= 0.0f) return std::nullopt;
      s.wi = to_light / std::sqrt(d2);
      s.value = light.intensity / d2;
      s.pdf = pmf;
      s.is_delta = true;
      return s;
    }
    case LightSampler::Kind::kVoxel: {
      const VoxelLightGrid& grid = *scene_.voxel_lights;
      s.point = grid.VoxelCenter(e.index).cast<float>();
      const Eigen::Vector3f to_light = s.point - at.p;
      const float d2 = to_light.squaredNorm();
      if (d2 <= 0.0f) return std::nullopt;
      s.wi = to_light / std::sqrt(d2);
      s.value = grid.Intensity(e.index, (-s.wi).cast<double>()) * grid.Falloff(d2);
      s.pdf = pmf;
      s.is_delta = true;
      return s;
    }
  }
  return std::nullopt;
}

float PathTracer::AreaLightPdf(const SurfacePoint& from, const SurfacePoint& on_light) const {
  const float pmf = lights_->TrianglePmf(on_light.mesh, on_light.face);
  if (pmf <= 0.0f) return 0.0f;
  const Eigen::Vector3f d = on_light.p - from.p;
  const float d2 = d.squaredNorm();
  const float cos_light = std::abs(on_light.ng.dot(d)) / std::sqrt(d2);
  return cos_light > 0.0f ? pmf * d2 / (on_light.area * cos_light) : 0.0f;
}

Eigen::Vector3f PathTracer::Radiance(const Eigen::Vector3f& origin,
                                     const Eigen::Vector3f& direction, const RenderOptions& options,
                                     CounterRng& rng, RayCounts* counts, double first_light_u,
                                     bool* met_surface) const {
  RayCounts local;
  Eigen::Vector3f radiance = Eigen::Vector3f::Zero();
  Eigen::Vector3f beta = Eigen::Vector3f::Ones();  // path throughput
  Eigen::Vector3f ray_o = origin, ray_d = direction.normalized();
  float bsdf_pdf = 0.0f;  // solid-angle pdf of the last BSDF sample
  std::optional<SurfacePoint> previous;
  const bool by_power = options.light_selection == "power";
  const LightVisibility* visibility =
      !by_power && options.light_visibility ? visibility_.Get(scene_, *tracer_, *lights_) : nullptr;

  for (int depth = 1;; ++depth) {  // depth = segments of the path so far, ending at `hit`
    ++local.intersect;
    const auto hit = Hit(ray_o, ray_d);
    if (depth == 1 && met_surface) *met_surface = hit.has_value();
    if (!hit) break;
    const SceneMesh& mesh = scene_.meshes[hit->mesh];

    // Emission seen along the ray: emitters are one-sided (front = counter-clockwise side).
    if (mesh.IsEmitter() && hit->ng.dot(ray_d) < 0.0f) {
      if (depth == 1) {
        if (!options.hide_emitters) radiance += mesh.emission;
      } else {
        const float weight =
            PowerHeuristic(bsdf_pdf, options.light_samples * AreaLightPdf(*previous, *hit));
        radiance += beta.cwiseProduct(mesh.emission) * weight;
      }
    }
    if (!DepthAllowed(options, depth + 1)) break;
    const Eigen::Vector3f albedo = mesh.albedo.Eval(mesh.mesh, hit->face, hit->b1, hit->b2);
    if (albedo.maxCoeff() <= 0.0f) break;

    // Lambertian surfaces reflect on both sides: orient the normals towards the incoming ray.
    SurfacePoint at = *hit;
    if (at.ng.dot(ray_d) > 0.0f) at.ng = -at.ng, at.ns = -at.ns;
    const Eigen::Vector3f origin_offset = at.p + OffsetScale(at.p) * at.ng;

    // Sample direct illumination from the light sources (next-event estimation), n samples
    // each weighted 1 / n; the power heuristic sees n pdf_light against pdf_bsdf. At the first
    // vertex a given first_light_u places the n choices in the n strata of [0, 1).
    const int n = options.light_samples;
    const float* seen = visibility ? visibility->At(at.p) : nullptr;
    const auto add = [&](const std::optional<LightSample>& light) {
      const float cos_s = light ? at.ns.dot(light->wi) : 0.0f;
      if (!light || cos_s <= 0.0f || at.ng.dot(light->wi) <= 0.0f) return;
      ++local.occluded;
      if (tracer_->SegmentOccluded(origin_offset, light->point)) return;
      const float pdf_bsdf = cos_s / static_cast<float>(M_PI);
      const float weight = light->is_delta ? 1.0f : PowerHeuristic(n * light->pdf, pdf_bsdf);
      const Eigen::Vector3f f = albedo * (cos_s / static_cast<float>(M_PI));
      radiance += beta.cwiseProduct(f).cwiseProduct(light->value) * (weight / (n * light->pdf));
    };
    if (depth == 1 && options.exact_lights > 0 && !by_power && !has_area_lights_ &&
        !lights_->empty()) {
      // The first vertex (direct light, most of a pixel's noise): the exact_lights strongest
      // near-field lights taken each with probability 1, the rest sampled n times (delta lights
      // only, so no MIS weight depends on the split).
      thread_local std::vector<double> scratch;
      thread_local std::vector<size_t> exact;
      for (int k = 0; k < n; ++k) {
        const double drawn = rng.UniformDouble();
        const double u = first_light_u >= 0.0 ? (k + first_light_u) / n : drawn;
        LightSampler::Choice rest;
        lights_->SplitAt(at.p, at.ns, options.exact_lights, u, &scratch, &exact, &rest, seen);
        if (k == 0) {
          // Each exact light once, with pmf 1 / n against `add`'s division by n.
          for (size_t e : exact) add(EvaluateLight(at, e, 1.0f / n, rng));
        }
        if (rest.pmf > 0.0f) add(EvaluateLight(at, rest.entry, rest.pmf, rng));
      }
    } else {
      for (int k = 0; k < n; ++k) {
        double u = -1.0;
        if (depth == 1 && first_light_u >= 0.0) {
          u = (k + first_light_u) / n;
        }
        add(SampleLight(at, by_power, rng, u, seen));
      }
    }

    // The distant light, by its own shadow rays to infinity (path::DistantDirections).
    if (distant_) {
      const int rays = path::kDistantRays;
      Eigen::Vector3f directions[path::kDistantRays];
      const int m = path::DistantDirections(at.ns, at.ng, rays, rng, directions);
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (int i = 0; i < m; ++i) {
        ++local.occluded;
        if (!tracer_->Occluded(origin_offset, directions[i], 0.0f,
                               std::numeric_limits<float>::infinity()))
          sum += distant_->DistantRadiance(directions[i]);
      }
      radiance += beta.cwiseProduct(albedo).cwiseProduct(sum) / static_cast<float>(rays);
    }

    Eigen::Vector3f wi;
    if (!path::ContinuePath(at.ns, at.ng, albedo, depth, options, rng, &wi, &beta)) break;
    bsdf_pdf = at.ns.dot(wi) / static_cast<float>(M_PI);
    previous = at;
    ray_o = origin_offset;
    ray_d = wi;
  }
  if (counts) {
    counts->intersect += local.intersect;
    counts->occluded += local.occluded;
  }
  return radiance;
}

void VoxelSplitting::SetPmf(std::vector<double> probabilities, int samples_per_vertex) {
  GS_CHECK_GT(samples_per_vertex, 0);
  double total = 0.0;
  for (double p : probabilities) total += p;
  GS_CHECK_GT(total, 0.0);
  pmf = std::move(probabilities);
  cdf.resize(pmf.size());
  double running = 0.0;
  for (size_t i = 0; i < pmf.size(); ++i) {
    pmf[i] /= total;
    running += pmf[i];
    cdf[i] = running;
  }
  // From the last voxel that can be drawn on, the running sum is 1: rounding cannot send a draw
  // past it to a voxel of probability 0.
  size_t last = pmf.size() - 1;
  while (last > 0 && pmf[last] <= 0.0) --last;
  std::fill(cdf.begin() + static_cast<std::ptrdiff_t>(last), cdf.end(), 1.0);
  samples = samples_per_vertex;
}

void VoxelSplitting::Prepare(const VoxelLightGrid& grid) {
  const int voxels = grid.VoxelCount();
  GS_CHECK(enabled.empty() || static_cast<int>(enabled.size()) == voxels);
  centres.resize(static_cast<size_t>(voxels));
  connected.clear();
  for (int j = 0; j < voxels; ++j) {
    centres[j] = grid.VoxelCenter(j).cast<float>();
    if (enabled.empty() || enabled[j]) connected.push_back(j);
  }
}

int VoxelSplitting::Choose(double u) const {
  const auto it = std::upper_bound(cdf.begin(), cdf.end(), u);
  size_t i = std::min(static_cast<size_t>(it - cdf.begin()), pmf.size() - 1);
  while (pmf[i] <= 0.0 && i + 1 < pmf.size()) ++i;
  return static_cast<int>(i);
}

namespace {

// The shadow rays of one path vertex to voxels: voxel, weight and cos x falloff per ray beside the
// arrays that OccludedFrom reads (directions to the voxels, segment lengths), then the unblocked
// ones as the sink reads them. One per thread, so that a path allocates nothing.
struct VoxelShadowRays {
  std::vector<int> voxel, out_voxel;
  std::vector<float> weight, cos_falloff, t_max;
  float softening2 = 0.0f;  // e^2 of the grid's falloff 1 / (d^2 + e^2)
  std::vector<Eigen::Vector3f> directions, out_w, out_base;
  std::vector<uint8_t> blocked;
  int n = 0;

  void Reserve(size_t most) {
    if (voxel.size() >= most) return;
    for (auto* v : {&voxel, &out_voxel}) v->resize(most);
    for (auto* v : {&weight, &cos_falloff, &t_max}) v->resize(most);
    for (auto* v : {&directions, &out_w, &out_base}) v->resize(most);
    blocked.resize(most);
  }
  // Adds the ray from surface point p (normals ns, ng facing the incoming ray) to voxel j at
  // `centre` when the voxel is above both the shading and the geometric surface.
  void Consider(const Eigen::Vector3f& p, const Eigen::Vector3f& ns, const Eigen::Vector3f& ng,
                const Eigen::Vector3f& centre, int j, float w) {
    const Eigen::Vector3f to_light = centre - p;
    const float d2 = to_light.squaredNorm();
    if (d2 <= 0.0f) return;
    const float distance = std::sqrt(d2);
    const Eigen::Vector3f wi = to_light / distance;
    const float cos_s = ns.dot(wi);
    if (cos_s <= 0.0f || ng.dot(wi) <= 0.0f) return;
    voxel[n] = j;
    weight[n] = w;
    cos_falloff[n] = cos_s / (d2 + softening2);
    directions[n] = wi;
    t_max[n] = distance * (1.0f - 1e-4f);
    ++n;
  }
  // Traces the gathered rays together in packets from `from` and reports the unblocked ones to
  // the sink in the gathered order, with base = f_beta cos / (d^2 + e^2) x weight.
  void Trace(const RayTracer& tracer, const Eigen::Vector3f& from, const Eigen::Vector3f& f_beta,
             const VoxelCoefficientSink& sink, RayCounts* counts) {
    if (n == 0) return;
    counts->occluded += n;
    tracer.OccludedFrom(from, directions.data(), t_max.data(), n, 0.0f, blocked.data());
    int m = 0;
    for (int i = 0; i < n; ++i) {
      if (blocked[i]) continue;
      // I(w) = L sum_k lambda_k max(0, w . d_k) with w = -wi, from the voxel to the surface.
      out_voxel[m] = voxel[i];
      out_w[m] = -directions[i];
      out_base[m] = f_beta * (cos_falloff[i] * weight[i]);
      ++m;
    }
    if (m > 0) sink({m, out_voxel.data(), out_w.data(), out_base.data()});
  }
};

}  // namespace

void PathTracer::VoxelCoefficients(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                                   const VoxelLightGrid& grid, const VoxelSplitting& splitting,
                                   const RenderOptions& options, CounterRng& rng,
                                   const VoxelCoefficientSink& sink, RayCounts* counts,
                                   float first_vertex_weight) const {
  RayCounts local;
  Eigen::Vector3f beta = Eigen::Vector3f::Ones();
  Eigen::Vector3f ray_o = origin, ray_d = direction.normalized();
  const VoxelSplitting* prepared = &splitting;
  VoxelSplitting local_splitting;
  if (static_cast<int>(splitting.centres.size()) != grid.VoxelCount()) {
    local_splitting.enabled = splitting.enabled;
    local_splitting.Prepare(grid);
    prepared = &local_splitting;
  }
  const std::vector<Eigen::Vector3f>& centres = prepared->centres;
  thread_local VoxelShadowRays rays;
  rays.softening2 = static_cast<float>(grid.softening * grid.softening);
  rays.Reserve(
      std::max(prepared->connected.size(), static_cast<size_t>(std::max(splitting.samples, 0))));

  for (int depth = 1;; ++depth) {
    ++local.intersect;
    const auto hit = Hit(ray_o, ray_d);
    if (!hit || !DepthAllowed(options, depth + 1)) break;
    const SceneMesh& mesh = scene_.meshes[hit->mesh];
    const Eigen::Vector3f albedo = mesh.albedo.Eval(mesh.mesh, hit->face, hit->b1, hit->b2);
    if (albedo.maxCoeff() <= 0.0f) break;
    SurfacePoint at = *hit;
    if (at.ng.dot(ray_d) > 0.0f) at.ng = -at.ng, at.ns = -at.ns;
    const Eigen::Vector3f origin_offset = at.p + OffsetScale(at.p) * at.ng;

    // Shadow rays to the chosen voxels (as SampleLight + next-event estimation in Radiance()).
    rays.n = 0;
    if (depth == 1 && first_vertex_weight <= 0.0f) {
      // direct light estimated by other paths
    } else if (depth <= splitting.all_until_depth || splitting.samples <= 0) {
      const float weight = depth == 1 ? first_vertex_weight : 1.0f;
      for (int j : prepared->connected) rays.Consider(at.p, at.ns, at.ng, centres[j], j, weight);
    } else {
      for (int s = 0; s < splitting.samples; ++s) {
        const int j = splitting.Choose(rng.UniformDouble());
        rays.Consider(at.p, at.ns, at.ng, centres[j], j,
                      static_cast<float>(1.0 / (splitting.samples * splitting.pmf[j])));
      }
    }
    rays.Trace(*tracer_, origin_offset, beta.cwiseProduct(albedo) / static_cast<float>(M_PI), sink,
               &local);
    // The distant light (light VoxelCount()) as path::DistantDirections says: each unblocked
    // direction w a connection with base beta albedo / n.
    const bool distant_here = depth > 1 || first_vertex_weight > 0.0f;
    if (grid.distant && splitting.distant && splitting.distant_rays > 0 && distant_here) {
      const int n = splitting.distant_rays;
      const float weight = (depth == 1 ? first_vertex_weight : 1.0f) / static_cast<float>(n);
      rays.Reserve(static_cast<size_t>(n));
      const int m = path::DistantDirections(at.ns, at.ng, n, rng, rays.directions.data());
      std::fill_n(rays.t_max.begin(), m, std::numeric_limits<float>::infinity());
      if (m > 0) {
        local.occluded += m;
        tracer_->OccludedFrom(origin_offset, rays.directions.data(), rays.t_max.data(), m, 0.0f,
                              rays.blocked.data());
        const int light = grid.VoxelCount();
        const Eigen::Vector3f base = beta.cwiseProduct(albedo) * weight;
        int k = 0;
        for (int i = 0; i < m; ++i) {
          if (rays.blocked[i]) continue;
          rays.out_voxel[k] = light;
          rays.out_w[k] = rays.directions[i];
          rays.out_base[k] = base;
          ++k;
        }
        if (k > 0) sink({k, rays.out_voxel.data(), rays.out_w.data(), rays.out_base.data()});
      }
    }

    Eigen::Vector3f wi;
    if (!path::ContinuePath(at.ns, at.ng, albedo, depth, options, rng, &wi, &beta)) break;
    ray_o = origin_offset;
    ray_d = wi;
  }
  if (counts) {
    counts->intersect += local.intersect;
    counts->occluded += local.occluded;
  }
}

std::optional<RayHit> PathTracer::PixelCentreHit(const PosedView& view, int u, int v) const {
  const Eigen::Matrix3f rotation = view.world_from_camera.rotation().cast<float>();
  const Eigen::Vector3f eye = view.world_from_camera.translation().cast<float>();
  return tracer_->Intersect(
      eye, rotation * view.intrinsics.RayDirection(u, v).cast<float>().normalized());
}

RenderOutput PathTracer::Render(const PosedView& view, const RenderOptions& options,
                                uint64_t seed) const {
  options.Validate();
  const CameraIntrinsics& k = view.intrinsics;
  k.Validate("render view");
  RenderOutput out;
  out.radiance = ImageRgb(k.width, k.height);
  out.depth = ImageDepth(k.width, k.height);
  out.normal = ImageRgb(k.width, k.height);
  out.object = Image<int>(k.width, k.height, -1);
  const Eigen::Matrix3f rotation = view.world_from_camera.rotation().cast<float>();
  const Eigen::Vector3f eye = view.world_from_camera.translation().cast<float>();
  const bool box = options.filter == "box", gaussian = options.filter == "gaussian";
  std::vector<RayCounts> pixel_rays(static_cast<size_t>(k.width) * k.height);

  ParallelFor(
      0, static_cast<size_t>(k.width) * k.height,
      [&](size_t pixel) {
        const int u = static_cast<int>(pixel % k.width), v = static_cast<int>(pixel / k.width);
        // Geometry buffers from the pixel-centre ray.
        const Eigen::Vector3f centre_dir = k.RayDirection(u, v).cast<float>().normalized();
        if (const auto hit = Hit(eye, rotation * centre_dir)) {
          out.depth(u, v) = hit->t * centre_dir.z();
          out.normal(u, v) = hit->ns.dot(rotation * centre_dir) > 0.0f ? -hit->ns : hit->ns;
          out.object(u, v) = hit->mesh;
        }
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        int counted = 0;
        const path::PixelLattice lattice(seed, pixel);
        for (int s = 0; s < options.spp; ++s) {
          CounterRng rng(seed, pixel, static_cast<uint64_t>(s));
          // Pixel (u, v) covers [u - 0.5, u + 0.5) x [v - 0.5, v + 0.5) (DESIGN.md §1).
          // A sample's first two numbers belong to its pixel position, which the lattice gives.
          if (box) rng.UniformDouble(), rng.UniformDouble();
          double x = box ? u - 0.5 + lattice(s, 0) : u;
          double y = box ? v - 0.5 + lattice(s, 1) : v;
          if (gaussian) {
            // Like Mitsuba without sample_border, only positions inside the image contribute.
            do {
              x = u + SampleGaussianFilter(options.filter_stddev, rng);
              y = v + SampleGaussianFilter(options.filter_stddev, rng);
            } while (x < -0.5 || y < -0.5 || x >= k.width - 0.5 || y >= k.height - 0.5);
          }
          const Eigen::Vector3f dir = rotation * k.RayDirection(x, y).cast<float>().normalized();
          bool met_surface = false;
          const Eigen::Vector3f l =
              Radiance(eye, dir, options, rng, &pixel_rays[pixel], lattice(s, 2), &met_surface);
          if (options.surface_only && !met_surface) continue;
          ++counted;
          if (!l.allFinite()) {
            throw Error(Format("rendering failed at pixel (", u, ", ", v, ") sample ", s,
                               ": radiance (", l.transpose(), ") is not finite (seed ", seed, ")"));
          }
          sum += l.cast<double>();
        }
        if (counted > 0) out.radiance(u, v) = (sum / counted).cast<float>();
      },
      16);
  for (const RayCounts& r : pixel_rays) {
    out.rays.intersect += r.intersect;
    out.rays.occluded += r.occluded;
  }
  return out;
}

double RenderHalves::NoiseRms() const {
  double noise = 0.0;
  for (size_t i = 0; i < a.size(); ++i)
    noise += 0.25 * (a.data()[i] - b.data()[i]).cast<double>().squaredNorm();
  return a.size() == 0 ? 0.0 : std::sqrt(noise / (3.0 * static_cast<double>(a.size())));
}

RenderHalves RenderInHalves(const PathTracer& tracer, const PosedView& view,
                            const RenderOptions& options, uint64_t seed_a, uint64_t seed_b) {
  RenderOptions half = options;
  half.spp = std::max(1, options.spp / 2);
  RenderHalves out;
  out.a = tracer.Render(view, half, seed_a).radiance;
  out.b = tracer.Render(view, half, seed_b).radiance;
  out.mean = ImageRgb(out.a.width(), out.a.height());
  for (size_t i = 0; i < out.a.size(); ++i)
    out.mean.data()[i] = 0.5f * (out.a.data()[i] + out.b.data()[i]);
  return out;
}

}  // namespace genscene::render
