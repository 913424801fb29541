// Joint albedo and lights: the albedo update and the shading kernel on known fields, and the
// whole alternation on the Cornell box with a texture the clustering does not know.
#include "inverse/lights/joint_albedo.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <set>
#include <tuple>

#include "core/check.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "inverse/lights/light_estimation.h"
#include "render/procedural.h"

namespace genscene::inverse {
using namespace genscene::render;
namespace {

// Two triangles of a unit square in z = 0 (normal +z) and one upright (normal -y).
TriangleMesh SquareAndWall() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}};
  m.faces = {{0, 1, 2}, {0, 2, 3}, {0, 4, 5}, {0, 5, 1}};
  return m;
}

TEST(JointAlbedo, TheUpdateDividesTheObservedColourByTheShading) {
  const TriangleMesh mesh = SquareAndWall();
  MeshColors clusters(mesh, std::vector<int>(mesh.faces.size(), 4));
  const size_t n = clusters.SampleCount();
  clusters.labels().assign(n, 0);
  for (auto& c : clusters.colors()) c = Eigen::Vector3f::Constant(0.5f);
  MeshColors observed = clusters;
  std::vector<Eigen::Vector3f> truth(n), shading(n);
  for (size_t t = 0; t < n; ++t) {
    truth[t] = Eigen::Vector3f(0.2f + 0.6f * ((t % 3) == 0), 0.4f, 0.1f + 0.05f * (t % 5));
    shading[t] = Eigen::Vector3f(1.0f + 0.1f * (t % 7), 2.0f, 0.5f);
    observed.colors()[t] = truth[t].cwiseProduct(shading[t]);
  }
  JointAlbedoInputs in;
  in.observed = &observed;
  in.clusters = &clusters;
  const std::vector<uint8_t> covered(n, 1);
  size_t updated = 0;
  double scale = 0.0;
  const MeshColors exact = UpdateAlbedo(in, shading, covered, 0.0, 1.0, &updated, &scale);
  EXPECT_EQ(scale, 1.0);
  EXPECT_EQ(updated, n);
  for (size_t t = 0; t < n; ++t) EXPECT_LT((exact.colors()[t] - truth[t]).norm(), 1e-5f) << t;
  // The prior pulls each texel toward its cluster's least-squares albedo m over the observed
  // texels with shading. A texel that is not observed (its colour: the texturing's fill) takes
  // its colour over its shading as the others do, without a say in m; one without shading takes
  // m.
  in.view_counts.assign(n, 1);
  in.view_counts[3] = 0;
  std::vector<uint8_t> partly = covered;
  partly[4] = 0;
  constexpr double kPrior = 10.0;
  const MeshColors pulled = UpdateAlbedo(in, shading, partly, kPrior, 1.0);
  Eigen::Vector3d os = Eigen::Vector3d::Zero(), ss = Eigen::Vector3d::Zero();
  for (size_t t = 0; t < n; ++t) {
    if (t == 3 || t == 4) continue;
    os += observed.colors()[t].cast<double>().cwiseProduct(shading[t].cast<double>());
    ss += shading[t].cast<double>().cwiseAbs2();
  }
  const Eigen::Vector3f mean = os.cwiseQuotient(ss).cast<float>();
  const Eigen::Vector3d mean_square = ss / static_cast<double>(n - 2);
  EXPECT_LT((pulled.colors()[4] - mean).norm(), 1e-5f);
  for (int c = 0; c < 3; ++c) {
    const double o = observed.colors()[3][c], s = shading[3][c], m = kPrior * mean_square[c];
    EXPECT_NEAR(pulled.colors()[3][c], (o * s + m * mean[c]) / (s * s + m), 1e-5) << c;
  }
  EXPECT_GT((pulled.colors()[3] - mean).norm(), 1e-3f);
  double spread_exact = 0.0, spread_pulled = 0.0;
  for (size_t t = 0; t < n; ++t) {
    spread_exact += (exact.colors()[t] - mean).squaredNorm();
    spread_pulled += (pulled.colors()[t] - mean).squaredNorm();
  }
  EXPECT_LT(spread_pulled, 0.2 * spread_exact);
  // A ceiling below the data scales the whole albedo down: the 95th percentile of the largest
  // channel lands on it, ratios between texels stay.
  const MeshColors lowered = UpdateAlbedo(in, shading, covered, 0.0, 0.4, nullptr, &scale);
  EXPECT_LT(scale, 1.0);
  size_t above = 0;
  for (size_t t = 0; t < n; ++t) {
    above += lowered.colors()[t].maxCoeff() > 0.4f + 1e-6f ? 1 : 0;
    EXPECT_LT((lowered.colors()[t] - scale * truth[t]).norm(), 1e-5f) << t;
  }
  EXPECT_LE(above, n / 20 + 1);
  // Kept within [0, 1].
  observed.colors()[0] *= 10.0f;
  const MeshColors clamped = UpdateAlbedo(in, shading, covered, 0.0, 1.0);
  EXPECT_LE(clamped.colors()[0].maxCoeff(), 1.0f);
  EXPECT_GE(clamped.colors()[0].minCoeff(), 0.0f);
}

