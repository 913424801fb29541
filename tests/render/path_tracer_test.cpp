// The path tracer against closed forms (DESIGN.md §4): a point light and a voxel light over a
// Lambertian plane (exact, no noise), a small area light (form factor), a white furnace, the
// 1/sqrt(spp) convergence, the voxel-light cube export, and determinism across thread counts.
#include "render/path_tracer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "core/parallel.h"
#include "core/rng.h"
#include "core/synthetic.h"
#include "render/light_sampler.h"
#include "render/light_visibility.h"
#include "render/ray_tracer.h"

namespace genscene::render {
namespace {

// A square in the plane z = height, side `side`, centred on the z axis, facing +z or -z.
SceneMesh Square(double side, double height, bool facing_up, const Eigen::Vector3f& albedo,
                 const Eigen::Vector3f& emission = Eigen::Vector3f::Zero()) {
  SceneMesh m;
  const float h = static_cast<float>(side / 2), z = static_cast<float>(height);
  m.mesh.vertices = {{-h, -h, z}, {h, -h, z}, {h, h, z}, {-h, h, z}};
  if (facing_up) {
    m.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  } else {
    m.mesh.faces = {{0, 2, 1}, {0, 3, 2}};
  }
  m.albedo = SurfaceAlbedo::Constant(albedo);
  m.emission = emission;
  return m;
}

PosedView LookingDownAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, int width,
                        int height, double f) {
  PosedView view;
  view.intrinsics.width = width;
  view.intrinsics.height = height;
  view.intrinsics.fx = view.intrinsics.fy = f;
  view.intrinsics.cx = 0.5 * (width - 1);
  view.intrinsics.cy = 0.5 * (height - 1);
  view.world_from_camera = LookAt(eye, target);
  return view;
}

// World point seen at pixel (u, v) of a render, from its depth buffer.
Eigen::Vector3d PointAt(const PosedView& view, const RenderOutput& out, int u, int v) {
  return view.world_from_camera * view.intrinsics.Unproject(u, v, out.depth(u, v));
}

TEST(PathTracer, PointLightOverPlaneIsExact) {
  const Eigen::Vector3f albedo(0.5f, 0.7f, 0.2f), intensity(2.0f, 3.0f, 4.0f);
  Scene scene;
  scene.meshes.push_back(Square(40.0, 0.0, true, albedo));
  scene.point_lights.push_back({Eigen::Vector3d(0.2, 0.1, 1.0), intensity});
  const PathTracer tracer(scene);
  const PosedView view = LookingDownAt({0.5, -0.8, 2.0}, {0.0, 0.0, 0.0}, 24, 18, 20.0);
  RenderOptions options;
  options.filter = "center";
  options.spp = 1;
  options.max_depth = 2;  // direct illumination only
  const RenderOutput out = tracer.Render(view, options, 1);
  for (int v = 0; v < 18; ++v) {
    for (int u = 0; u < 24; ++u) {
      ASSERT_GT(out.depth(u, v), 0.0f);
      const Eigen::Vector3d p = PointAt(view, out, u, v);
      const Eigen::Vector3d to_light = scene.point_lights[0].position - p;
      const double r2 = to_light.squaredNorm(), cos_theta = to_light.z() / std::sqrt(r2);
      // L = rho / pi * I cos(theta) / r^2
      const Eigen::Vector3d expected = albedo.cast<double>() / M_PI * cos_theta / r2;
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(out.radiance(u, v)[c], expected[c] * intensity[c],
                    1e-4 * expected[c] * intensity[c])
            << u << "," << v;
      }
    }
  }
}

// A square against empty space, seen from above: the pixels along its outline are partly
// covered. The box filter averages in the empty part (black); surface_only averages only the
// samples that meet the square, so an outline pixel has the colour of the square's inside.
TEST(PathTracer, SurfaceOnlyAveragesTheCoveredPartOfAPixel) {
  Scene scene;
  scene.meshes.push_back(Square(0.96, 0.0, true, Eigen::Vector3f(0.6f, 0.6f, 0.6f)));
  scene.point_lights.push_back({Eigen::Vector3d(0.0, 0.0, 20.0), Eigen::Vector3f(400, 400, 400)});
  const PathTracer tracer(scene);
  // 0.1 m per pixel on the plane: the square's edges at +-0.48 m cut pixels at 80 % or 30 %.
  const PosedView view = LookingDownAt({0.0, 0.0, 2.0}, {0.0, 0.0, 0.0}, 20, 20, 20.0);
  RenderOptions options;
  options.spp = 64;
  options.max_depth = 2;
  const RenderOutput box = tracer.Render(view, options, 3);
  options.surface_only = true;
  const RenderOutput covered = tracer.Render(view, options, 3);
  const float inside = covered.radiance(10, 10).x();
  ASSERT_GT(inside, 0.0f);
  int outline = 0;
  for (int v = 0; v < 20; ++v) {
    for (int u = 0; u < 20; ++u) {
      const bool centre_hits = box.depth(u, v) > 0.0f;
      const bool on_outline = u == 5 || u == 14 || v == 5 || v == 14;
      if (!centre_hits) {
        // Pixels whose centre misses may still be partly covered (the 30 % ones); never brighter.
        EXPECT_LE(covered.radiance(u, v).x(), 1.02f * inside) << u << "," << v;
        continue;
      }
      EXPECT_NEAR(covered.radiance(u, v).x(), inside, 0.02f * inside) << u << "," << v;
      if (on_outline) {
        ++outline;
        EXPECT_LT(box.radiance(u, v).x(), 0.9f * inside) << u << "," << v;
      } else {
        EXPECT_NEAR(box.radiance(u, v).x(), covered.radiance(u, v).x(), 1e-4f * inside);
      }
    }
  }
  EXPECT_EQ(outline, 36);  // the ring of pixels 5..14 around the square's inside
  EXPECT_EQ(covered.radiance(0, 0).x(), 0.0f);
}

