// Vertex refinement's differentiable path tracer: the sparse dual number against closed
// forms, and the path tracer's derivatives against central finite differences, sample by sample,
// for direct and one-bounce light from point, area and voxel lights, flat and smooth shading.
#include "render/differentiable_tracer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "core/mesh_colors.h"
#include "core/synthetic.h"
#include "render/light_sampler.h"
#include "render/path_tracer.h"
#include "tests/test_util.h"

namespace genscene::render {
namespace {

TEST(SparseDual, ArithmeticMatchesTheClosedFormDerivatives) {
  // f(a, b) = sqrt(a b) / (a + 2) - b^2 with a = x of vertex 3, b = z of vertex 1.
  const double a0 = 1.7, b0 = 0.6;
  const SparseDual a = SparseDual::Variable(a0, 3, 0), b = SparseDual::Variable(b0, 1, 2);
  const SparseDual f = sqrt(a * b) / (a + 2.0) - b * b;
  const double s = std::sqrt(a0 * b0);
  EXPECT_NEAR(f.value(), s / (a0 + 2.0) - b0 * b0, 1e-15);
  EXPECT_NEAR(f.Derivative(3, 0), 0.5 * b0 / s / (a0 + 2.0) - s / ((a0 + 2.0) * (a0 + 2.0)), 1e-14);
  EXPECT_NEAR(f.Derivative(1, 2), 0.5 * a0 / s / (a0 + 2.0) - 2.0 * b0, 1e-14);
  EXPECT_EQ(f.Derivative(1, 0), 0.0);
  ASSERT_EQ(f.partials().size(), 2u);
  EXPECT_EQ(f.partials()[0].vertex, 1);  // sorted by vertex
  EXPECT_EQ(f.partials()[1].vertex, 3);
}

TEST(SparseDual, NormalizedCrossProductMatchesFiniteDifferences) {
  const Eigen::Vector3d p0(0.1, 0.2, 0.3), p1(1.0, 0.1, -0.2), p2(0.3, 1.1, 0.4);
  const auto normal = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                          const Eigen::Vector3d& c) {
    return Eigen::Vector3d((b - a).cross(c - a).normalized());
  };
  const DualVec3 v0 = DualVec3::Variable(p0, 0), v1 = DualVec3::Variable(p1, 1),
                 v2 = DualVec3::Variable(p2, 2);
  const DualVec3 n = Normalized(Cross(v1 - v0, v2 - v0));
  const double h = 1e-6;
  for (int vertex = 0; vertex < 3; ++vertex) {
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Vector3d q[2][3] = {{p0, p1, p2}, {p0, p1, p2}};
      q[0][vertex][axis] += h;
      q[1][vertex][axis] -= h;
      const Eigen::Vector3d fd =
          (normal(q[0][0], q[0][1], q[0][2]) - normal(q[1][0], q[1][1], q[1][2])) / (2 * h);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(n[c].Derivative(vertex, axis), fd[c], 1e-8);
    }
  }
}

// A refined icosphere (radius 0.2, level 1) above a floor, one of three kinds of light.
// kSoftVoxel: the voxel lights with a softening of 0.25 m (VoxelLightGrid::Falloff). kDistant:
// only the voxel grid's distant light (a sky brightest from above), seen by the paths that leave.
enum class LightKind { kPoint, kArea, kVoxel, kSoftVoxel, kDistant };