TEST(JointAlbedo, ProbesTraceTheShadingOfAPointLightOverTheObservedSurface) {
  // A 2 m square floor (normal +z) of albedo (0.6, 0.3, 0.1) and a point light 1 m above its
  // centre: nothing reflects back, so the shading is the light's irradiance over pi,
  // S = I cos / (pi d^2), whatever the albedo.
  Scene scene;
  SceneMesh floor;
  floor.mesh.vertices = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  floor.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  floor.albedo = SurfaceAlbedo::Constant({0.6f, 0.3f, 0.1f});
  scene.meshes.push_back(floor);
  const PathTracer geometry(scene);
  const MeshColors layout(floor.mesh, std::vector<int>(floor.mesh.faces.size(), 64));
  // Half the texels unobserved (x < 0): no probes there.
  const std::vector<Eigen::Vector3f> position =
      layout.InterpolateVertexAttribute(floor.mesh.vertices);
  std::vector<int32_t> views(layout.SampleCount());
  for (size_t t = 0; t < views.size(); ++t) views[t] = position[t].x() >= 0.0f ? 2 : 0;
  const double spacing = 0.1, offset = 0.005;
  const std::vector<PixelSurface> probes =
      ShadingProbes(geometry, layout, 0, views, spacing, offset);
  // The observed half is 1 m x 2 m: one probe per 10 cm cell, on a face-interior texel where the
  // cell has some.
  EXPECT_GE(probes.size(), 180u);
  EXPECT_LE(probes.size(), 231u);
  std::set<std::tuple<int, int>> cells;
  for (const PixelSurface& p : probes) {
    ASSERT_TRUE(p.hit);
    EXPECT_EQ(p.mesh, 0);
    EXPECT_GE(p.position.x(), -1e-6f);
    EXPECT_NEAR(p.position.z(), 0.0f, 1e-6f);
    EXPECT_NEAR(p.normal.z(), 1.0f, 1e-5f);
    // Inside a face, not on a vertex or an edge, where the ray would meet several faces (but in
    // the cells beyond x = 1 or y = 1, which hold only the square's border).
    if (p.position.x() < 1.0f - 1e-5f && p.position.y() < 1.0f - 1e-5f) {
      EXPECT_GT(std::min({p.b1, p.b2, 1.0f - p.b1 - p.b2}), 1e-4f) << p.position.transpose();
    }
    const auto cell = std::make_tuple(static_cast<int>(std::floor(p.position.x() / spacing)),
                                      static_cast<int>(std::floor(p.position.y() / spacing)));
    EXPECT_TRUE(cells.insert(cell).second) << "two probes in one cell";
  }
  scene.point_lights.push_back({Eigen::Vector3d(0, 0, 1), Eigen::Vector3f(2.0f, 1.0f, 0.5f)});
  const PathTracer lit(scene);
  const RenderOptions paths = RenderOptions::Paths(1);
  const std::vector<Eigen::Vector3f> shading = ProbeShading(lit, probes, offset, paths, 4, 3);
  ASSERT_EQ(shading.size(), probes.size());
  for (size_t i = 0; i < probes.size(); ++i) {
    const Eigen::Vector3f to_light = Eigen::Vector3f(0, 0, 1) - probes[i].position;
    const float d2 = to_light.squaredNorm(), cosine = to_light.z() / std::sqrt(d2);
    const Eigen::Vector3f truth =
        Eigen::Vector3f(2.0f, 1.0f, 0.5f) * (cosine / (static_cast<float>(M_PI) * d2));
    EXPECT_LT((shading[i] - truth).norm(), 1e-3f * truth.norm()) << probes[i].position.transpose();
  }
  // Same seed, same shading with one thread.
  const int threads = ThreadCount();
  SetThreadCount(1);
  const std::vector<PixelSurface> single_probes =
      ShadingProbes(geometry, layout, 0, views, spacing, offset);
  const std::vector<Eigen::Vector3f> single = ProbeShading(lit, single_probes, offset, paths, 4, 3);
  SetThreadCount(threads);
  ASSERT_EQ(single_probes.size(), probes.size());
  for (size_t i = 0; i < probes.size(); ++i) {
    EXPECT_EQ(single_probes[i].position, probes[i].position);
    EXPECT_EQ(single[i], shading[i]);
  }
  // Over an albedo below 0.02 in a channel the radiance says too little of the shading: the
  // probes get NaN and the kernel leaves them out.
  const ShadingKernel kernel(floor.mesh, layout, 0, probes, 0.2, kProbeNormalCosine);
  std::vector<uint8_t> covered;
  kernel.Shade(shading, 1, &covered);
  EXPECT_GT(std::count(covered.begin(), covered.end(), uint8_t{1}), 0);
  scene.meshes[0].albedo = SurfaceAlbedo::Constant({0.6f, 0.01f, 0.1f});
  const PathTracer dark(scene);
  const std::vector<Eigen::Vector3f> unknown = ProbeShading(dark, probes, offset, paths, 4, 3);
  for (const Eigen::Vector3f& s : unknown) EXPECT_TRUE(s.array().isNaN().all());
  const std::vector<Eigen::Vector3f> none = kernel.Shade(unknown, 1, &covered);
  EXPECT_EQ(std::count(covered.begin(), covered.end(), uint8_t{1}), 0);
  for (const Eigen::Vector3f& s : none) EXPECT_TRUE(s.allFinite());
}