// Direct light of one voxel over a plane against the emission model, as a point (softening 0)
// and softened: E = I(w) cos / (r^2 + e^2).
TEST(PathTracer, VoxelLightOverPlaneFollowsEmissionModel) {
  for (const double softening : {0.0, 0.4}) {
    const Eigen::Vector3f albedo(0.6f, 0.6f, 0.6f);
    Scene scene;
    scene.meshes.push_back(Square(40.0, 0.0, true, albedo));
    VoxelLightGrid grid;
    grid.dims = Eigen::Vector3i(1, 1, 1);
    grid.bounds =
        Eigen::AlignedBox3d(Eigen::Vector3d(-0.1, -0.1, 0.9), Eigen::Vector3d(0.1, 0.1, 1.1));
    grid.intensity = {Eigen::Vector3f(1.0f, 2.0f, 3.0f)};
    grid.weights = {{0.1f, 0.9f, 0.3f, 0.0f, 0.2f, 1.0f}};
    grid.softening = softening;
    scene.voxel_lights = grid;
    const PathTracer tracer(scene);
    const PosedView view = LookingDownAt({0.3, -1.0, 2.5}, {0.0, 0.0, 0.0}, 20, 16, 12.0);
    RenderOptions options;
    options.filter = "center";
    options.spp = 1;
    options.max_depth = 2;
    const RenderOutput out = tracer.Render(view, options, 3);
    const Eigen::Vector3d c(0.0, 0.0, 1.0);
    for (int v = 0; v < 16; ++v) {
      for (int u = 0; u < 20; ++u) {
        const Eigen::Vector3d p = PointAt(view, out, u, v);
        const Eigen::Vector3d w = (p - c).normalized();  // from the voxel to the receiver
        const auto& l = grid.weights[0];
        // I(w) = L sum_k lambda_k max(0, w . d_k); E = I cos / r^2; L_o = rho / pi E.
        const double sum = l[0] * std::max(0.0, w.x()) + l[1] * std::max(0.0, -w.x()) +
                           l[2] * std::max(0.0, w.y()) + l[3] * std::max(0.0, -w.y()) +
                           l[4] * std::max(0.0, w.z()) + l[5] * std::max(0.0, -w.z());
        const double r2 = (c - p).squaredNorm(), cos_theta = (c - p).z() / std::sqrt(r2);
        for (int ch = 0; ch < 3; ++ch) {
          const double expected = albedo[ch] / M_PI * grid.intensity[0][ch] * sum * cos_theta /
                                  (r2 + softening * softening);
          EXPECT_NEAR(out.radiance(u, v)[ch], expected, 1e-4 * expected + 1e-7)
              << u << "," << v << " softening " << softening;
        }
      }
    }
  }
}

// A 40 m plane of `albedo` at z = 0 under 24 point lights at random over [-2, 2]^2, between
// `lowest` and lowest + 1 m high.
Scene PointLightsOverAPlane(const Eigen::Vector3f& albedo, double lowest) {
  Scene scene;
  scene.meshes.push_back(Square(40.0, 0.0, true, albedo));
  CounterRng rng(5, 0);
  for (int i = 0; i < 24; ++i) {
    const Eigen::Vector3d at(rng.UniformDouble() * 4 - 2, rng.UniformDouble() * 4 - 2,
                             lowest + rng.UniformDouble());
    scene.point_lights.push_back({at, Eigen::Vector3f::Constant(0.2f + rng.Uniform())});
  }
  return scene;
}

// The exact direct light (channel 0) the plane of PointLightsOverAPlane reflects at p.
double DirectFromPointLights(const Scene& scene, double albedo, const Eigen::Vector3d& p) {
  double expected = 0.0;
  for (const PointLight& light : scene.point_lights) {
    const Eigen::Vector3d to = light.position - p;
    if (to.z() <= 0.0) continue;
    expected += albedo / M_PI * light.intensity[0] * to.z() / std::pow(to.norm(), 3.0);
  }
  return expected;
}

// A render (channel 0) against the exact direct light `exact(p)` at the point each pixel sees.
struct AgainstExact {
  double squared = 0.0;        // sum over the pixels of (render - exact)^2
  double mean = 0.0;           // mean render
  double expected_mean = 0.0;  // mean exact value
  int pixels = 0;
  double Rms() const { return std::sqrt(squared / pixels); }
};
template <typename Exact>
AgainstExact RenderAgainstExact(const PathTracer& tracer, const PosedView& view,
                                const RenderOptions& options, uint64_t seed, const Exact& exact) {
  const RenderOutput out = tracer.Render(view, options, seed);
  AgainstExact r;
  r.pixels = view.intrinsics.width * view.intrinsics.height;
  for (int v = 0; v < view.intrinsics.height; ++v) {
    for (int u = 0; u < view.intrinsics.width; ++u) {
      const double expected = exact(PointAt(view, out, u, v));
      const double got = out.radiance(u, v)[0];
      r.squared += (got - expected) * (got - expected);
      r.mean += got / r.pixels;
      r.expected_mean += expected / r.pixels;
    }
  }
  return r;
}