Scene SphereOnFloor(LightKind light, bool smooth) {
  Scene scene;
  SceneMesh floor;
  floor.name = "floor";
  floor.mesh.vertices = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  floor.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  floor.albedo = SurfaceAlbedo::Constant({0.7f, 0.6f, 0.5f});
  scene.meshes.push_back(floor);

  SceneMesh sphere;
  sphere.name = "sphere";
  const UnitIcosphere unit = MakeUnitIcosphere(1);
  for (const Eigen::Vector3d& v : unit.vertices)
    sphere.mesh.vertices.push_back((0.2 * v + Eigen::Vector3d(0, 0, 0.25)).cast<float>());
  sphere.mesh.faces = unit.faces;
  sphere.mesh.ComputeVertexNormals();
  sphere.smooth_shading = smooth;
  sphere.albedo = SurfaceAlbedo::Constant({0.8f, 0.8f, 0.8f});
  scene.meshes.push_back(sphere);

  switch (light) {
    case LightKind::kPoint:
      scene.point_lights.push_back(
          {Eigen::Vector3d(0.4, -0.5, 0.9), Eigen::Vector3f(2.0f, 1.8f, 1.5f)});
      break;
    case LightKind::kArea: {
      SceneMesh panel;
      panel.name = "panel";
      panel.mesh.vertices = {
          {-0.2f, -0.4f, 1.0f}, {0.3f, -0.4f, 1.0f}, {0.3f, 0.1f, 1.0f}, {-0.2f, 0.1f, 1.0f}};
      panel.mesh.faces = {{0, 2, 1}, {0, 3, 2}};  // front faces down
      panel.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Zero());
      panel.emission = Eigen::Vector3f(12.0f, 10.0f, 8.0f);
      scene.meshes.push_back(panel);
      break;
    }
    case LightKind::kVoxel:
    case LightKind::kSoftVoxel: {
      VoxelLightGrid grid;
      grid.bounds =
          Eigen::AlignedBox3d(Eigen::Vector3d(-0.9, -0.9, 0.6), Eigen::Vector3d(0.9, 0.9, 1.2));
      grid.dims = Eigen::Vector3i(3, 3, 2);
      grid.intensity.assign(grid.VoxelCount(), Eigen::Vector3f::Zero());
      grid.weights.assign(grid.VoxelCount(), {0, 0, 0, 0, 0, 0});
      grid.intensity[3] = Eigen::Vector3f(1.5f, 1.2f, 1.0f);
      grid.weights[3] = {0.3f, 0.1f, 0.5f, 0.2f, 0.1f, 1.0f};
      grid.intensity[14] = Eigen::Vector3f(0.5f, 0.5f, 0.8f);
      grid.weights[14] = {1, 1, 1, 1, 1, 1};
      if (light == LightKind::kSoftVoxel) grid.softening = 0.25;
      scene.voxel_lights = grid;
      break;
    }
    case LightKind::kDistant: {
      VoxelLightGrid grid;
      grid.bounds =
          Eigen::AlignedBox3d(Eigen::Vector3d(-0.9, -0.9, 0.6), Eigen::Vector3d(0.9, 0.9, 1.2));
      grid.dims = Eigen::Vector3i(1, 1, 1);
      grid.intensity.assign(1, Eigen::Vector3f::Zero());
      grid.weights.assign(1, {1, 1, 1, 1, 1, 1});
      grid.distant = true;
      grid.distant_intensity = Eigen::Vector3f(1.2f, 1.0f, 0.8f);
      grid.distant_weights = {0.3f, 0.1f, 0.2f, 0.1f, 1.0f, 0.0f};
      scene.voxel_lights = grid;
      break;
    }
  }
  return scene;
}

// Close enough that the sphere and its shadow fill most of the view.
PosedView SphereView(int width, int height) {
  return {CameraIntrinsics::FromHorizontalFov(width, height, 40.0),
          LookAt({0.25, -0.8, 0.6}, {0.0, 0.0, 0.2})};
}

struct GradientCheck {
  int samples = 0;         // samples with derivatives
  int skipped = 0;         // of those, near a visibility change (finite differences disagree)
  double max_error = 0.0;  // max over samples of max_i |ad_i - fd_i| / max_i |fd_i|
};