// A 2 m square floor at z = 0 centred on the origin, albedo 0.5.
SceneMesh FloorOfAlbedoHalf() {
  SceneMesh floor;
  floor.mesh.vertices = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  floor.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  floor.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Constant(0.5f));
  return floor;
}

// One voxel light centred 15 cm above the origin, shining down (lobe -z), softening 2 cm.
VoxelLightGrid OneVoxelAboveTheFloor() {
  VoxelLightGrid lights;
  lights.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.05, -0.05, 0.1), Eigen::Vector3d(0.05, 0.05, 0.2));
  lights.dims = Eigen::Vector3i::Ones();
  lights.softening = 0.02;
  lights.intensity = {Eigen::Vector3f(2.0f, 1.0f, 0.5f)};
  lights.weights = {{0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f}};
  return lights;
}

TEST(JointAlbedo, TheGuidedKernelKeepsTheFalloffOfALightNearTheSurface) {
  // A 2 m floor of albedo 0.5 and one voxel light 15 cm above its centre, shining down (lobe -z):
  // nothing reflects back or shadows, so the probes' shading is the unshadowed shading G, and
  // its falloff under the light is steep against the kernel's radius.
  Scene scene;
  const SceneMesh floor = FloorOfAlbedoHalf();
  scene.meshes.push_back(floor);
  const VoxelLightGrid lights = OneVoxelAboveTheFloor();
  const PathTracer geometry(scene);
  scene.voxel_lights = lights;
  const PathTracer lit(scene);
  const MeshColors layout(floor.mesh, std::vector<int>(floor.mesh.faces.size(), 64));
  const double offset = 0.002;
  const std::vector<PixelSurface> probes = ShadingProbes(geometry, layout, 0, {}, 0.03, offset);
  ASSERT_GT(probes.size(), 1000u);
  const std::vector<Eigen::Vector3f> shading =
      ProbeShading(lit, probes, offset, RenderOptions::Paths(1), 4, 5);
  const std::vector<Eigen::Vector3f> at_probes = DirectShading(lights, scene.meshes[0], probes);
  // G by hand: I (-l . -z) cos / (pi (d^2 + e^2)), l the unit direction to the light.
  const auto by_hand = [&](const Eigen::Vector3f& p) -> Eigen::Vector3f {
    const Eigen::Vector3f to = Eigen::Vector3f(0.0f, 0.0f, 0.15f) - p;
    const float d2 = to.squaredNorm(), cosine = to.z() / std::sqrt(d2);
    return Eigen::Vector3f(2.0f, 1.0f, 0.5f) *
           (cosine * cosine / (static_cast<float>(M_PI) * (d2 + 0.02f * 0.02f)));
  };
  for (size_t i = 0; i < probes.size(); ++i) {
    const Eigen::Vector3f truth = by_hand(probes[i].position);
    EXPECT_LT((at_probes[i] - truth).norm(), 1e-4f * truth.norm())
        << probes[i].position.transpose();
    EXPECT_LT((shading[i] - truth).norm(), 1e-3f * truth.norm()) << probes[i].position.transpose();
  }
  // The texels' shading from the probes, 10 cm kernel: the plain mean is pulled up under the
  // light (the falloff is convex), the guided one follows it.
  const std::vector<PixelSurface> texels = TexelSurfaces(floor.mesh, layout, 0);
  ASSERT_EQ(texels.size(), layout.SampleCount());
  ShadingGuide guide;
  guide.samples = at_probes;
  guide.texels = DirectShading(lights, scene.meshes[0], texels);
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();
  for (const Eigen::Vector3f& v : shading) mean += v;
  guide.floor = 0.5f * mean / static_cast<float>(shading.size());
  const ShadingKernel kernel(floor.mesh, layout, 0, probes, 0.1, kProbeNormalCosine);
  std::vector<uint8_t> covered;
  const std::vector<Eigen::Vector3f> plain = kernel.Shade(shading, 4, &covered);
  const std::vector<Eigen::Vector3f> guided = kernel.Shade(shading, 4, &covered, &guide);
  double plain_worst = 0.0, guided_worst = 0.0;
  int checked = 0;
  for (size_t t = 0; t < texels.size(); ++t) {
    const Eigen::Vector3f& p = texels[t].position;
    if (!covered[t] || p.head<2>().norm() > 0.5f) continue;
    const Eigen::Vector3f truth = by_hand(p);
    EXPECT_LT((guide.texels[t] - truth).norm(), 1e-4f * truth.norm());
    plain_worst = std::max(plain_worst, double((plain[t] - truth).norm() / truth.norm()));
    guided_worst = std::max(guided_worst, double((guided[t] - truth).norm() / truth.norm()));
    ++checked;
  }
  std::cout << "shading within 0.5 m of the light's foot, worst relative error: plain kernel "
            << plain_worst << ", guided " << guided_worst << " (" << checked << " texels)\n";
  EXPECT_GT(checked, 500);
  EXPECT_GT(plain_worst, 0.1);  // the plain mean's bias under the light (0.17 here)
  EXPECT_LT(guided_worst, 0.03);
  EXPECT_LT(guided_worst, 0.2 * plain_worst);
}