// Many point lights over a plane, one below it and one far fainter than the rest: next-event
// estimation that chooses the light by its contribution at the shading point stays unbiased (the
// exact sum of the lights' direct light) and is far less noisy than choosing by power alone (with
// nothing casting shadows it is exact up to rounding: the pmf is the integrand).
TEST(PathTracer, LightsChosenByContributionAreUnbiasedAndLessNoisy) {
  const Eigen::Vector3f albedo(0.5f, 0.5f, 0.5f);
  Scene scene = PointLightsOverAPlane(albedo, 0.05);
  scene.point_lights.push_back({Eigen::Vector3d(0, 0, -0.5), Eigen::Vector3f::Constant(5.0f)});
  scene.point_lights.push_back({Eigen::Vector3d(1, 1, 1), Eigen::Vector3f::Constant(1e-5f)});
  const PathTracer tracer(scene);
  const PosedView view = LookingDownAt({0.2, -0.3, 3.0}, {0.0, 0.0, 0.0}, 32, 24, 14.0);
  RenderOptions options;
  options.filter = "center";
  options.spp = 16;
  options.max_depth = 2;
  const auto exact = [&](const Eigen::Vector3d& p) {
    return DirectFromPointLights(scene, albedo[0], p);
  };
  AgainstExact by[2];
  for (int mode = 0; mode < 2; ++mode) {
    options.light_selection = mode == 0 ? "power" : "contribution";
    by[mode] = RenderAgainstExact(tracer, view, options, 11, exact);
  }
  std::printf(
      "[ closed   ] 26 point lights, 16 spp: RMS error by power %.5f, by contribution %.5f; "
      "means %.5f %.5f vs %.5f\n",
      by[0].Rms(), by[1].Rms(), by[0].mean, by[1].mean, by[0].expected_mean);
  EXPECT_NEAR(by[1].mean, by[1].expected_mean, 0.01 * by[1].expected_mean);
  EXPECT_LT(by[1].squared, 0.25 * by[0].squared) << "variance by contribution against by power";
}

// A light ten thousand times fainter than the room's main light, two centimetres above the
// floor: under it, it gives as much light as the main one. Chosen by power it would be drawn
// once in ten thousand samples there with a weight of ten thousand (salt noise); it is among the
// lights chosen by contribution, so the render is as clean as with the main light alone.
TEST(PathTracer, AFaintLightBesideASurfaceIsChosenByItsContribution) {
  const Eigen::Vector3f albedo(0.5f, 0.5f, 0.5f);
  Scene scene;
  scene.meshes.push_back(Square(40.0, 0.0, true, albedo));
  scene.point_lights.push_back({Eigen::Vector3d(0, 0, 2), Eigen::Vector3f::Constant(10.0f)});
  scene.point_lights.push_back({Eigen::Vector3d(0.1, 0, 0.02), Eigen::Vector3f::Constant(1e-3f)});
  const PathTracer tracer(scene);
  const PosedView view = LookingDownAt({0.1, -0.05, 2.0}, {0.1, 0.0, 0.0}, 24, 24, 200.0);
  RenderOptions options;
  options.filter = "center";
  options.spp = 16;
  options.max_depth = 2;
  options.exact_lights = 0;  // every light sampled: the choice itself is tested
  const auto exact = [&](const Eigen::Vector3d& p) {
    return DirectFromPointLights(scene, albedo[0], p);
  };
  AgainstExact by[2];
  for (int mode = 0; mode < 2; ++mode) {
    options.light_selection = mode == 0 ? "power" : "contribution";
    by[mode] = RenderAgainstExact(tracer, view, options, 5, exact);
  }
  std::printf(
      "[ closed   ] faint light 2 cm above the floor, 16 spp: RMS error by power %.5f, by "
      "contribution %.5f; means %.5f %.5f vs %.5f\n",
      by[0].Rms(), by[1].Rms(), by[0].mean, by[1].mean, by[0].expected_mean);
  EXPECT_NEAR(by[1].mean, by[1].expected_mean, 0.01 * by[1].expected_mean);
  EXPECT_LT(by[1].squared, 1e-3 * by[0].squared)
      << "squared error by contribution against by power";
}