// Compares, sample by sample, the AD derivatives of pixel radiance with central differences of
// the same estimator (same random numbers) for every coordinate of every refined vertex the sample
// depends on, and for a few it does not depend on. A sample whose differences at steps h and h/2
// disagree sits on a visibility change (a ray switches triangles): it is counted as skipped.
// Mesh 1 of `scene` is refined.
GradientCheck CheckGradients(const Scene& scene, const RenderOptions& options,
                             const PosedView& view) {
  std::vector<bool> refined(scene.meshes.size(), false);
  refined[1] = true;
  DifferentiablePathTracer tracer(scene, refined);
  const int width = view.intrinsics.width, height = view.intrinsics.height;
  const Eigen::VectorXd x0 = tracer.Positions();
  const Eigen::Matrix3d rotation = view.world_from_camera.rotation();
  const Eigen::Vector3d eye = view.world_from_camera.translation();
  GradientCheck check;
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const uint64_t stream = static_cast<uint64_t>(v) * width + u;
      const Eigen::Vector3d dir = rotation * view.intrinsics.RayDirection(u, v).normalized();
      const auto eval = [&](bool derivatives) {
        CounterRng rng(7, stream);
        return tracer.Radiance(eye, dir, options, rng, derivatives);
      };
      tracer.SetPositions(x0, true);
      const DualRgb ad = eval(true);
      const DualRgb value_only = eval(false);
      std::map<int, int> vertices;  // involved vertex -> 1
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(ad[c].value(), value_only[c].value())
            << "derivatives change the value at " << u << "," << v;
        for (const SparseDual::Partial& p : ad[c].partials()) vertices[p.vertex] = 1;
      }
      if (vertices.empty()) continue;
      // Plus three vertices the sample should not depend on (zero derivative expected).
      for (int extra : {0, tracer.VertexCount() / 2, tracer.VertexCount() - 1})
        vertices.emplace(extra, 0);
      const auto difference = [&](int vertex, int axis, double h) {
        Eigen::VectorXd x = x0;
        x[3 * vertex + axis] = x0[3 * vertex + axis] + h;
        tracer.SetPositions(x, false);
        const DualRgb plus = eval(false);
        x[3 * vertex + axis] = x0[3 * vertex + axis] - h;
        tracer.SetPositions(x, false);
        const DualRgb minus = eval(false);
        tracer.SetPositions(x0, false);
        Eigen::Vector3d d;
        for (int c = 0; c < 3; ++c) d[c] = (plus[c].value() - minus[c].value()) / (2 * h);
        return d;
      };
      double scale = 0.0, worst = 0.0;
      bool edge = false;
      std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pairs;
      for (const auto& [vertex, involved] : vertices) {
        for (int axis = 0; axis < 3; ++axis) {
          const double h = 1e-6;
          const Eigen::Vector3d fd = difference(vertex, axis, h),
                                fd_half = difference(vertex, axis, h / 2);
          if ((fd - fd_half).cwiseAbs().maxCoeff() > 1e-4 * (1.0 + fd.cwiseAbs().maxCoeff()))
            edge = true;
          const Eigen::Vector3d derivative(ad[0].Derivative(vertex, axis),
                                           ad[1].Derivative(vertex, axis),
                                           ad[2].Derivative(vertex, axis));
          pairs.push_back({derivative, fd});
          scale = std::max(scale, fd.cwiseAbs().maxCoeff());
        }
      }
      // Derivatives below 1e-5 of the value per metre are round-off in the differences, not signal.
      const double value =
          std::max({std::abs(ad[0].value()), std::abs(ad[1].value()), std::abs(ad[2].value())});
      scale = std::max(scale, 1e-5 * value);
      ++check.samples;
      if (edge) {
        ++check.skipped;
        continue;
      }
      for (const auto& [derivative, fd] : pairs)
        worst = std::max(worst, (derivative - fd).cwiseAbs().maxCoeff());
      if (scale > 0.0) check.max_error = std::max(check.max_error, worst / scale);
      if (scale > 0.0 && worst / scale > 1e-3) {
        ADD_FAILURE() << "sample at pixel (" << u << ", " << v << "): derivatives off by "
                      << worst / scale << " of the largest; value " << ad[0].value();
        int k = 0;
        for (const auto& [vertex, involved] : vertices) {
          for (int axis = 0; axis < 3; ++axis, ++k) {
            if ((pairs[k].first - pairs[k].second).cwiseAbs().maxCoeff() > 1e-3 * scale) {
              ADD_FAILURE() << "  vertex " << vertex << " axis " << axis << ": AD "
                            << pairs[k].first.transpose() << ", differences "
                            << pairs[k].second.transpose();
            }
          }
        }
      }
    }
  }
  return check;
}

struct Case {
  LightKind light;
  bool smooth;
  int max_depth;  // 2: direct light, 3: one bounce
};

class DifferentiableTracerGradient : public ::testing::TestWithParam<Case> {};

TEST_P(DifferentiableTracerGradient, MatchesCentralDifferencesAwayFromVisibilityEdges) {
  const Case c = GetParam();
  RenderOptions options;
  options.max_depth = c.max_depth;
  options.rr_depth = 100;
  // By power the light choice does not depend on the vertices, so that each sample's estimate is
  // a smooth function of them (by contribution only the expectation is: the test below).
  options.light_selection = "power";
  const GradientCheck check =
      CheckGradients(SphereOnFloor(c.light, c.smooth), options, SphereView(16, 12));
  // The view is filled with sphere and floor: most samples carry derivatives, few sit on edges.
  std::printf(
      "%d samples with derivatives, %d skipped at visibility edges, max relative error %.2e\n",
      check.samples, check.skipped, check.max_error);
  EXPECT_GT(check.samples, 30);
  EXPECT_LT(check.skipped, check.samples / 10);
  EXPECT_LE(check.max_error, 1e-3) << check.samples << " samples, " << check.skipped << " skipped";
}

