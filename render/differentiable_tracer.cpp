#include "render/differentiable_tracer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/check.h"
#include "render/light_sampler.h"
#include "render/light_visibility.h"
#include "render/path_continuation.h"

namespace genscene::render {

namespace {

constexpr double kPi = M_PI;

using path::OffsetScale;
using path::PowerHeuristic;
using path::SampleCosine;

// radiance += rgb (*) scalar, the only way radiance grows: every term is a constant colour times a
// function of the geometry.
void AddTo(DualRgb* radiance, const Eigen::Vector3d& rgb, const SparseDual& scalar) {
  for (int c = 0; c < 3; ++c) {
    if (rgb[c] != 0.0) (*radiance)[c] += rgb[c] * scalar;
  }
}

// Area-weighted vertex normals (the paper's section IV): n_v = normalize(sum over the faces of v
// of (e1 x e2)), whose length is twice the face area. `vertex(i)` gives vertex i (seeded or not).
template <typename VertexFn>
std::vector<DualVec3> AreaWeightedNormals(const TriangleMesh& mesh, const VertexFn& vertex) {
  std::vector<DualVec3> sum(mesh.vertices.size(), DualVec3(Eigen::Vector3d::Zero()));
  for (const Eigen::Vector3i& f : mesh.faces) {
    const DualVec3 v0 = vertex(f[0]);
    const DualVec3 scaled = Cross(vertex(f[1]) - v0, vertex(f[2]) - v0);
    for (int i = 0; i < 3; ++i) sum[f[i]] = sum[f[i]] + scaled;
  }
  for (DualVec3& n : sum) {
    if (n.value().squaredNorm() > 0.0) n = Normalized(n);
  }
  return sum;
}

}  // namespace

struct DifferentiablePathTracer::Hit {
  DualVec3 p;
  DualVec3 ng;  // unit geometric normal of the counter-clockwise face (not flipped)
  DualVec3 ns;  // unit shading normal, same side as ng
  double area = 0.0;
  int mesh = -1, face = -1;
  double b1 = 0.0, b2 = 0.0;  // barycentric values (for the albedo)
};

DifferentiablePathTracer::DifferentiablePathTracer(const Scene& scene,
                                                   const std::vector<bool>& refined)
    : scene_(scene), tracer_(std::make_unique<RayTracer>()) {
  scene_.Validate();
  GS_CHECK_EQ(refined.size(), scene_.meshes.size());
  first_vertex_.assign(scene_.meshes.size(), -1);
  positions_.resize(scene_.meshes.size());
  normals_.resize(scene_.meshes.size());
  dual_normals_.resize(scene_.meshes.size());
  for (size_t m = 0; m < scene_.meshes.size(); ++m) {
    const SceneMesh& mesh = scene_.meshes[m];
    const bool parameters = refined[m] && !mesh.IsEmitter();
    if (parameters) {
      first_vertex_[m] = vertex_count_;
      vertex_count_ += static_cast<int>(mesh.mesh.vertices.size());
    }
    for (const Eigen::Vector3f& v : mesh.mesh.vertices) positions_[m].push_back(v.cast<double>());
    if (mesh.smooth_shading && !parameters) {
      for (const Eigen::Vector3f& n : mesh.mesh.normals) normals_[m].push_back(n.cast<double>());
    }
    tracer_->AddMesh(mesh.mesh, parameters);
  }
  tracer_->Commit();
  lights_ = std::make_unique<LightSampler>(scene_);
  has_area_lights_ = lights_->HasTriangles();
  UpdateNormals(true);
}

DifferentiablePathTracer::~DifferentiablePathTracer() = default;

int DifferentiablePathTracer::ParameterVertex(int mesh, int v) const {
  return first_vertex_[mesh] < 0 ? -1 : first_vertex_[mesh] + v;
}

Eigen::VectorXd DifferentiablePathTracer::Positions() const {
  Eigen::VectorXd x(3 * vertex_count_);
  for (size_t m = 0; m < positions_.size(); ++m) {
    if (first_vertex_[m] < 0) continue;
    for (size_t v = 0; v < positions_[m].size(); ++v)
      x.segment<3>(3 * (first_vertex_[m] + v)) = positions_[m][v];
  }
  return x;
}

void DifferentiablePathTracer::SetPositions(const Eigen::VectorXd& x, bool derivatives) {
  GS_CHECK_EQ(x.size(), 3 * vertex_count_);
  if (!x.allFinite()) throw Error("vertex refinement: a vertex position is not finite");
  for (size_t m = 0; m < positions_.size(); ++m) {
    if (first_vertex_[m] < 0) continue;
    std::vector<Eigen::Vector3f>& vertices = scene_.meshes[m].mesh.vertices;
    for (size_t v = 0; v < positions_[m].size(); ++v) {
      positions_[m][v] = x.segment<3>(3 * (first_vertex_[m] + v));
      vertices[v] = positions_[m][v].cast<float>();
    }
    tracer_->UpdateVertices(static_cast<int>(m), vertices);
  }
  UpdateNormals(derivatives);
}

void DifferentiablePathTracer::UpdateNormals(bool derivatives) {
  normal_derivatives_ = derivatives;
  for (size_t m = 0; m < scene_.meshes.size(); ++m) {
    SceneMesh& mesh = scene_.meshes[m];
    if (first_vertex_[m] < 0 || !mesh.smooth_shading) continue;
    const int mi = static_cast<int>(m);
    const std::vector<DualVec3> normals =
        AreaWeightedNormals(mesh.mesh, [&](int v) { return Vertex(mi, v, derivatives); });
    normals_[m].clear();
    mesh.mesh.normals.clear();
    for (const DualVec3& n : normals) {
      normals_[m].push_back(n.value());
      mesh.mesh.normals.push_back(n.value().cast<float>());
    }
    if (derivatives) dual_normals_[m] = normals;
  }
}

DualVec3 DifferentiablePathTracer::Vertex(int mesh, int v, bool derivatives) const {
  const Eigen::Vector3d& p = positions_[mesh][v];
  return derivatives && first_vertex_[mesh] >= 0 ? DualVec3::Variable(p, first_vertex_[mesh] + v)
                                                 : DualVec3(p);
}

std::optional<DifferentiablePathTracer::Hit> DifferentiablePathTracer::Intersect(
    const DualVec3& origin, const DualVec3& direction, bool derivatives) const {
  const auto found =
      tracer_->Intersect(origin.value().cast<float>(), direction.value().cast<float>());
  if (!found) return std::nullopt;
  const SceneMesh& m = scene_.meshes[found->mesh];
  const Eigen::Vector3i& f = m.mesh.faces[found->face];
  const DualVec3 v0 = Vertex(found->mesh, f[0], derivatives);
  const DualVec3 v1 = Vertex(found->mesh, f[1], derivatives);
  const DualVec3 v2 = Vertex(found->mesh, f[2], derivatives);
  Hit h;
  h.mesh = found->mesh;
  h.face = found->face;

  // Moller-Trumbore: the barycentrics of the ray's crossing of the triangle's plane, as functions
  // of the ray and the vertices (Embree only decides which triangle).
  const DualVec3 e1 = v1 - v0, e2 = v2 - v0;
  const DualVec3 pvec = Cross(direction, e2);
  const SparseDual det = Dot(e1, pvec);
  SparseDual b1(found->b1), b2(found->b2);
  const double scale = e1.value().norm() * e2.value().norm() * direction.value().norm();
  if (std::abs(det.value()) > 1e-12 * scale) {
    const SparseDual inv = 1.0 / det;
    const DualVec3 tvec = origin - v0;
    b1 = Dot(tvec, pvec) * inv;
    b2 = Dot(direction, Cross(tvec, e1)) * inv;
  }
  h.b1 = b1.value();
  h.b2 = b2.value();
  const SparseDual b0 = 1.0 - b1 - b2;
  h.p = b0 * v0 + b1 * v1 + b2 * v2;

  const DualVec3 scaled_normal = Cross(e1, e2);
  h.area = 0.5 * scaled_normal.value().norm();
  h.ng = h.area > 0.0 ? Normalized(scaled_normal)
                      : DualVec3(Eigen::Vector3d(-direction.value().normalized()));
  h.ns = h.ng;
  if (m.smooth_shading) {
    const bool dual = derivatives && first_vertex_[found->mesh] >= 0;
    const auto normal = [&](int i) {
      return dual ? dual_normals_[found->mesh][f[i]] : DualVec3(normals_[found->mesh][f[i]]);
    };
    const DualVec3 interpolated = b0 * normal(0) + b1 * normal(1) + b2 * normal(2);
    if (interpolated.value().squaredNorm() > 0.0) h.ns = Normalized(interpolated);
    if (h.ns.value().dot(h.ng.value()) < 0.0) h.ns = -h.ns;
  }
  return h;
}

SparseDual DifferentiablePathTracer::EmitterWeight(const Hit& hit, const Hit& previous,
                                                   const SparseDual& bsdf_pdf) const {
  const float pmf = lights_->TrianglePmf(hit.mesh, hit.face);
  if (pmf <= 0.0f) return SparseDual(1.0);
  const DualVec3 d = hit.p - previous.p;
  const SparseDual d2 = SquaredNorm(d);
  const SparseDual cos_light = abs(Dot(hit.ng, d)) / sqrt(d2);
  const SparseDual light_pdf = pmf * d2 / (hit.area * cos_light);
  return PowerHeuristic(bsdf_pdf, light_pdf);
}

void DifferentiablePathTracer::NextEvent(const Hit& at, const DualVec3& origin_offset,
                                         const Eigen::Vector3d& beta_albedo, CounterRng& rng,
                                         DualRgb* radiance, RayCounts* counts,
                                         const LightChoice& choice, double choice_u) const {
  if (lights_->empty()) return;
  // The random numbers are drawn as PathTracer::Radiance draws them for one light sample. The
  // choice's probabilities are taken at the hit's value and held constant: the estimator f / pmf
  // of the chosen light is differentiated through f only, whose expectation over the choice is
  // the derivative of the sum over the lights.
  const double drawn = rng.UniformDouble();
  const double u = choice_u >= 0.0 ? choice_u : drawn;
  if (!choice.by_contribution) {
    const size_t i = lights_->Choose(u);
    Light(at, origin_offset, beta_albedo, i, lights_->pmf(i), rng, radiance, counts);
    return;
  }
  const Eigen::Vector3f p = at.p.value().cast<float>(), n = at.ns.value().cast<float>();
  const float* seen = choice.visibility ? choice.visibility->At(p) : nullptr;
  thread_local std::vector<double> scratch;
  if (choice.exact > 0) {
    thread_local std::vector<size_t> exact;
    LightSampler::Choice rest;
    lights_->SplitAt(p, n, choice.exact, u, &scratch, &exact, &rest, seen);
    for (size_t e : exact) Light(at, origin_offset, beta_albedo, e, 1.0f, rng, radiance, counts);
    if (rest.pmf > 0.0f)
      Light(at, origin_offset, beta_albedo, rest.entry, rest.pmf, rng, radiance, counts);
    return;
  }
  const LightSampler::Choice c = lights_->ChooseAt(p, n, u, &scratch, seen);
  Light(at, origin_offset, beta_albedo, c.entry, c.pmf, rng, radiance, counts);
}

void DifferentiablePathTracer::Light(const Hit& at, const DualVec3& origin_offset,
                                     const Eigen::Vector3d& beta_albedo, size_t i, float pmf,
                                     CounterRng& rng, DualRgb* radiance, RayCounts* counts) const {
  const LightSampler::Entry& e = lights_->entry(i);
  const float u1 = rng.Uniform(), u2 = rng.Uniform();
  Eigen::Vector3d light_point = Eigen::Vector3d::Zero(), rgb = Eigen::Vector3d::Zero();
  switch (e.kind) {
    case LightSampler::Kind::kTriangle: {
      const SceneMesh& m = scene_.meshes[e.mesh];
      light_point = UniformPointOnTriangle(m.mesh, e.index, u1, u2).cast<double>();
      rgb = m.emission.cast<double>();
      break;
    }
    case LightSampler::Kind::kPoint:
      light_point = scene_.point_lights[e.index].position;
      rgb = scene_.point_lights[e.index].intensity.cast<double>();
      break;
    case LightSampler::Kind::kVoxel:
      light_point = scene_.voxel_lights->VoxelCenter(e.index);
      rgb = scene_.voxel_lights->intensity[e.index].cast<double>();
      break;
  }
  const DualVec3 to_light = light_point - at.p;
  const SparseDual d2 = SquaredNorm(to_light);
  if (d2.value() <= 0.0) return;
  const SparseDual distance = sqrt(d2);
  const DualVec3 wi = (1.0 / distance) * to_light;
  // The light's factor: value = rgb * factor / pdf.
  SparseDual factor(1.0), pdf(pmf);
  if (e.kind == LightSampler::Kind::kTriangle) {
    const Eigen::Vector3d n_light =
        scene_.meshes[e.mesh].mesh.FaceNormalScaled(e.index).normalized().cast<double>();
    const SparseDual cos_light = -Dot(wi, n_light);
    if (cos_light.value() <= 0.0) return;  // one-sided: the light faces away
    pdf = pmf * d2 / (e.area * cos_light);
  } else if (e.kind == LightSampler::Kind::kPoint) {
    factor = 1.0 / d2;
  } else {
    // I(w) = L sum_k lambda_k max(0, w . d_k), w = -wi from the voxel to the surface.
    const auto& lambda = scene_.voxel_lights->weights[e.index];
    SparseDual sum(0.0);
    for (int axis = 0; axis < 3; ++axis) {
      const SparseDual w = -wi[axis];
      if (w.value() > 0.0) sum += lambda[2 * axis] * w;
      if (w.value() < 0.0) sum -= lambda[2 * axis + 1] * w;
    }
    factor = sum / (d2 + scene_.voxel_lights->softening * scene_.voxel_lights->softening);
  }
  const SparseDual cos_s = Dot(at.ns, wi);
  if (cos_s.value() <= 0.0 || at.ng.value().dot(wi.value()) <= 0.0) return;
  ++counts->occluded;
  if (tracer_->SegmentOccluded(origin_offset.value().cast<float>(), light_point.cast<float>())) {
    return;
  }
  const bool delta = e.kind != LightSampler::Kind::kTriangle;
  const SparseDual weight = delta ? SparseDual(1.0) : PowerHeuristic(pdf, cos_s / kPi);
  AddTo(radiance, beta_albedo.cwiseProduct(rgb), cos_s / kPi * factor * weight / pdf);
}

void DifferentiablePathTracer::DistantLight(const Hit& at, const DualVec3& origin_offset,
                                            const Eigen::Vector3d& beta_albedo, CounterRng& rng,
                                            DualRgb* radiance, RayCounts* counts) const {
  const VoxelLightGrid* grid = scene_.voxel_lights ? &*scene_.voxel_lights : nullptr;
  if (!grid || !grid->HasDistantLight()) return;
  // As PathTracer::Radiance: the lattice's directions about the shading normal, each visible
  // one adding E(w) = L_d sum_k lambda_dk max(0, w . d_k), differentiated through w.
  const int rays = path::kDistantRays;
  DualVec3 directions[path::kDistantRays];
  const int m = path::DistantDirections(at.ns, at.ng, rays, rng, directions);
  const auto& lambda = grid->distant_weights;
  SparseDual sum(0.0);
  for (int i = 0; i < m; ++i) {
    const DualVec3& w = directions[i];
    ++counts->occluded;
    if (tracer_->Occluded(origin_offset.value().cast<float>(), w.value().cast<float>(), 0.0f,
                          std::numeric_limits<float>::infinity()))
      continue;
    for (int axis = 0; axis < 3; ++axis) {
      const SparseDual& c = w[axis];
      if (c.value() > 0.0) sum += lambda[2 * axis] * c;
      if (c.value() < 0.0) sum -= lambda[2 * axis + 1] * c;
    }
  }
  AddTo(radiance, beta_albedo.cwiseProduct(grid->distant_intensity.cast<double>()),
        sum * (1.0 / rays));
}

DualRgb DifferentiablePathTracer::Radiance(const Eigen::Vector3d& origin,
                                           const Eigen::Vector3d& direction,
                                           const RenderOptions& options, CounterRng& rng,
                                           bool derivatives, RayCounts* counts,
                                           double first_light_u) const {
  if (derivatives && !normal_derivatives_) {
    throw Error("DifferentiablePathTracer: derivatives asked after SetPositions without them");
  }
  RayCounts local;
  DualRgb radiance;
  Eigen::Vector3d beta = Eigen::Vector3d::Ones();  // throughput: albedo products, geometry-free
  DualVec3 ray_o(origin), ray_d(Eigen::Vector3d(direction.normalized()));
  SparseDual bsdf_pdf;
  std::optional<Hit> previous;
  LightChoice choice;
  choice.by_contribution = options.light_selection == "contribution";
  choice.visibility = choice.by_contribution && options.light_visibility
                          ? visibility_.Get(scene_, *tracer_, *lights_)
                          : nullptr;

  for (int depth = 1;; ++depth) {
    ++local.intersect;
    auto hit = Intersect(ray_o, ray_d, derivatives);
    if (!hit) break;
    const SceneMesh& mesh = scene_.meshes[hit->mesh];

    // Emission seen along the ray (one-sided emitters), MIS-weighted after a BSDF sample.
    if (mesh.IsEmitter() && hit->ng.value().dot(ray_d.value()) < 0.0) {
      const Eigen::Vector3d emission = mesh.emission.cast<double>();
      if (depth == 1) {
        if (!options.hide_emitters) AddTo(&radiance, emission, SparseDual(1.0));
      } else {
        AddTo(&radiance, beta.cwiseProduct(emission), EmitterWeight(*hit, *previous, bsdf_pdf));
      }
    }
    if (!path::DepthAllowed(options, depth + 1)) break;
    const Eigen::Vector3d albedo =
        mesh.albedo
            .Eval(mesh.mesh, hit->face, static_cast<float>(hit->b1), static_cast<float>(hit->b2))
            .cast<double>();
    if (albedo.maxCoeff() <= 0.0) break;

    // Lambertian surfaces reflect on both sides: orient the normals towards the incoming ray.
    Hit at = std::move(*hit);
    if (at.ng.value().dot(ray_d.value()) > 0.0) at.ng = -at.ng, at.ns = -at.ns;
    const DualVec3 origin_offset = at.p + OffsetScale(at.p.value()) * at.ng;
    // As PathTracer::Radiance: by contribution the first vertex takes the strongest lights
    // exactly (without area lights).
    choice.exact = depth == 1 && choice.by_contribution && !has_area_lights_
                       ? std::max(options.exact_lights, 0)
                       : 0;
    NextEvent(at, origin_offset, beta.cwiseProduct(albedo), rng, &radiance, &local, choice,
              depth == 1 ? first_light_u : -1.0);
    DistantLight(at, origin_offset, beta.cwiseProduct(albedo), rng, &radiance, &local);

    DualVec3 wi;
    if (!path::ContinuePath(at.ns, at.ng, albedo, depth, options, rng, &wi, &beta)) break;
    bsdf_pdf = Dot(at.ns, wi) / kPi;
    previous = std::move(at);
    ray_o = origin_offset;
    ray_d = std::move(wi);
  }
  if (counts) {
    counts->intersect += local.intersect;
    counts->occluded += local.occluded;
  }
  return radiance;
}

DualRgb DifferentiablePathTracer::Pixel(const PosedView& view, int u, int v,
                                        const RenderOptions& options, uint64_t seed,
                                        bool derivatives, RayCounts* counts) const {
  const CameraIntrinsics& k = view.intrinsics;
  const Eigen::Matrix3d rotation = view.world_from_camera.rotation();
  const Eigen::Vector3d eye = view.world_from_camera.translation();
  const size_t pixel = static_cast<size_t>(v) * k.width + u;
  const bool box = options.filter == "box";
  if (options.filter == "gaussian")
    throw Error("vertex refinement: the gaussian pixel filter is not supported (box or center)");
  DualRgb sum;
  const path::PixelLattice lattice(seed, pixel);
  for (int s = 0; s < options.spp; ++s) {
    CounterRng rng(seed, pixel, static_cast<uint64_t>(s));
    // As PathTracer::Render: a sample's first two numbers belong to its pixel position.
    if (box) rng.UniformDouble(), rng.UniformDouble();
    const double x = box ? u - 0.5 + lattice(s, 0) : u;
    const double y = box ? v - 0.5 + lattice(s, 1) : v;
    // As PathTracer::Render: the direction is normalised in float there, here in double.
    const Eigen::Vector3d dir = rotation * k.RayDirection(x, y).normalized();
    const DualRgb l = Radiance(eye, dir, options, rng, derivatives, counts, lattice(s, 2));
    for (int c = 0; c < 3; ++c) sum[c] += l[c];
  }
  for (SparseDual& c : sum) c *= 1.0 / options.spp;
  return sum;
}

}  // namespace genscene::render