// A bright light behind a wall and a dim one in front of it, over a floor seen only in front of
// the wall: by unshadowed contribution the bright light takes most samples there and every one
// is blocked, while the dim light that does reach the floor is drawn rarely. The visibility
// cache (RenderOptions::light_visibility) lowers the blocked light's weight: the mean stays the
// exact direct light of the dim one, the noise falls.
TEST(PathTracer, ALightBehindAWallIsRarelyChosenWhereItIsBlocked) {
  const Eigen::Vector3f albedo(0.5f, 0.5f, 0.5f);
  Scene scene;
  scene.meshes.push_back(Square(8.0, 0.0, true, albedo));
  SceneMesh wall;  // the plane x = 0, 4 m wide and 2 m high
  wall.mesh.vertices = {{0, -2, 0}, {0, 2, 0}, {0, 2, 2}, {0, -2, 2}};
  wall.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  wall.albedo = SurfaceAlbedo::Constant(albedo);
  scene.meshes.push_back(wall);
  scene.point_lights.push_back({Eigen::Vector3d(-0.4, 0, 0.5), Eigen::Vector3f::Constant(20.0f)});
  scene.point_lights.push_back({Eigen::Vector3d(1.0, 0, 1.0), Eigen::Vector3f::Constant(1.0f)});
  const PathTracer tracer(scene);
  // The floor from x = 0.6 to 1.4 only.
  const PosedView view = LookingDownAt({1.0, -0.05, 2.0}, {1.0, 0.0, 0.0}, 24, 24, 60.0);
  RenderOptions options;
  options.filter = "center";
  options.spp = 16;
  options.max_depth = 2;
  options.exact_lights = 0;
  int behind = 0;  // pixels that see anything but the floor in front of the wall
  const auto exact = [&](const Eigen::Vector3d& p) {  // the dim light's alone
    behind += !(p.x() > 0.5);
    const Eigen::Vector3d to = scene.point_lights[1].position - p;
    return albedo[0] / M_PI * scene.point_lights[1].intensity[0] * to.z() / std::pow(to.norm(), 3);
  };
  AgainstExact with[2];
  for (int mode = 0; mode < 2; ++mode) {
    options.light_visibility = mode == 1;
    with[mode] = RenderAgainstExact(tracer, view, options, 5, exact);
  }
  ASSERT_EQ(behind, 0) << "the view sees only the floor in front of the wall";
  std::printf(
      "[ closed   ] light behind a wall, 16 spp: RMS error without the visibility cache %.5f, "
      "with it %.5f; means %.5f %.5f vs %.5f\n",
      with[0].Rms(), with[1].Rms(), with[0].mean, with[1].mean, with[0].expected_mean);
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(with[k].mean, with[k].expected_mean,
                4.0 * with[k].Rms() / std::sqrt(static_cast<double>(with[k].pixels)))
        << k;
  }
  EXPECT_LT(with[1].squared, 0.3 * with[0].squared)
      << "squared error with the cache against without";
}

// LightVisibility on a floor split by a wall: in front of the wall the light behind it has the
// floor's factor and the light in front of it 1; a cell that the wall passes through sees both
// lights from some of its points; a point off the surfaces has no cell.
TEST(LightVisibility, HoldsTheShareOfEachLightThatReachesTheSurface) {
  Scene scene;
  scene.meshes.push_back(Square(8.0, 0.0, true, Eigen::Vector3f::Constant(0.5f)));
  SceneMesh wall;
  wall.mesh.vertices = {{0, -2, 0}, {0, 2, 0}, {0, 2, 2}, {0, -2, 2}};
  wall.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  wall.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Constant(0.5f));
  scene.meshes.push_back(wall);
  RayTracer tracer;
  for (const SceneMesh& m : scene.meshes) tracer.AddMesh(m.mesh);
  tracer.Commit();
  const std::vector<Eigen::Vector3f> lights = {{-0.4f, 0.0f, 0.5f}, {1.0f, 0.0f, 1.0f}};
  LightVisibilityOptions options;
  const LightVisibility visibility(scene, tracer, lights, options);
  EXPECT_GT(visibility.cells(), 100u);
  for (const Eigen::Vector3f& p :
       {Eigen::Vector3f(1.0f, 0.3f, 0.0f), Eigen::Vector3f(2.5f, -1.0f, 0.0f)}) {
    const float* f = visibility.At(p);
    ASSERT_NE(f, nullptr);
    EXPECT_FLOAT_EQ(f[0], options.floor) << p.transpose();
    EXPECT_FLOAT_EQ(f[1], 1.0f) << p.transpose();
  }
  const float* behind = visibility.At(Eigen::Vector3f(-1.0f, 0.3f, 0.0f));
  ASSERT_NE(behind, nullptr);
  EXPECT_FLOAT_EQ(behind[0], 1.0f);
  EXPECT_FLOAT_EQ(behind[1], options.floor);
  EXPECT_EQ(visibility.At(Eigen::Vector3f(1.0f, 0.0f, 1.5f)), nullptr);
}