TEST(JointAlbedo, TheDirectShadingHasTheShadowOfAnOccluder) {
  // The floor and light above; a 10 cm square 5 cm above the floor at x = 0.3 casts its shadow
  // onto x in [0.375, 0.525], |y| < 0.075 (the light's centre, 15 cm up, seen past the square).
  Scene scene;
  const SceneMesh floor = FloorOfAlbedoHalf();
  scene.meshes.push_back(floor);
  SceneMesh square;
  square.mesh.vertices = {
      {0.25f, -0.05f, 0.05f}, {0.35f, -0.05f, 0.05f}, {0.35f, 0.05f, 0.05f}, {0.25f, 0.05f, 0.05f}};
  square.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  square.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Constant(0.5f));
  scene.meshes.push_back(square);
  const VoxelLightGrid lights = OneVoxelAboveTheFloor();
  const PathTracer geometry(scene);
  const MeshColors layout(floor.mesh, std::vector<int>(floor.mesh.faces.size(), 256));
  const std::vector<PixelSurface> texels = TexelSurfaces(floor.mesh, layout, 0);
  const std::vector<Eigen::Vector3f> open = DirectShading(lights, scene.meshes[0], texels);
  const std::vector<Eigen::Vector3f> shadowed =
      DirectShading(lights, scene.meshes[0], texels, &geometry.tracer());
  ASSERT_EQ(shadowed.size(), texels.size());
  int in_shadow = 0, in_light = 0;
  for (size_t t = 0; t < texels.size(); ++t) {
    const Eigen::Vector3f& p = texels[t].position;
    ASSERT_GT(open[t].minCoeff(), 0.0f) << p.transpose();
    if (p.x() > 0.39f && p.x() < 0.51f && std::abs(p.y()) < 0.06f) {
      EXPECT_EQ(shadowed[t], Eigen::Vector3f::Zero()) << p.transpose();
      ++in_shadow;
    } else if (p.x() < 0.36f || p.x() > 0.54f || std::abs(p.y()) > 0.09f) {
      EXPECT_EQ(shadowed[t], open[t]) << p.transpose();
      ++in_light;
    }
  }
  EXPECT_GT(in_shadow, 100);
  EXPECT_GT(in_light, 1000);

  // A second voxel 10 cm over, at 1e-4 of the first's intensity: under the 1e-3 cutoff its
  // visibility is not traced, so the first voxel's shadow keeps exactly its unshadowed term.
  VoxelLightGrid two = lights;
  two.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.05, -0.05, 0.1), Eigen::Vector3d(0.15, 0.05, 0.2));
  two.dims = Eigen::Vector3i(2, 1, 1);
  two.intensity = {Eigen::Vector3f(2.0f, 1.0f, 0.5f), Eigen::Vector3f(2e-4f, 1e-4f, 5e-5f)};
  two.weights = {lights.weights[0], lights.weights[0]};
  VoxelLightGrid weak_only = two;
  weak_only.intensity[0].setZero();
  const std::vector<Eigen::Vector3f> weak = DirectShading(weak_only, scene.meshes[0], texels);
  const std::vector<Eigen::Vector3f> both =
      DirectShading(two, scene.meshes[0], texels, &geometry.tracer());
  for (size_t t = 0; t < texels.size(); ++t) {
    const Eigen::Vector3f& p = texels[t].position;
    if (!(p.x() > 0.39f && p.x() < 0.51f && std::abs(p.y()) < 0.06f)) continue;
    ASSERT_GT(weak[t].minCoeff(), 0.0f);
    EXPECT_LT((both[t] - weak[t]).norm(), 1e-6f * weak[t].norm()) << p.transpose();
  }

  // 25 voxels of one intensity (more shadow rays per point than one packet of 16), nothing in
  // between: every texel's shading is the unshadowed sum.
  Scene open_floor;
  open_floor.meshes.push_back(floor);
  const PathTracer floor_only(open_floor);
  VoxelLightGrid many = lights;
  many.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.25, -0.25, 0.1), Eigen::Vector3d(0.25, 0.25, 0.2));
  many.dims = Eigen::Vector3i(5, 5, 1);
  many.intensity.assign(25, Eigen::Vector3f(2.0f, 1.0f, 0.5f));
  many.weights.assign(25, lights.weights[0]);
  const std::vector<Eigen::Vector3f> free_sum = DirectShading(many, open_floor.meshes[0], texels);
  const std::vector<Eigen::Vector3f> traced =
      DirectShading(many, open_floor.meshes[0], texels, &floor_only.tracer());
  for (size_t t = 0; t < texels.size(); ++t) {
    ASSERT_GT(free_sum[t].minCoeff(), 0.0f);
    EXPECT_LT((traced[t] - free_sum[t]).norm(), 1e-5f * free_sum[t].norm())
        << texels[t].position.transpose();
  }
  // With the square back, those 25 voxels are shadowed in part: less light, never more.
  const std::vector<Eigen::Vector3f> partly =
      DirectShading(many, scene.meshes[0], texels, &geometry.tracer());
  int darker = 0;
  for (size_t t = 0; t < texels.size(); ++t) {
    EXPECT_TRUE((partly[t].array() <= free_sum[t].array() * (1.0f + 1e-5f)).all());
    if (partly[t].x() < 0.99f * free_sum[t].x()) ++darker;
  }
  EXPECT_GT(darker, 100);
}