// By contribution the light choice follows the hit, and its probabilities are held constant in
// the derivatives: sample by sample the derivatives differ from those by power, but both are
// unbiased estimates of the same derivative of the image. Here the derivative of the sum of the
// pixels of a sphere on a floor under two voxel lights, with one bounce, as the sphere rises
// (every vertex's z): over 12288 samples the two means agree within four standard errors.
TEST(DifferentiableTracer, DerivativesByContributionAgreeWithThoseByPowerInExpectation) {
  const Scene scene = SphereOnFloor(LightKind::kSoftVoxel, true);
  std::vector<bool> refined(scene.meshes.size(), false);
  refined[1] = true;
  const DifferentiablePathTracer tracer(scene, refined);
  const PosedView view = SphereView(8, 6);
  RenderOptions options;
  options.spp = 256;
  options.max_depth = 3;
  options.rr_depth = 100;
  double mean[2], error[2], value[2];
  for (int mode = 0; mode < 2; ++mode) {
    options.light_selection = mode == 0 ? "power" : "contribution";
    double sum = 0.0, sum2 = 0.0, values = 0.0;
    int n = 0;
    for (int v = 0; v < 6; ++v) {
      for (int u = 0; u < 8; ++u) {
        const Eigen::Matrix3d rotation = view.world_from_camera.rotation();
        const Eigen::Vector3d dir = rotation * view.intrinsics.RayDirection(u, v).normalized();
        for (int s = 0; s < options.spp; ++s) {
          CounterRng rng(3, static_cast<uint64_t>(v * 8 + u), static_cast<uint64_t>(s));
          const DualRgb l =
              tracer.Radiance(view.world_from_camera.translation(), dir, options, rng, true);
          double g = 0.0;
          for (int c = 0; c < 3; ++c) {
            values += l[c].value();
            for (const SparseDual::Partial& p : l[c].partials()) g += p.d.z();
          }
          sum += g;
          sum2 += g * g;
          ++n;
        }
      }
    }
    mean[mode] = sum / n;
    error[mode] = std::sqrt(std::max(0.0, sum2 / n - mean[mode] * mean[mode]) / n);
    value[mode] = values / n;
  }
  std::printf(
      "d(image)/d(sphere z) per sample: by power %.5f +- %.5f, by contribution %.5f +- %.5f; "
      "radiance %.5f and %.5f\n",
      mean[0], error[0], mean[1], error[1], value[0], value[1]);
  EXPECT_GT(std::abs(mean[0]), 4.0 * error[0]) << "the derivative is not zero";
  EXPECT_NEAR(mean[1], mean[0], 4.0 * std::hypot(error[0], error[1]));
}

std::string CaseName(const ::testing::TestParamInfo<Case>& info) {
  static const char* const kLight[] = {"Point", "Area", "Voxel", "SoftVoxel", "Distant"};
  return std::string(kLight[static_cast<int>(info.param.light)]) +
         (info.param.smooth ? "Smooth" : "Flat") +
         (info.param.max_depth == 2 ? "Direct" : "OneBounce");
}

INSTANTIATE_TEST_SUITE_P(
    Lights, DifferentiableTracerGradient,
    ::testing::Values(Case{LightKind::kPoint, false, 2}, Case{LightKind::kPoint, true, 2},
                      Case{LightKind::kPoint, true, 3}, Case{LightKind::kArea, false, 2},
                      Case{LightKind::kArea, true, 2}, Case{LightKind::kArea, true, 3},
                      Case{LightKind::kVoxel, false, 2}, Case{LightKind::kVoxel, true, 3},
                      Case{LightKind::kSoftVoxel, true, 2}, Case{LightKind::kSoftVoxel, true, 3},
                      Case{LightKind::kDistant, true, 2}, Case{LightKind::kDistant, true, 3}),
    CaseName);