// LightSampler::SplitAt: the strongest near-field lights taken exactly plus one of the others
// over its renormalised probability is, averaged over u, exactly the sum of every light's
// unshadowed contribution (here of 12 voxel lights and a faint point light at a floor point);
// the rest's probabilities sum to 1 and the exact lights are the strongest.
TEST(LightSampler, TheSplitIntoExactAndSampledLightsIsUnbiased) {
  Scene scene;
  scene.meshes.push_back(Square(10.0, 0.0, true, Eigen::Vector3f::Constant(0.5f)));
  VoxelLightGrid grid;
  grid.dims = Eigen::Vector3i(4, 3, 1);
  grid.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0.5), Eigen::Vector3d(1, 1, 1.0));
  grid.softening = 0.1;
  CounterRng rng(3, 0);
  for (int j = 0; j < grid.VoxelCount(); ++j) {
    grid.intensity.push_back(Eigen::Vector3f::Constant(0.1f + rng.Uniform()));
    grid.weights.push_back(
        {rng.Uniform(), rng.Uniform(), rng.Uniform(), rng.Uniform(), rng.Uniform(), rng.Uniform()});
  }
  scene.voxel_lights = grid;
  scene.point_lights.push_back({Eigen::Vector3d(0.3, 0.2, 2.0), Eigen::Vector3f::Constant(1e-6f)});
  const LightSampler sampler(scene);
  const Eigen::Vector3f p(0.2f, -0.1f, 0.0f), n(0.0f, 0.0f, 1.0f);
  // The unshadowed luminance each entry gives p, as the path tracer evaluates it.
  const auto contribution = [&](size_t i) {
    const LightSampler::Entry& e = sampler.entry(i);
    Eigen::Vector3d at = e.kind == LightSampler::Kind::kVoxel
                             ? grid.VoxelCenter(e.index)
                             : scene.point_lights[e.index].position;
    const Eigen::Vector3d to = at - p.cast<double>();
    const double d2 = to.squaredNorm(), cos = std::max(0.0, to.z() / std::sqrt(d2));
    if (e.kind == LightSampler::Kind::kPoint)
      return Luminance(scene.point_lights[e.index].intensity) * cos / d2;
    return Luminance(grid.Intensity(e.index, -to / std::sqrt(d2))) * cos *
           grid.Falloff(static_cast<float>(d2));
  };
  double all = 0.0;
  std::vector<double> each;
  for (size_t i = 0; i < 13; ++i) each.push_back(contribution(i)), all += each.back();
  std::vector<double> scratch;
  std::vector<size_t> exact;
  for (int count : {0, 1, 4, 12, 20}) {
    double sum = 0.0, exact_sum = 0.0;
    const int grid_points = 200000;
    for (int k = 0; k < grid_points; ++k) {
      LightSampler::Choice rest;
      sampler.SplitAt(p, n, count, (k + 0.5) / grid_points, &scratch, &exact, &rest);
      if (rest.pmf > 0.0f) sum += each[rest.entry] / rest.pmf / grid_points;
      if (k == 0) {
        for (size_t e : exact) exact_sum += each[e];
        EXPECT_EQ(exact.size(), static_cast<size_t>(std::min(count, 12))) << count;
        // The exact ones are the strongest near-field lights.
        double weakest_exact = 1e30, strongest_other = 0.0;
        for (size_t i = 0; i < 13; ++i) {
          if (sampler.entry(i).kind != LightSampler::Kind::kVoxel) continue;
          const bool taken = std::find(exact.begin(), exact.end(), i) != exact.end();
          if (taken) weakest_exact = std::min(weakest_exact, each[i]);
          if (!taken) strongest_other = std::max(strongest_other, each[i]);
        }
        if (!exact.empty()) {
          EXPECT_GE(weakest_exact, strongest_other * 0.999) << count;
        }
      }
    }
    EXPECT_NEAR(exact_sum + sum, all, 1e-3 * all) << count << " exact lights";
  }
}

// A pixel's samples choose the first vertex's light on a stratified lattice (Render), not
// independently (Radiance without first_light_u): on 24 point lights both are unbiased and the
// stratified error is smaller. (The lights are 0.3 m and more above the plane: by power, lights
// close to it would make the error too heavy-tailed for its standard error.)
TEST(PathTracer, StratifiedLightChoiceIsUnbiasedAndLessNoisy) {
  const Eigen::Vector3f albedo(0.5f, 0.5f, 0.5f);
  const Scene scene = PointLightsOverAPlane(albedo, 0.3);
  const PathTracer tracer(scene);
  const PosedView view = LookingDownAt({0.2, -0.3, 3.0}, {0.0, 0.0, 0.0}, 32, 24, 14.0);
  RenderOptions options;
  options.filter = "center";
  options.spp = 16;
  options.max_depth = 2;
  options.light_selection = "power";
  const RenderOutput out = tracer.Render(view, options, 11);
  const Eigen::Matrix3f rotation = view.world_from_camera.rotation().cast<float>();
  const Eigen::Vector3f eye = view.world_from_camera.translation().cast<float>();
  double error[2] = {0, 0}, mean[2] = {0, 0}, expected_mean = 0.0;
  for (int v = 0; v < 24; ++v) {
    for (int u = 0; u < 32; ++u) {
      const double expected = DirectFromPointLights(scene, albedo[0], PointAt(view, out, u, v));
      const Eigen::Vector3f dir =
          rotation * view.intrinsics.RayDirection(u, v).cast<float>().normalized();
      double independent = 0.0;
      for (int s = 0; s < options.spp; ++s) {
        CounterRng sample_rng(11, static_cast<uint64_t>(v * 32 + u), static_cast<uint64_t>(s));
        independent += tracer.Radiance(eye, dir, options, sample_rng)[0] / options.spp;
      }
      const double got[2] = {out.radiance(u, v)[0], independent};
      for (int k = 0; k < 2; ++k) {
        error[k] += (got[k] - expected) * (got[k] - expected);
        mean[k] += got[k] / (32 * 24);
      }
      expected_mean += expected / (32 * 24);
    }
  }
  std::printf(
      "[ closed   ] 24 point lights by power, 16 spp: RMS error stratified %.5f, independent "
      "%.5f; means %.5f %.5f vs %.5f\n",
      std::sqrt(error[0] / 768), std::sqrt(error[1] / 768), mean[0], mean[1], expected_mean);
  // Unbiased: each mean within four standard errors (RMS error / sqrt(pixels)) of the truth.
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(mean[k], expected_mean, 4.0 * std::sqrt(error[k] / 768) / std::sqrt(768.0)) << k;
  }
  EXPECT_LT(error[0], 0.6 * error[1]) << "squared error stratified against independent";
}