TEST(JointAlbedo, TheShadingKernelAveragesNearbyPixelsOfTheSameOrientation) {
  const TriangleMesh mesh = SquareAndWall();
  const MeshColors layout(mesh, std::vector<int>(mesh.faces.size(), 8));
  // Pixels on the square with shading 1 + x; pixels on the wall with shading 100.
  std::vector<PixelSurface> pixels;
  std::vector<Eigen::Vector3f> shading;
  CounterRng rng(7, 0);
  for (int i = 0; i < 4000; ++i) {
    PixelSurface p;
    p.hit = true;
    p.mesh = 0;
    const bool wall = i % 4 == 0;
    const float u = static_cast<float>(rng.Uniform()), v = static_cast<float>(rng.Uniform());
    p.position = wall ? Eigen::Vector3f(u, 0.0f, v) : Eigen::Vector3f(u, v, 0.0f);
    p.normal = wall ? Eigen::Vector3f(0, 1, 0) : Eigen::Vector3f(0, 0, 1);
    pixels.push_back(p);
    shading.push_back(Eigen::Vector3f::Constant(wall ? 100.0f : 1.0f + u));
  }
  std::vector<uint8_t> covered;
  const std::vector<Eigen::Vector3f> texel =
      TexelShading(mesh, layout, 0, pixels, shading, 0.1, 1, &covered);
  const std::vector<Eigen::Vector3f> position = layout.InterpolateVertexAttribute(mesh.vertices);
  int checked = 0;
  for (size_t t = 0; t < layout.SampleCount(); ++t) {
    const Eigen::Vector3f& p = position[t];
    // Inside the square, away from the wall and the borders: the linear field, unbiased.
    if (p.z() == 0.0f && p.x() > 0.15f && p.x() < 0.85f && p.y() > 0.15f && p.y() < 0.85f) {
      ASSERT_TRUE(covered[t]);
      EXPECT_NEAR(texel[t].x(), 1.0f + p.x(), 0.03f) << p.transpose();
      ++checked;
    }
    if (p.z() > 0.15f && p.x() > 0.15f && p.x() < 0.85f) {  // on the wall: the wall's pixels
      ASSERT_TRUE(covered[t]);
      EXPECT_NEAR(texel[t].x(), 100.0f, 1e-3f);
    }
  }
  EXPECT_GT(checked, 20);
  // Sparse noisy pixels: a kernel that must hold 16 pixels widens and averages the noise out.
  std::vector<PixelSurface> sparse;
  std::vector<Eigen::Vector3f> noisy;
  for (size_t i = 1; i < pixels.size() && sparse.size() < 200; i += 4) {
    sparse.push_back(pixels[i]);  // on the square
    noisy.push_back(Eigen::Vector3f::Constant(2.0f * static_cast<float>(rng.Uniform())));
  }
  const auto Spread = [&](int min_pixels) {
    std::vector<uint8_t> reached;
    const std::vector<Eigen::Vector3f> s =
        TexelShading(mesh, layout, 0, sparse, noisy, 0.05, min_pixels, &reached);
    double sum = 0.0, sq = 0.0;
    int m = 0;
    for (size_t t = 0; t < s.size(); ++t) {
      if (!reached[t] || position[t].z() != 0.0f) continue;
      sum += s[t].x();
      sq += s[t].x() * s[t].x();
      ++m;
    }
    EXPECT_GT(m, 20);
    return std::sqrt(std::max(0.0, sq / m - (sum / m) * (sum / m)));
  };
  const double narrow = Spread(1), wide = Spread(16);
  std::cout << "texel shading spread: 1 pixel " << narrow << ", 16 pixels " << wide << "\n";
  EXPECT_LT(wide, 0.5 * narrow);
  // No pixel within the radius: not covered.
  std::vector<PixelSurface> far = pixels;
  for (PixelSurface& p : far) p.position += Eigen::Vector3f(5, 5, 5);
  TexelShading(mesh, layout, 0, far, shading, 0.1, 1, &covered);
  for (uint8_t c : covered) EXPECT_EQ(c, 0);
}