// Hard cases: a smooth fan of `n` triangles around a raised centre vertex
// (valence n) on the floor, lit by a point light; the fan is refined.
Scene Fan(int n, double height, const Eigen::Vector3d& light) {
  Scene scene = SphereOnFloor(LightKind::kPoint, true);
  scene.point_lights[0].position = light;
  SceneMesh& fan = scene.meshes[1];
  fan.name = "fan";
  fan.mesh = TriangleMesh();
  fan.mesh.vertices.push_back(Eigen::Vector3f(0.0f, 0.0f, static_cast<float>(height)));
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * (i + 0.3) / n;
    fan.mesh.vertices.push_back(
        Eigen::Vector3d(0.3 * std::cos(a), 0.3 * std::sin(a), 0.02).cast<float>());
  }
  for (int i = 0; i < n; ++i) fan.mesh.faces.push_back({0, 1 + i, 1 + (i + 1) % n});
  fan.mesh.ComputeVertexNormals();
  return scene;
}

PosedView FanView(int width, int height) {
  return {CameraIntrinsics::FromHorizontalFov(width, height, 45.0),
          LookAt({0.2, -0.7, 0.6}, {0.0, 0.0, 0.05})};
}

void ExpectGradientsMatch(const Scene& scene, const PosedView& view, int max_depth = 3) {
  RenderOptions options;
  options.max_depth = max_depth;
  options.rr_depth = 100;
  const GradientCheck check = CheckGradients(scene, options, view);
  std::printf(
      "%d samples with derivatives, %d skipped at visibility edges, max relative error %.2e\n",
      check.samples, check.skipped, check.max_error);
  EXPECT_GT(check.samples, 30);
  EXPECT_LT(check.skipped, check.samples / 5);
  EXPECT_LE(check.max_error, 1e-3);
}

TEST(DifferentiableTracerHardCases, VertexOfValenceThree) {
  ExpectGradientsMatch(Fan(3, 0.15, {0.3, -0.3, 0.8}), FanView(16, 12));
}

TEST(DifferentiableTracerHardCases, VertexOfValenceTwelve) {
  ExpectGradientsMatch(Fan(12, 0.15, {0.3, -0.3, 0.8}), FanView(16, 12));
}

TEST(DifferentiableTracerHardCases, ZeroAreaFaceInTheOneRing) {
  Scene scene = Fan(6, 0.15, {0.3, -0.3, 0.8});
  TriangleMesh& mesh = scene.meshes[1].mesh;
  mesh.vertices[3] = mesh.vertices[2];  // face (0, 2, 3) has no area; it stays in the centre's ring
  mesh.ComputeVertexNormals();
  ASSERT_EQ(mesh.FaceNormalScaled(1).norm(), 0.0f);
  ExpectGradientsMatch(scene, FanView(16, 12));
}

TEST(DifferentiableTracerHardCases, GrazingAngleHits) {
  // The fan almost flat (2 cm rise over 30 cm, slopes of 4 degrees) seen from 1 degree above the
  // floor: the rays meet the near slopes 5 degrees off their plane.
  const Scene scene = Fan(8, 0.04, {0.0, 0.3, 0.5});
  const PosedView view{CameraIntrinsics::FromHorizontalFov(16, 12, 12.0),
                       LookAt({0.0, -0.9, 0.045}, {0.0, 0.0, 0.03})};
  ExpectGradientsMatch(scene, view, 2);
}

TEST(DifferentiableTracerHardCases, LightVeryCloseToTheSurface) {
  // A point light 5 mm above the fan's centre vertex: 1 / r^2 varies by orders of magnitude.
  ExpectGradientsMatch(Fan(6, 0.15, {0.0, 0.0, 0.155}), FanView(16, 12), 2);
}