// Form factor from a differential area to a parallel rectangle a x b at distance h, with the
// normal through one corner: F = 1/(2 pi) [X/sqrt(1+X^2) atan(Y/sqrt(1+X^2)) + (X <-> Y)].
double CornerFormFactor(double a, double b, double h) {
  const double x = a / h, y = b / h;
  return (x / std::sqrt(1 + x * x) * std::atan(y / std::sqrt(1 + x * x)) +
          y / std::sqrt(1 + y * y) * std::atan(x / std::sqrt(1 + y * y))) /
         (2.0 * M_PI);
}

// A plane lit by a small square area light: every pixel looks at the point below its centre
// (a very long focal length), where L = rho * Le * F exactly.
struct AreaLightSetup {
  Scene scene;
  PosedView view;
  double expected = 0.0;
  AreaLightSetup() {
    const double side = 0.3, height = 0.8, rho = 0.8, le = 5.0;
    scene.meshes.push_back(Square(10.0, 0.0, true, Eigen::Vector3f::Constant(rho)));
    scene.meshes.push_back(
        Square(side, height, false, Eigen::Vector3f::Zero(), Eigen::Vector3f::Constant(le)));
    view = LookingDownAt({0.0, -0.5, 1.2}, {0.0, 0.0, 0.0}, 16, 16, 1e5);
    expected = rho * le * 4.0 * CornerFormFactor(side / 2, side / 2, height);
  }
};

double RmsErrorOverPixels(const RenderOutput& out, double expected, double* mean) {
  double sum2 = 0.0, sum = 0.0;
  for (const auto& p : out.radiance.pixels()) {
    sum += p.x();
    sum2 += (p.x() - expected) * (p.x() - expected);
  }
  *mean = sum / out.radiance.size();
  return std::sqrt(sum2 / out.radiance.size());
}

TEST(PathTracer, SmallAreaLightMatchesFormFactor) {
  const AreaLightSetup setup;
  const PathTracer tracer(setup.scene);
  RenderOptions options;
  options.filter = "center";
  options.spp = 256;
  options.max_depth = 2;
  double mean = 0.0;
  RmsErrorOverPixels(tracer.Render(setup.view, options, 5), setup.expected, &mean);
  std::printf("[ closed   ] area light: mean %.6f vs form factor %.6f (%.3f%%)\n", mean,
              setup.expected, 100.0 * (mean / setup.expected - 1.0));
  EXPECT_NEAR(mean, setup.expected, 0.01 * setup.expected);
}

// A light close to a surface: a 1 cm square emitter 1 cm above a floor, seen through the gap.
// The floor under its centre has L = rho * Le * F with the form factor F of a centred parallel
// square (side 2a, height h). The shadow rays end on the light itself, so they must be traced to
// it from the offset origin, not along the direction from the unoffset point.
TEST(PathTracer, AreaLightCloseToASurfaceIsNotShadowedByItself) {
  const double h = 0.01, a = 0.005;
  const Eigen::Vector3f albedo(0.5f, 0.5f, 0.5f), emission(2.0f, 2.0f, 2.0f);
  Scene scene;
  scene.meshes.push_back(Square(2 * a, 0.0, true, albedo));
  scene.meshes.push_back(Square(2 * a, h, false, Eigen::Vector3f::Zero(), emission));
  const PathTracer tracer(scene);
  const PosedView view = LookingDownAt({0.0, 0.0, 0.009}, {0.0, 0.0, 0.0}, 8, 8, 400.0);
  RenderOptions options;
  options.filter = "center";
  options.spp = 256;
  options.max_depth = 2;
  const RenderOutput out = tracer.Render(view, options, 3);
  // Form factor from a point to a parallel square centred above it (four rectangles a x a):
  // F = 4 / (2 pi) [X / sqrt(1 + X^2) atan(Y / sqrt(1 + X^2)) + (X <-> Y)], X = Y = a / h.
  const double x = a / h, s1 = std::sqrt(1.0 + x * x);
  const double form_factor = 4.0 / (2.0 * M_PI) * 2.0 * (x / s1) * std::atan(x / s1);
  const double expected = 0.5 * 2.0 * form_factor;
  double mean = 0.0;
  for (int v = 0; v < 8; ++v) {
    for (int u = 0; u < 8; ++u) mean += out.radiance(u, v).mean() / 64.0;
  }
  std::printf("[ closed   ] 1 cm light 1 cm above the floor: mean %.5f vs %.5f\n", mean, expected);
  EXPECT_NEAR(mean, expected, 0.01 * expected);
}