// The Cornell box's mesh with a Mesh Colors albedo: each face's colour, and on the back wall
// (y = 1) stripes 0.25 m wide at half the colour.
struct TexturedBox {
  Scene scene = WithoutLights(MakeCornellBoxScene());
  MeshColors truth, flat;
  int dark_texels = 0;
  TexturedBox() {
    const SceneMesh& m = scene.meshes[0];
    std::vector<int> resolution;  // 16 on the walls and the box, 2 on the sphere
    for (size_t f = 0; f < m.mesh.faces.size(); ++f)
      resolution.push_back(m.mesh.FaceNormalScaled(f).norm() > 0.1f ? 16 : 2);
    truth = MeshColors(m.mesh, resolution);
    const std::vector<Eigen::Vector3f> position = truth.InterpolateVertexAttribute(m.mesh.vertices);
    flat = truth;
    flat.labels().assign(truth.SampleCount(), 0);

    for (size_t t = 0; t < truth.SampleCount(); ++t) {
      int face = 0;
      double b1 = 0.0, b2 = 0.0;
      truth.SampleFacePoint(t, &face, &b1, &b2);
      const Eigen::Vector3f base = m.albedo.Eval(m.mesh, face, 0.3f, 0.3f);
      flat.colors()[t] = base;
      const bool dark = position[t].y() > 0.99f &&
                        static_cast<int>(std::floor(position[t].x() / 0.25f + 8.0f)) % 2 == 0;
      truth.colors()[t] = dark ? 0.5f * base : base;
      if (dark) ++dark_texels;
      flat.labels()[t] = base.x() > 2.0f * base.y() ? 1 : (base.y() > 2.0f * base.x() ? 2 : 0);
    }
  }
  // Scene with `albedo` on the box and the light grid of `lights`.
  Scene With(const MeshColors& albedo, const VoxelLightGrid* lights = nullptr) const {
    Scene s = scene;
    s.meshes[0].albedo = SurfaceAlbedo::FromMeshColors(albedo);
    if (lights) s.voxel_lights = *lights;
    return s;
  }
};