// With an area light (lights by power) and with voxel lights (by contribution, the strongest taken
// exactly at the first vertex, weighed by their visibility).
TEST(DifferentiableTracer, PixelsMatchThePathTracersRenderWithTheSameSeed) {
  for (const LightKind light : {LightKind::kArea, LightKind::kSoftVoxel}) {
    const Scene scene = SphereOnFloor(light, true);
    const PosedView view = SphereView(20, 15);
    RenderOptions options;
    options.spp = 4;
    options.exact_lights = 1;  // of the two voxel lights, one exact and one sampled
    const RenderOutput render = PathTracer(scene).Render(view, options, 5);
    const DifferentiablePathTracer tracer(scene, std::vector<bool>(scene.meshes.size(), false));
    double diff = 0.0, total = 0.0;
    for (int v = 0; v < 15; ++v) {
      for (int u = 0; u < 20; ++u) {
        const DualRgb p = tracer.Pixel(view, u, v, options, 5, false);
        for (int c = 0; c < 3; ++c) {
          diff += std::abs(p[c].value() - render.radiance(u, v)[c]);
          total += render.radiance(u, v)[c];
        }
      }
    }
    // Same random numbers, same paths: only float against double arithmetic differs (and the
    // rare path that float round-off sends elsewhere).
    EXPECT_GT(total, 0.0);
    EXPECT_LT(diff / total, 1e-2) << static_cast<int>(light);
  }
}

// The albedo lookups both tracers make, for any barycentrics a hit can carry: a per-vertex albedo
// and a Mesh Colors field stay within the values of the face they were asked for (a convex
// combination of its samples), finite, for points on edges, a few ulps outside, NaN and infinite.
struct MeshColorsField : AlbedoField {
  const MeshColors* colors;
  explicit MeshColorsField(const MeshColors* c) : colors(c) {}
  Eigen::Vector3f Eval(int face, float b1, float b2) const override {
    return colors->Linear(face, b1, b2);
  }
};

TEST(AlbedoLookupProperty, StaysWithinTheFaceValuesForAnyBarycentrics) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  mesh.faces = {{0, 1, 2}, {1, 3, 2}};
  for (int v = 0; v < 4; ++v) mesh.vertex_colors.push_back({unit(rng), unit(rng), unit(rng)});
  const SurfaceAlbedo per_vertex = SurfaceAlbedo::FromMesh(mesh, Eigen::Vector3f::Constant(0.5f));
  ASSERT_EQ(per_vertex.kind, SurfaceAlbedo::Kind::kPerVertex);
  for (int resolution : {1, 2, 4, 8, 16, 64}) {
    MeshColors colors(mesh, {resolution, std::max(1, resolution / 2)});
    for (auto& c : colors.colors()) c = {unit(rng), unit(rng), unit(rng)};
    SurfaceAlbedo field;
    field.kind = SurfaceAlbedo::Kind::kField;
    field.field = std::make_shared<MeshColorsField>(&colors);
    for (int face = 0; face < 2; ++face) {
      // The range of the face's own values: its vertices' colours, its Mesh Colors samples.
      Eigen::Vector3f lo_v = Eigen::Vector3f::Constant(1.0f), hi_v = Eigen::Vector3f::Zero();
      for (int k = 0; k < 3; ++k) {
        lo_v = lo_v.cwiseMin(mesh.vertex_colors[mesh.faces[face][k]]);
        hi_v = hi_v.cwiseMax(mesh.vertex_colors[mesh.faces[face][k]]);
      }
      const int r = face == 0 ? resolution : std::max(1, resolution / 2);
      Eigen::Vector3f lo_f = Eigen::Vector3f::Constant(1.0f), hi_f = Eigen::Vector3f::Zero();
      for (int i = 0; i <= r; ++i) {
        for (int j = 0; i + j <= r; ++j) {
          lo_f = lo_f.cwiseMin(colors.colors()[colors.SampleIndex(face, i, j)]);
          hi_f = hi_f.cwiseMax(colors.colors()[colors.SampleIndex(face, i, j)]);
        }
      }
      size_t outside = 0, checked = 0;
      for (const auto& [b1, b2] : test::HardBarycentrics(rng, 2000, 2000)) {
        const Eigen::Vector3f a = per_vertex.Eval(mesh, face, b1, b2),
                              m = field.Eval(mesh, face, b1, b2);
        ++checked;
        const bool in = a.allFinite() && m.allFinite() && (a - lo_v).minCoeff() >= -1e-6f &&
                        (hi_v - a).minCoeff() >= -1e-6f && (m - lo_f).minCoeff() >= -1e-6f &&
                        (hi_f - m).minCoeff() >= -1e-6f;
        if (!in && outside++ < 3)
          ADD_FAILURE() << "face " << face << " R " << r << " b " << b1 << " " << b2
                        << ": per-vertex " << a.transpose() << ", Mesh Colors " << m.transpose();
      }
      EXPECT_EQ(outside, 0u) << "of " << checked;
    }
  }
}