TEST(PathTracer, ErrorFallsAsOneOverSqrtSpp) {
  const AreaLightSetup setup;
  const PathTracer tracer(setup.scene);
  RenderOptions options;
  options.filter = "center";
  options.max_depth = 2;
  double mean = 0.0;
  options.spp = 4;
  const double error_4 =
      RmsErrorOverPixels(tracer.Render(setup.view, options, 7), setup.expected, &mean);
  options.spp = 64;
  const double error_64 =
      RmsErrorOverPixels(tracer.Render(setup.view, options, 8), setup.expected, &mean);
  // 16x the samples: the error should fall 4x, within a factor of 1.5.
  const double ratio = error_4 / error_64;
  std::printf("[ closed   ] RMS error 4 spp %.5f, 64 spp %.5f: ratio %.3f (1/sqrt(spp): 4)\n",
              error_4, error_64, ratio);
  EXPECT_GT(ratio, 4.0 / 1.5) << error_4 << " " << error_64;
  EXPECT_LT(ratio, 4.0 * 1.5) << error_4 << " " << error_64;
}

TEST(PathTracer, WhiteFurnace) {
  // Inside a closed box whose walls all have albedo a and emit Le: L = Le / (1 - a).
  SyntheticScene room;
  room.room = SyntheticScene::Room{};
  room.room->bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 2));
  const float a = 0.6f;
  room.room->albedo.fill(Eigen::Vector3f::Constant(a));
  SceneMesh walls;
  walls.mesh = room.ToMesh();
  walls.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Constant(a));
  walls.emission = Eigen::Vector3f(1.0f, 0.5f, 0.25f);
  walls.mesh.face_colors.clear();
  Scene scene;
  scene.meshes.push_back(walls);
  const PathTracer tracer(scene);
  const PosedView view = LookingDownAt({0.2, -0.5, 1.0}, {0.0, 0.5, 0.8}, 12, 10, 8.0);
  RenderOptions options;
  options.spp = 256;
  const RenderOutput out = tracer.Render(view, options, 11);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : out.radiance.pixels()) mean += p.cast<double>();
  mean /= out.radiance.size();
  const Eigen::Vector3d expected = walls.emission.cast<double>() / (1.0 - a);
  std::printf("[ closed   ] furnace: mean %.5f %.5f %.5f vs Le/(1-a) %.5f %.5f %.5f\n", mean[0],
              mean[1], mean[2], expected[0], expected[1], expected[2]);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], expected[c], 0.01 * expected[c]);
}

TEST(PathTracer, VoxelLightMatchesItsSixQuadExport) {
  Scene voxel;
  voxel.meshes.push_back(Square(6.0, 0.0, true, Eigen::Vector3f::Constant(0.7f)));
  VoxelLightGrid grid;
  grid.dims = Eigen::Vector3i(2, 1, 1);
  grid.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.4, -0.2, 0.8), Eigen::Vector3d(0.4, 0.2, 1.2));
  grid.intensity = {Eigen::Vector3f(1.0f, 1.5f, 2.0f), Eigen::Vector3f(0.5f, 0.2f, 0.1f)};
  grid.weights = {{0.2f, 0.5f, 0.1f, 0.3f, 0.0f, 1.0f}, {1.0f, 0.0f, 0.4f, 0.4f, 0.6f, 0.8f}};
  grid.cube_size = 0.01;
  voxel.voxel_lights = grid;
  Scene quads;
  quads.meshes = voxel.meshes;
  for (const SceneMesh& m : VoxelCubeFaces(grid)) quads.meshes.push_back(m);
  EXPECT_EQ(quads.meshes.size(), 1u + 5u + 5u);  // zero weights export no quad

  const PosedView view = LookingDownAt({0.1, -1.5, 2.0}, {0.0, 0.0, 0.0}, 16, 12, 10.0);
  RenderOptions options;
  options.spp = 1024;
  options.max_depth = 2;
  options.hide_emitters = true;
  const RenderOutput a = PathTracer(voxel).Render(view, options, 21);  // exact: a delta light
  const PathTracer quad_tracer(quads);
  const RenderOutput b1 = quad_tracer.Render(view, options, 22);
  const RenderOutput b2 = quad_tracer.Render(view, options, 23);
  // Means over the image; the standard error of the quad render's mean from its two seeds.
  const double n = static_cast<double>(a.radiance.size());
  Eigen::Vector3d mean_a = Eigen::Vector3d::Zero(), mean_b = Eigen::Vector3d::Zero(),
                  var = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < a.radiance.size(); ++i) {
    const Eigen::Vector3d x1 = b1.radiance.pixels()[i].cast<double>(),
                          x2 = b2.radiance.pixels()[i].cast<double>();
    mean_a += a.radiance.pixels()[i].cast<double>() / n;
    mean_b += (x1 + x2) / (2.0 * n);
    var += (x1 - x2).cwiseAbs2() / 4.0;  // variance of (x1 + x2) / 2 per pixel
  }
  for (int c = 0; c < 3; ++c) {
    const double standard_error = std::sqrt(var[c]) / n;
    // Noise (4 standard errors) plus 0.5 % for the cube's finite size (faces 5 mm off centre).
    std::printf("[ closed   ] voxel light vs six quads, channel %d: %.6f vs %.6f (se %.6f)\n", c,
                mean_a[c], mean_b[c], standard_error);
    EXPECT_LT(standard_error, 0.005 * mean_a[c]) << "too noisy to tell";
    EXPECT_NEAR(mean_b[c], mean_a[c], 4.0 * standard_error + 0.005 * mean_a[c])
        << c << " se " << standard_error;
  }
}