// Relative RMS error of the back wall's texels against the truth, after one global scale.
double BackWallError(const TexturedBox& box, const MeshColors& albedo) {
  const std::vector<Eigen::Vector3f> position =
      box.truth.InterpolateVertexAttribute(box.scene.meshes[0].mesh.vertices);
  double at = 0.0, aa = 0.0, tt = 0.0;
  for (size_t t = 0; t < position.size(); ++t) {
    if (!(position[t].y() > 0.99f && std::abs(position[t].x()) < 0.9f && position[t].z() > 0.1f &&
          position[t].z() < 1.9f))
      continue;
    at += albedo.colors()[t].cast<double>().dot(box.truth.colors()[t].cast<double>());
    aa += albedo.colors()[t].cast<double>().squaredNorm();
    tt += box.truth.colors()[t].cast<double>().squaredNorm();
  }
  GS_CHECK(tt > 0.0);
  const double s = at / aa;  // the global scale that fits best
  return std::sqrt(std::max(0.0, (s * s * aa - 2.0 * s * at + tt) / tt));
}

TEST(JointAlbedo, TheAlternationReturnsTextureDetailToTheAlbedo) {
  const TexturedBox box;
  ASSERT_GT(box.dark_texels, 100);
  VoxelLightGrid lights = MakeVoxelGrid(box.scene, 3, 0.5);
  lights.intensity[22] = Eigen::Vector3f(2.0f, 1.5f, 1.0f);  // top layer, centre
  lights.weights[22] = {0.2f, 0.2f, 0.2f, 0.2f, 0.0f, 1.0f};
  const Scene lit = box.With(box.truth, &lights);
  const PathTracer tracer(lit);
  // Training views of the textured box.
  RenderOptions ro;
  ro.spp = 64;
  std::vector<PosedImage> views;
  const std::vector<PosedView> all = CornellLightViews(32, 24);
  for (size_t i = 0; i < 3; ++i)
    views.push_back({all[i], tracer.Render(all[i], ro, 100 + i).radiance});
  // The observed colour of every texel: its outgoing radiance along the normal (Lambertian).
  MeshColors observed = box.flat;
  const SceneMesh& m = lit.meshes[0];
  TriangleMesh normals = m.mesh;
  normals.ComputeVertexNormals();
  const std::vector<Eigen::Vector3f> position =
      observed.InterpolateVertexAttribute(m.mesh.vertices);
  const std::vector<Eigen::Vector3f> normal = observed.InterpolateVertexAttribute(normals.normals);
  RenderOptions one;
  one.spp = 1;
  for (size_t t = 0; t < observed.SampleCount(); ++t) {
    const Eigen::Vector3f n = normal[t].normalized();
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (int k = 0; k < 128; ++k) {
      CounterRng rng(5, t, static_cast<uint64_t>(k));
      sum += tracer.Radiance(position[t] + 0.01f * n, -n, one, rng);
    }
    observed.colors()[t] = sum / 128.0f;
  }
  LightEstimationOptions o;
  o.grid = 3;
  o.boundary_inset = 0.5;
  o.pixels_per_view = 600;
  o.refine_levels = 0;
  o.albedo_radius = 0.05;
  JointAlbedoInputs joint;
  joint.observed = &observed;
  joint.clusters = &box.flat;
  const LightEstimate e = EstimateLights(box.With(box.flat), views, o, 9, &joint);
  ASSERT_TRUE(e.albedo.has_value());
  ASSERT_FALSE(e.albedo_steps.empty());
  EXPECT_TRUE(e.albedo_steps.front().kept);
  double previous = e.rounds.back().solve.cost;
  for (const JointAlbedoStep& s : e.albedo_steps) {
    if (!s.kept) break;
    EXPECT_LT(s.cost, previous);
    previous = s.cost;
  }
  const double before = BackWallError(box, box.flat), after = BackWallError(box, *e.albedo);
  std::cout << "back wall albedo error: clusters " << before << ", joint " << after << "\n";
  EXPECT_LT(after, 0.65 * before);  // measured: 0.309 -> 0.190
  // Same seed, same albedo with one thread.
  const int threads = ThreadCount();
  SetThreadCount(1);
  const LightEstimate single = EstimateLights(box.With(box.flat), views, o, 9, &joint);
  SetThreadCount(threads);
  ASSERT_TRUE(single.albedo.has_value());
  EXPECT_EQ(single.albedo->colors(), e.albedo->colors());
  EXPECT_EQ(single.albedo_steps.size(), e.albedo_steps.size());
  // Without joint inputs nothing changes.
  const LightEstimate plain = EstimateLights(box.With(box.flat), views, o, 9);
  EXPECT_FALSE(plain.albedo.has_value());
  EXPECT_TRUE(plain.albedo_steps.empty());
}

}  // namespace
}  // namespace genscene::inverse