// An area light's sample point, for random numbers anywhere in [0, 1] (0, 1 and the floats next
// to them included), lies on the light's face.
TEST(AlbedoLookupProperty, AreaLightSamplesLieOnTheFace) {
  TriangleMesh mesh;
  mesh.vertices = {{0.1f, 0.2f, 1.0f}, {0.9f, 0.25f, 1.1f}, {0.3f, 0.8f, 0.9f}};
  mesh.faces = {{0, 1, 2}};
  const Eigen::Vector3f e1 = mesh.vertices[1] - mesh.vertices[0],
                        e2 = mesh.vertices[2] - mesh.vertices[0];
  const Eigen::Vector3f n = e1.cross(e2);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<float> values = {0.0f, 1.0f, std::nextafter(1.0f, 0.0f), std::nextafter(0.0f, 1.0f),
                               0.5f};
  for (int k = 0; k < 200; ++k) values.push_back(unit(rng));
  for (float u1 : values) {
    for (float u2 : values) {
      const Eigen::Vector3f p = UniformPointOnTriangle(mesh, 0, u1, u2);
      ASSERT_TRUE(p.allFinite()) << u1 << " " << u2;
      // Barycentrics of p (it lies in the plane): each >= 0, summing to 1.
      const Eigen::Vector3f d = p - mesh.vertices[0];
      const float b1 = d.cross(e2).dot(n) / n.squaredNorm(),
                  b2 = e1.cross(d).dot(n) / n.squaredNorm();
      EXPECT_NEAR(d.dot(n) / n.norm(), 0.0f, 1e-6f);
      EXPECT_GE(b1, -1e-6f) << u1 << " " << u2;
      EXPECT_GE(b2, -1e-6f) << u1 << " " << u2;
      EXPECT_LE(b1 + b2, 1.0f + 1e-6f) << u1 << " " << u2;
    }
  }
}

// Both tracers over a Mesh Colors albedo at every resolution, with rays grazing an almost flat
// fan (hits on and near the shared edges of its eight faces): no error, finite values and
// derivatives, and the two tracers agree pixel by pixel as they do on plain albedos.
TEST(AlbedoLookupProperty, BothTracersReadMeshColorsAtGrazingHits) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(0.05f, 0.95f);
  for (int resolution : {1, 2, 4, 8}) {
    Scene scene = Fan(8, 0.04, {0.0, 0.3, 0.5});
    TriangleMesh& fan = scene.meshes[1].mesh;
    std::vector<int> resolutions;
    for (size_t f = 0; f < fan.faces.size(); ++f)
      resolutions.push_back(f % 2 ? resolution : std::max(1, resolution / 2));
    auto colors = std::make_shared<MeshColors>(fan, resolutions);
    for (auto& c : colors->colors()) c = {unit(rng), unit(rng), unit(rng)};
    scene.meshes[1].albedo.kind = SurfaceAlbedo::Kind::kField;
    scene.meshes[1].albedo.field = std::make_shared<MeshColorsField>(colors.get());
    const PosedView view{CameraIntrinsics::FromHorizontalFov(24, 18, 12.0),
                         LookAt({0.0, -0.9, 0.045}, {0.0, 0.0, 0.03})};
    RenderOptions options;
    options.spp = 2;
    options.max_depth = 3;
    const RenderOutput render = PathTracer(scene).Render(view, options, 9);
    const DifferentiablePathTracer tracer(scene, {false, true});
    double diff = 0.0, total = 0.0;
    for (int v = 0; v < view.intrinsics.height; ++v) {
      for (int u = 0; u < view.intrinsics.width; ++u) {
        const DualRgb p = tracer.Pixel(view, u, v, options, 9, true);
        for (int c = 0; c < 3; ++c) {
          ASSERT_TRUE(std::isfinite(p[c].value())) << u << " " << v;
          for (const auto& partial : p[c].partials()) {
            ASSERT_TRUE(partial.d.allFinite()) << u << " " << v;
          }
          ASSERT_TRUE(std::isfinite(render.radiance(u, v)[c])) << u << " " << v;
          diff += std::abs(p[c].value() - render.radiance(u, v)[c]);
          total += render.radiance(u, v)[c];
        }
      }
    }
    EXPECT_GT(total, 0.0);
    EXPECT_LT(diff / total, 1e-2) << "resolution " << resolution;
  }
}

}  // namespace
}  // namespace genscene::render