TEST(PathTracer, SameSeedSameImageWithOneAndTwoThreads) {
  const AreaLightSetup setup;
  Scene scene = setup.scene;
  scene.meshes[0].albedo = SurfaceAlbedo::Constant(Eigen::Vector3f(0.9f, 0.5f, 0.3f));
  PosedView view = LookingDownAt({0.0, -1.0, 1.0}, {0.0, 0.0, 0.3}, 20, 15, 15.0);
  RenderOptions options;
  options.spp = 8;
  std::vector<float> without_distant;
  // Without and with a distant light (its own shadow rays and random numbers per vertex).
  for (bool distant : {false, true}) {
    if (distant) {
      VoxelLightGrid grid;
      grid.bounds =
          Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1));
      grid.dims = Eigen::Vector3i::Ones();
      grid.cube_size = 0.01;
      grid.intensity = {Eigen::Vector3f::Zero()};
      grid.weights = {{1, 1, 1, 1, 1, 1}};
      grid.distant = true;
      grid.distant_intensity = Eigen::Vector3f(0.5f, 0.6f, 0.7f);
      grid.distant_weights = {0.2f, 0.2f, 0.2f, 0.2f, 1.0f, 0.0f};
      scene.voxel_lights = grid;
    }
    const PathTracer tracer(scene);
    SetThreadCount(1);
    const RenderOutput one = tracer.Render(view, options, 99);
    SetThreadCount(2);
    const RenderOutput two = tracer.Render(view, options, 99);
    SetThreadCount(0);
    const RenderOutput other_seed = tracer.Render(view, options, 100);
    EXPECT_EQ(one.radiance.pixels(), two.radiance.pixels()) << "distant " << distant;
    EXPECT_EQ(one.depth.pixels(), two.depth.pixels()) << "distant " << distant;
    EXPECT_NE(one.radiance.pixels(), other_seed.radiance.pixels()) << "distant " << distant;
    std::vector<float> sums;
    for (const Eigen::Vector3f& p : one.radiance.pixels()) sums.push_back(p.sum());
    if (!distant) {
      without_distant = sums;
    } else {
      EXPECT_NE(sums, without_distant) << "the distant light changed nothing";
    }
  }
}

// The stream of shadow rays from one vertex (the voxel-light splitting) gives each ray's single-ray
// answer: 64 origins inside the Cornell room (box and sphere occlude), 343 segments each towards
// points all over the room, with empty segments (t_max <= t_min) and streams longer than one chunk.
TEST(RayTracer, StreamOcclusionMatchesSingleRays) {
  RayTracer tracer;
  tracer.AddMesh(MakeCornellScene().ToMesh());
  tracer.Commit();
  CounterRng rng(7, 1);
  int blocked = 0, open = 0;
  for (int o = 0; o < 64; ++o) {
    const Eigen::Vector3f origin(1.9f * rng.Uniform() - 0.95f, 1.9f * rng.Uniform() - 0.95f,
                                 1.9f * rng.Uniform() + 0.05f);
    std::vector<Eigen::Vector3f> directions(343);
    std::vector<float> t_max(343);
    for (size_t i = 0; i < directions.size(); ++i) {
      const Eigen::Vector3f target(1.9f * rng.Uniform() - 0.95f, 1.9f * rng.Uniform() - 0.95f,
                                   1.9f * rng.Uniform() + 0.05f);
      directions[i] = (target - origin).normalized();
      t_max[i] = i % 50 == 0 ? 0.0f : (target - origin).norm();
    }
    std::vector<uint8_t> occluded(directions.size(), 7);
    tracer.OccludedFrom(origin, directions.data(), t_max.data(),
                        static_cast<int>(directions.size()), 0.0f, occluded.data());
    for (size_t i = 0; i < directions.size(); ++i) {
      const bool single = tracer.Occluded(origin, directions[i], 0.0f, t_max[i]);
      ASSERT_EQ(occluded[i], single ? 1 : 0) << "origin " << o << " ray " << i;
      (single ? blocked : open) += 1;
    }
  }
  // Both answers occur often, so the comparison tests something.
  EXPECT_GT(blocked, 1000);
  EXPECT_GT(open, 1000);
}

TEST(PathTracer, BadScenesAreRejected) {
  Scene scene;
  scene.meshes.push_back(
      Square(1.0, 0.0, true, Eigen::Vector3f::Constant(0.5f), Eigen::Vector3f(-1, 1, 1)));
  EXPECT_THROW(PathTracer{scene}, Error);
  scene.meshes[0].emission = Eigen::Vector3f::Zero();
  scene.meshes[0].mesh.vertices[2].x() = NAN;
  EXPECT_THROW(PathTracer{scene}, Error);
  scene.meshes[0] = Square(1.0, 0.0, true, Eigen::Vector3f(1.5f, 0.5f, 0.5f));
  EXPECT_THROW(PathTracer{scene}, Error);
  RenderOptions options;
  options.max_depth = 0;
  EXPECT_THROW(options.Validate(), Error);
}

}  // namespace
}  // namespace genscene::render
