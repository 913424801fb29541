// Light estimation: the cache against renders, the cost's gradient against finite
// differences, recovery of known lights, and the hard cases.
#include "inverse/lights/light_estimation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "core/check.h"
#include "core/color.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/synthetic.h"
#include "render/procedural.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on
namespace {

// The Cornell box without its light, and a voxel grid over it with a few lit voxels. The grid's
// cells tile the box (boundary inset 0.5: centres at 0, +-2/3 in x and y, 1/3, 1, 5/3 in z), so
// the lights stay clear of the walls; the estimates below use the same grid (kSmallInset).
constexpr double kSmallInset = 0.5;
struct SmallScene {
  Scene geometry = WithoutLights(MakeCornellBoxScene());
  VoxelLightGrid grid = MakeVoxelGrid(geometry, 3, kSmallInset);
  SmallScene() {
    grid.intensity[22] = Eigen::Vector3f(2.0f, 1.5f, 1.0f);  // top layer, centre: (0, 0, 1.67)
    grid.weights[22] = {0.2f, 0.2f, 0.2f, 0.2f, 0.0f, 1.0f};
    grid.intensity[4] = Eigen::Vector3f(0.3f, 0.3f, 0.6f);  // bottom layer, centre
    grid.weights[4] = {1, 1, 1, 1, 1, 1};
  }
  // The geometry lit by `lights` (default: this scene's grid).
  Scene Lit(const VoxelLightGrid* lights = nullptr) const {
    Scene lit = geometry;
    lit.voxel_lights = lights ? *lights : grid;
    return lit;
  }
};

int StrongestVoxel(const VoxelLightGrid& grid) {
  int strongest = 0;
  for (int j = 0; j < grid.VoxelCount(); ++j) {
    if (Luminance(grid.Power(j)) > Luminance(grid.Power(strongest))) strongest = j;
  }
  return strongest;
}

std::vector<PosedImage> Views(const std::vector<PosedView>& views) {
  std::vector<PosedImage> out;
  for (const PosedView& v : views)
    out.push_back({v, ImageRgb(v.intrinsics.width, v.intrinsics.height, Eigen::Vector3f::Ones())});
  return out;
}

TEST(LightCache, PredictionEqualsAFreshRenderWithTheSameSamples) {
  SmallScene s;
  const PathTracer tracer(s.geometry);
  const std::vector<PosedImage> views = Views(CornellLightViews(16, 12));
  LightEstimationOptions o;
  o.paths.spp = 4;
  o.pixels_per_view = 40;
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 3);
  for (const VoxelSplitting& splitting : {VoxelSplitting{}, [] {
                                            VoxelSplitting v;
                                            std::vector<double> pmf(27, 1.0);
                                            pmf[22] = 20.0;
                                            v.SetPmf(pmf, 5);
                                            return v;
                                          }()}) {
    const LightCache cache = TraceLightCache(tracer, s.grid, splitting, views, pixels, o, 11);
    const std::vector<Eigen::Vector3f> predicted = cache.Predict(s.grid);
    double worst = 0.0;
    for (size_t i = 0; i < pixels.size(); ++i) {
      const Eigen::Vector3f fresh =
          RenderSampledPixel(tracer, s.grid, splitting, pixels[i], views, o, 11);
      worst =
          std::max<double>(worst, (fresh - predicted[i]).norm() / std::max(1e-6f, fresh.norm()));
    }
    EXPECT_LT(worst, 1e-5) << "the cached prediction differs from the walk it was recorded from";
  }
}

// The outer voxel centres lie `inset` voxels inside the scene's box (lights on the walls and the
// ceiling with a small inset; cells that tile the box with 0.5), the voxels evenly spaced.
TEST(MakeVoxelGrid, OuterCentresLieTheInsetInsideTheBox) {
  const Scene geometry = WithoutLights(MakeCornellBoxScene());  // walls at x, y = +-1, z = 0 and 2
  for (double inset : {0.5, 0.1, 0.0}) {
    const VoxelLightGrid g = MakeVoxelGrid(geometry, 7, inset);
    const double voxel = 2.0 / (6.0 + 2.0 * inset);
    for (int axis = 0; axis < 3; ++axis) {
      EXPECT_NEAR(g.bounds.sizes()[axis] / g.dims[axis], voxel, 1e-6) << "inset " << inset;
    }
    const Eigen::Vector3d first = g.VoxelCenter(0), last = g.VoxelCenter(g.VoxelCount() - 1);
    EXPECT_LT((first - Eigen::Vector3d(-1.0, -1.0, 0.0) - Eigen::Vector3d::Constant(inset * voxel))
                  .norm(),
              1e-5)
        << "inset " << inset << ": first centre " << first.transpose();
    EXPECT_LT(
        (last - Eigen::Vector3d(1.0, 1.0, 2.0) + Eigen::Vector3d::Constant(inset * voxel)).norm(),
        1e-5)
        << "inset " << inset << ": last centre " << last.transpose();
  }
  // One voxel: its centre is the box's.
  EXPECT_LT(
      (MakeVoxelGrid(geometry, 1, 0.1).VoxelCenter(0) - Eigen::Vector3d(0.0, 0.0, 1.0)).norm(),
      1e-6);
}

// The cache's estimator (splitting over voxels) and the path tracer's (one light sample per
// vertex) are different Monte Carlo estimators of the same pixel: their means agree, with point
// lights and with softened ones (the bottom voxel lights the floor 1/3 m below it).
TEST(LightCache, AgreesWithThePathTracerOnAverage) {
  for (const double softening : {0.0, 0.3}) {
    SmallScene s;
    s.grid.softening = softening;
    const Scene lit = s.Lit();
    const PathTracer tracer(s.geometry), lit_tracer(lit);
    const std::vector<PosedView> all = CornellLightViews(12, 9);
    const std::vector<PosedImage> views = Views({all[0]});
    LightEstimationOptions o;
    o.paths.spp = 256;
    o.pixels_per_view = 1000;
    const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 3);
    const std::vector<Eigen::Vector3f> predicted =
        TraceLightCache(tracer, s.grid, VoxelSplitting{}, views, pixels, o, 5).Predict(s.grid);
    RenderOptions ro;
    ro.spp = 1024;
    const RenderOutput render = lit_tracer.Render(all[0], ro, 9);
    Eigen::Vector3d sum_cache = Eigen::Vector3d::Zero(), sum_render = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < pixels.size(); ++i) {
      sum_cache += predicted[i].cast<double>();
      sum_render += render.radiance(pixels[i].u, pixels[i].v).cast<double>();
    }
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(sum_cache[c] / sum_render[c], 1.0, 0.02)
          << "channel " << c << ", softening " << softening;
    }
  }
}

// Renders `views` of `lit` (direct + indirect) as training views.
std::vector<PosedImage> Render(const Scene& lit, const std::vector<PosedView>& views, int spp,
                               int max_depth = -1) {
  const PathTracer tracer(lit);
  RenderOptions ro;
  ro.spp = spp;
  ro.max_depth = max_depth;
  std::vector<PosedImage> out;
  for (size_t i = 0; i < views.size(); ++i)
    out.push_back({views[i], tracer.Render(views[i], ro, 100 + i).radiance});
  return out;
}

// The three training views of CornellLightViews at 24 x 18, rendered at 64 spp.
std::vector<PosedImage> TrainingViews(const Scene& lit) {
  const std::vector<PosedView> all = CornellLightViews(24, 18);
  return Render(lit, {all[0], all[1], all[2]}, 64);
}

// Light estimation on the small scene's 3^3 grid from 300 pixels per view.
LightEstimationOptions SmallOptions() {
  LightEstimationOptions o;
  o.grid = 3;
  o.boundary_inset = kSmallInset;
  o.pixels_per_view = 300;
  o.refine_levels = 0;  // the coarse estimator; refinement has its own tests
  return o;
}

// Normal equations of the small scene from 2 x 4 paths per pixel.
NormalEquations SmallEquations(const SmallScene& s, const std::vector<PosedImage>& views,
                               double correction) {
  const PathTracer tracer(s.geometry);
  LightEstimationOptions o;
  o.pixels_per_view = 150;
  o.paths.spp = 8;
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 3);
  o.paths.spp = 4;
  const LightCache a = TraceLightCache(tracer, s.grid, VoxelSplitting{}, views, pixels, o, 1);
  const LightCache b = TraceLightCache(tracer, s.grid, VoxelSplitting{}, views, pixels, o, 2);
  return NormalEquations::FromCaches(a, b, correction);
}

TEST(LightCost, GradientEqualsCentralDifferences) {
  SmallScene s;
  const Scene lit = s.Lit();
  const std::vector<PosedView> all = CornellLightViews(16, 12);
  const std::vector<PosedImage> views = Render(lit, {all[0], all[1]}, 16);
  const NormalEquations eq = SmallEquations(s, views, 0.5);
  for (const double chroma : {0.0, 0.7}) {
    const LightCost cost(eq, 1e-3, 0.01, chroma);
    // A random interior point (every L and lambda away from 0 and from the bounds), and the same
    // with only three voxels lit (G x then sums the lit parameters' columns).
    CounterRng rng(5, 0);
    Eigen::VectorXd dense(9 * 27);
    for (Eigen::Index i = 0; i < dense.size(); ++i) dense[i] = 0.05 + 0.9 * rng.UniformDouble();
    Eigen::VectorXd sparse = dense;
    for (int j = 0; j < 27; ++j) {
      if (j != 4 && j != 13 && j != 22) sparse.segment<3>(9 * j).setZero();
    }
    for (const Eigen::VectorXd& x : {dense, sparse}) {
      Eigen::VectorXd gradient;
      cost.Evaluate(x, &gradient);
      double worst = 0.0, mean = 0.0;
      for (Eigen::Index i = 0; i < x.size(); ++i) {
        const double h = 1e-5 * std::max(1.0, std::abs(x[i]));
        Eigen::VectorXd plus = x, minus = x;
        plus[i] += h;
        minus[i] -= h;
        const double numeric = (cost.Evaluate(plus) - cost.Evaluate(minus)) / (2.0 * h);
        const double error =
            std::abs(numeric - gradient[i]) / std::max(1e-8, std::abs(gradient[i]));
        worst = std::max(worst, error);
        mean += error / x.size();
      }
      EXPECT_LT(worst, 1e-4) << "mean relative error " << mean
                             << (&x == &dense ? " (all lit)" : " (three lit)") << ", chroma weight "
                             << chroma;
    }
  }
}

TEST(LightCost, GramCostEqualsThePerPixelCost) {
  SmallScene s;
  const Scene lit = s.Lit();
  const std::vector<PosedImage> views = Render(lit, {CornellLightViews(16, 12)[2]}, 16);
  const PathTracer tracer(s.geometry);
  LightEstimationOptions o;
  o.pixels_per_view = 100;
  o.paths.spp = 4;
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 3);
  const LightCache cache = TraceLightCache(tracer, s.grid, VoxelSplitting{}, views, pixels, o, 1);
  const NormalEquations eq = NormalEquations::FromCache(cache);
  VoxelLightGrid other = s.grid;
  other.intensity[13] = Eigen::Vector3f(0.4f, 0.5f, 0.6f);
  for (const VoxelLightGrid* g : {&s.grid, &other}) {
    const std::vector<Eigen::Vector3f> predicted = cache.Predict(*g);
    double residual = 0.0, energy = 0.0;
    for (size_t i = 0; i < pixels.size(); ++i) {
      residual += (predicted[i] - pixels[i].observed).cast<double>().squaredNorm();
      energy += pixels[i].observed.cast<double>().squaredNorm();
    }
    double data = 0.0;
    LightCost(eq, 0.0, 0.01).Evaluate(LightCost::Pack(*g), nullptr, &data);
    EXPECT_NEAR(data, residual / energy, 1e-5 * (residual / energy) + 1e-9);
  }
}

// A growing refinement pass traces only the voxels it adds and merges them into the caches: with
// the same seed every path is the same, so the merge equals one trace of both sets, bit for bit.
// One view of the small scene and 100 of its pixels, for the tests of caches traced in parts.
struct PartsSetup {
  SmallScene s;
  std::vector<PosedImage> views = Render(s.Lit(), {CornellLightViews(16, 12)[0]}, 8);
  PathTracer tracer{s.geometry};
  LightEstimationOptions o = [] {
    LightEstimationOptions options;
    options.pixels_per_view = 100;
    options.paths.spp = 4;
    return options;
  }();
  std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 3);
};

TEST(LightCache, MergeOfTwoVoxelSetsEqualsOneTraceOfBoth) {
  const PartsSetup p;
  const auto& [s, views, tracer, o, pixels] = p;
  VoxelSplitting first, second, both;
  for (int j = 0; j < 27; ++j) {
    first.enabled.push_back(j % 3 == 0);
    second.enabled.push_back(j % 3 == 1);
    both.enabled.push_back(j % 3 != 2);
  }
  LightCache merged = TraceLightCache(tracer, s.grid, first, views, pixels, o, 5);
  const LightCache added = TraceLightCache(tracer, s.grid, second, views, pixels, o, 5);
  ASSERT_GT(merged.NonZeros(), 0u);
  ASSERT_GT(added.NonZeros(), 0u);
  merged.Merge(added);
  const LightCache whole = TraceLightCache(tracer, s.grid, both, views, pixels, o, 5);
  EXPECT_EQ(merged.row_begin, whole.row_begin);
  EXPECT_EQ(merged.index, whole.index);
  ASSERT_EQ(merged.coefficient.size(), whole.coefficient.size());
  for (size_t e = 0; e < whole.coefficient.size(); ++e) {
    ASSERT_EQ(merged.coefficient[e], whole.coefficient[e]) << "entry " << e;
  }
  EXPECT_EQ(merged.rays.occluded, whole.rays.occluded);
  EXPECT_THROW(merged.Merge(added), std::exception) << "a parameter in both caches was merged";
}

// The growing pass's normal equations: the entries between parameters of the equations before
// the merge are taken from them, the others computed; the result equals computing all of them.
TEST(NormalEquations, KnownPartOfAMergedCacheGivesTheSameEquations) {
  const PartsSetup p;
  const auto& [s, views, tracer, o, pixels] = p;
  VoxelSplitting first, second;
  for (int j = 0; j < 27; ++j) {
    first.enabled.push_back(j % 3 == 0 || j == 26);
    second.enabled.push_back(j % 3 == 1);
  }
  LightCache a = TraceLightCache(tracer, s.grid, first, views, pixels, o, 5);
  LightCache b = TraceLightCache(tracer, s.grid, first, views, pixels, o, ~5ull);
  const NormalEquations known = NormalEquations::FromCaches(a, b, 0.5);
  a.Merge(TraceLightCache(tracer, s.grid, second, views, pixels, o, 5));
  b.Merge(TraceLightCache(tracer, s.grid, second, views, pixels, o, ~5ull));
  const NormalEquations whole = NormalEquations::FromCaches(a, b, 0.5);
  const NormalEquations grown = NormalEquations::FromCaches(a, b, 0.5, &known);
  const double n = static_cast<double>(whole.used.size());
  ASSERT_GT(whole.used.size(), known.used.size());
  // Dense rows (the sparse ones are always computed whole).
  ASSERT_GE(static_cast<double>(a.NonZeros() + b.NonZeros()),
            0.2 * n * static_cast<double>(pixels.size()));
  EXPECT_EQ(grown.used, whole.used);
  for (int c = 0; c < 3; ++c) {
    const double scale = whole.gram[c].cwiseAbs().maxCoeff();
    ASSERT_GT(scale, 0.0);
    EXPECT_LE((grown.gram[c] - whole.gram[c]).cwiseAbs().maxCoeff(), 1e-6 * scale)
        << "channel " << c;
    EXPECT_EQ(grown.gram[c], grown.gram[c].transpose()) << "channel " << c;
    EXPECT_LE((grown.rhs[c] - whole.rhs[c]).cwiseAbs().maxCoeff(),
              1e-9 * whole.rhs[c].cwiseAbs().maxCoeff());
    EXPECT_EQ(grown.observed_sq[c], whole.observed_sq[c]);
  }
}

// Drawing from a pmf with zeros (the unused voxels of a finer grid) never returns one of them,
// even for u just below 1 where the running sum's rounding could end short of 1.
TEST(VoxelSplitting, NeverDrawsAVoxelOfProbabilityZero) {
  VoxelSplitting v;
  std::vector<double> pmf(50, 0.0);
  pmf[3] = 0.1, pmf[17] = 0.2,
  pmf[29] = 0.3;  // normalised, their running sum is 1 - 2^-53; the last ones are 0
  v.SetPmf(pmf, 4);
  for (double u : {0.0, 0.25, 0.5, 0.999999, std::nextafter(1.0, 0.0)}) {
    const int j = v.Choose(u);
    EXPECT_GT(v.pmf[j], 0.0) << "u " << u << " drew voxel " << j;
  }
}

// Splittings that take the two code paths of the normal equations: sampled voxels (sparse rows)
// and every voxel (dense rows), on the 3^3 grid.
std::vector<VoxelSplitting> SparseAndDenseSplittings() {
  VoxelSplitting sampled;
  sampled.all_until_depth = 0;
  sampled.SetPmf(std::vector<double>(27, 1.0), 1);
  return {sampled, VoxelSplitting{}};
}

TEST(NormalEquations, DenseAndSparseRowsAndThreadCountsAgree) {
  SmallScene s;
  const Scene lit = s.Lit();
  const std::vector<PosedImage> views = Render(lit, {CornellLightViews(16, 12)[0]}, 8);
  const PathTracer tracer(s.geometry);
  LightEstimationOptions o;
  o.pixels_per_view = 120;
  o.paths.spp = 2;
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 3);
  for (const VoxelSplitting& split : SparseAndDenseSplittings()) {
    const LightCache a = TraceLightCache(tracer, s.grid, split, views, pixels, o, 1);
    const LightCache b = TraceLightCache(tracer, s.grid, split, views, pixels, o, 2);
    // Reference: the formula written out densely, in double.
    const NormalEquations eq = NormalEquations::FromCaches(a, b, 0.5);
    const int n = static_cast<int>(eq.used.size());
    std::vector<int> compact(162, -1);
    for (int i = 0; i < n; ++i) compact[eq.used[i]] = i;
    for (int c = 0; c < 3; ++c) {
      Eigen::MatrixXd ma = Eigen::MatrixXd::Zero(pixels.size(), n), mb = ma;
      for (size_t i = 0; i < pixels.size(); ++i) {
        for (size_t e = a.row_begin[i]; e < a.row_begin[i + 1]; ++e)
          ma(i, compact[a.index[e]]) = a.coefficient[e][c];
        for (size_t e = b.row_begin[i]; e < b.row_begin[i + 1]; ++e)
          mb(i, compact[b.index[e]]) = b.coefficient[e][c];
      }
      const Eigen::MatrixXd mean = 0.5 * (ma + mb), half = 0.5 * (ma - mb);
      const Eigen::MatrixXd expected = mean.transpose() * mean - 0.5 * half.transpose() * half;
      EXPECT_LT((eq.gram[c] - expected).norm(), 1e-5 * expected.norm()) << "channel " << c;
    }
    SetThreadCount(1);
    const NormalEquations one = NormalEquations::FromCaches(a, b, 0.5);
    SetThreadCount(0);
    for (int c = 0; c < 3; ++c)
      EXPECT_EQ(one.gram[c], eq.gram[c]) << "thread count changed the sums";
  }
}

// A light the grid can represent, seen through direct and indirect light: the estimate puts its
// power in the right place and reproduces the training views.
TEST(EstimateLights, RecoversAVoxelLight) {
  SmallScene s;
  VoxelLightGrid truth = s.grid;
  truth.intensity[4].setZero();  // one light: top centre, mostly facing down
  const Scene lit = s.Lit(&truth);
  const std::vector<PosedImage> views = TrainingViews(lit);
  LightEstimationOptions o = SmallOptions();
  o.rounds = 2;
  const LightEstimate e = EstimateLights(lit, views, o, 1);
  ASSERT_EQ(e.lights.VoxelCount(), 27);
  const Eigen::Vector3d centroid = e.lights.PowerCentroid();
  const double total = e.lights.TotalPowerLuminance();
  const double voxel = 2.0 / 3.0;
  EXPECT_LT((centroid - truth.VoxelCenter(22)).norm(), 0.5 * voxel)
      << "centroid " << centroid.transpose();
  EXPECT_NEAR(total / Luminance(truth.Power(22)), 1.0, 0.25);
  EXPECT_LT(e.train_rmse, 0.35);  // the cache's own paths are noisy (8 per half-pixel)
  EXPECT_LE(e.active_voxels, 6);
  EXPECT_EQ(StrongestVoxel(e.lights), 22) << "the light is in the wrong voxel";
}

// The per-view equations sum to the total, and scaling a view's observations (the exposure step)
// gives the equations of the scaled observations, for sparse and dense rows.
TEST(NormalEquations, PerViewEquationsSumToTheTotalAndScaleWithTheObservations) {
  SmallScene s;
  const std::vector<PosedImage> views = Render(s.Lit(), CornellLightViews(16, 12), 4);
  ASSERT_GE(views.size(), 2u);
  const PathTracer tracer(s.geometry);
  LightEstimationOptions o;
  o.pixels_per_view = 60;
  o.paths.spp = 2;
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 3);
  std::vector<Eigen::Vector3d> scale(views.size());
  for (size_t v = 0; v < views.size(); ++v)
    scale[v] = Eigen::Vector3d(0.5 + 0.3 * v, 1.2 - 0.1 * v, 0.8 + 0.05 * v);
  for (const VoxelSplitting& split : SparseAndDenseSplittings()) {
    LightCache a = TraceLightCache(tracer, s.grid, split, views, pixels, o, 1);
    LightCache b = TraceLightCache(tracer, s.grid, split, views, pixels, o, 2);
    NormalEquations eq = NormalEquations::FromCaches(a, b, 0.5);
    ASSERT_EQ(eq.view_rhs.size(), views.size());
    for (int c = 0; c < 3; ++c) {
      Eigen::VectorXd rhs = Eigen::VectorXd::Zero(eq.rhs[c].size());
      double observed_sq = 0.0;
      for (size_t v = 0; v < views.size(); ++v) {
        rhs += eq.view_rhs[v][c];
        observed_sq += eq.view_observed_sq[v][c];
      }
      EXPECT_LT((rhs - eq.rhs[c]).norm(), 1e-9 * eq.rhs[c].norm()) << "channel " << c;
      EXPECT_NEAR(observed_sq, eq.observed_sq[c], 1e-9 * eq.observed_sq[c]);
    }
    for (LightCache* cache : {&a, &b}) {
      for (SampledPixel& p : cache->pixels)
        p.observed = p.observed.cwiseProduct(scale[p.view].cast<float>());
    }
    const NormalEquations scaled = NormalEquations::FromCaches(a, b, 0.5);
    eq.ScaleObserved(scale);
    for (int c = 0; c < 3; ++c) {
      EXPECT_LT((eq.rhs[c] - scaled.rhs[c]).norm(), 1e-5 * scaled.rhs[c].norm()) << c;
      EXPECT_NEAR(eq.observed_sq[c], scaled.observed_sq[c], 1e-5 * scaled.observed_sq[c]) << c;
    }
  }
}

// Per-view camera gains (exposure and white balance): training views of one lighting, each
// multiplied by its own gain, give back the gains (relative to their geometric mean) and the
// lights, and fit better than without the exposure step; views of equal exposure give gains of
// 1; the same with one or two threads.
TEST(EstimateLights, RecoversPerViewExposureAndWhiteBalance) {
  SmallScene s;
  VoxelLightGrid truth = s.grid;
  truth.intensity[4].setZero();
  const Scene lit = s.Lit(&truth);
  const std::vector<PosedImage> plain = TrainingViews(lit);
  const std::vector<Eigen::Vector3d> gains = {
      {0.7, 0.75, 0.65}, {1.0, 1.0, 1.0}, {1.45, 1.3, 1.55}};
  std::vector<PosedImage> exposed = plain;
  ASSERT_EQ(exposed.size(), gains.size());
  Eigen::Vector3d mean_log = Eigen::Vector3d::Zero();
  for (size_t v = 0; v < exposed.size(); ++v) {
    for (Eigen::Vector3f& p : exposed[v].image.pixels()) p = p.cwiseProduct(gains[v].cast<float>());
    mean_log += gains[v].array().log().matrix() / static_cast<double>(gains.size());
  }
  const Eigen::Vector3d geometric_mean = mean_log.array().exp().matrix();
  LightEstimationOptions o = SmallOptions();
  o.rounds = 2;
  o.exposure = "white-balance";
  std::vector<LightEstimate> results;
  for (int threads : {1, 2}) {
    SetThreadCount(threads);
    results.push_back(EstimateLights(lit, exposed, o, 1));
  }
  SetThreadCount(0);
  const LightEstimate& e = results[0];
  ASSERT_EQ(e.exposure_gains.size(), gains.size());
  for (size_t v = 0; v < gains.size(); ++v) {
    const Eigen::Vector3d want = gains[v].cwiseQuotient(geometric_mean);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(e.exposure_gains[v][c] / want[c], 1.0, 0.04)
          << "view " << v << " channel " << c << ": " << e.exposure_gains[v].transpose();
    }
    EXPECT_EQ(e.exposure_gains[v], results[1].exposure_gains[v]) << "thread count changed it";
    std::cout << "view " << v << ": gain " << e.exposure_gains[v].transpose() << ", truth "
              << want.transpose() << "\n";
  }
  EXPECT_EQ(StrongestVoxel(e.lights), 22);
  // The lights carry the gains' geometric mean.
  EXPECT_NEAR(e.lights.TotalPowerLuminance() /
                  (Luminance(truth.Power(22)) * Luminance(geometric_mean.cast<float>())),
              1.0, 0.25);
  o.exposure = "none";
  const LightEstimate without = EstimateLights(lit, exposed, o, 1);
  std::cout << "training RMSE of the cache: with the gains " << e.train_rmse << ", without "
            << without.train_rmse << "\n";
  EXPECT_LT(e.train_rmse, 0.8 * without.train_rmse);
  // Equal exposures: gains of 1 (one gain per view).
  o.exposure = "gain";
  const LightEstimate equal = EstimateLights(lit, plain, o, 1);
  ASSERT_EQ(equal.exposure_gains.size(), plain.size());
  for (const Eigen::Vector3d& g : equal.exposure_gains) {
    EXPECT_NEAR(g[0], 1.0, 0.03) << g.transpose();
    EXPECT_EQ(g[0], g[1]);
    EXPECT_EQ(g[0], g[2]);
  }
}

// The result carries the estimate's active_fraction, so that lights.json, the viewer and the
// reports count the active voxels as the estimate did (without refinement as well as with it).
TEST(EstimateLights, TheResultCarriesTheActiveFraction) {
  SmallScene s;
  VoxelLightGrid truth = s.grid;
  truth.intensity[4].setZero();
  const Scene lit = s.Lit(&truth);
  LightEstimationOptions o = SmallOptions();
  o.refine_levels = 0;
  o.active_fraction = 0.02;
  const LightEstimate e = EstimateLights(lit, TrainingViews(lit), o, 1);
  EXPECT_EQ(e.lights.active_fraction, 0.02);
  EXPECT_EQ(static_cast<size_t>(e.active_voxels), e.lights.ActiveVoxels().size());
}

// Adaptive refinement: a light in a voxel of a grid twice as fine, off the centre of the coarse
// voxel that holds it. One refinement level puts the strongest voxel of the 6^3 result on it and
// fits the training pixels better than the coarse grid alone.
TEST(EstimateLights, RefinementPutsALightInItsFinerVoxel) {
  SmallScene s;
  VoxelLightGrid truth = MakeVoxelGrid(s.geometry, 6, kSmallInset);
  const int light =
      2 + 6 * 3 + 36 * 5;  // centre (-0.17, 0.17, 1.83); the coarse voxel's is (0, 0, 1.67)
  truth.intensity[light] = Eigen::Vector3f(2.0f, 1.5f, 1.0f);
  truth.weights[light] = {0.1f, 0.1f, 0.1f, 0.1f, 0.0f, 1.0f};
  const Scene lit = s.Lit(&truth);
  const std::vector<PosedImage> views = TrainingViews(lit);
  LightEstimationOptions o = SmallOptions();
  o.rounds = 1;
  const LightEstimate coarse = EstimateLights(lit, views, o, 1);
  o.refine_levels = 1;
  o.refine_spp = 16;
  const LightEstimate fine = EstimateLights(lit, views, o, 1);
  ASSERT_EQ(coarse.lights.VoxelCount(), 27);
  ASSERT_EQ(fine.lights.VoxelCount(), 216);
  ASSERT_GE(fine.rounds.size(), 2u);
  EXPECT_EQ(fine.rounds.back().level, 1);
  EXPECT_GT(fine.rounds.back().candidates, 0);
  EXPECT_LT(fine.rounds.back().candidates, 216)
      << "refinement traces only the voxels near the lights";
  EXPECT_EQ(StrongestVoxel(fine.lights), light) << "the light is in the wrong finer voxel";
  EXPECT_LT((fine.lights.PowerCentroid() - truth.VoxelCenter(light)).norm(), 0.5 * 2.0 / 6.0)
      << "centroid " << fine.lights.PowerCentroid().transpose();
  // Judged by renders of the estimates against the training images (the noise of both taken out).
  const auto error = [&](const VoxelLightGrid& lights) {
    const PathTracer tracer(s.Lit(&lights));
    double sum = 0.0;
    for (size_t i = 0; i < views.size(); ++i)
      sum += CompareRender(tracer, views[i], o, 64, 9 + i).rmse_bias;
    return sum / views.size();
  };
  const double coarse_error = error(coarse.lights), fine_error = error(fine.lights);
  std::printf("training views' error: coarse %.4f, refined %.4f; %d candidate voxels\n",
              coarse_error, fine_error, fine.rounds.back().candidates);
  EXPECT_LT(fine_error, 0.75 * coarse_error);
}

// A finer level that fits the pixels worse than the coarse grid is dropped: here only the
// strongest coarse voxel is split (refine_fraction 1), so the finer grid has no voxel near the
// second light (70 % of the first's power, two coarse voxels below it) and its data term is far
// larger. The coarse result stands, as good as without refinement, and a note says why.
TEST(EstimateLights, AFinerLevelThatFitsWorseLeavesTheCoarseResult) {
  SmallScene s;
  const Scene lit = s.Lit();
  const std::vector<PosedImage> views = TrainingViews(lit);
  LightEstimationOptions o = SmallOptions();
  o.rounds = 1;
  o.softening = 0.0;  // the scene's lights are points: the coarse grid fits them closely
  const LightEstimate coarse = EstimateLights(lit, views, o, 1);
  o.refine_levels = 1;
  o.refine_spp = 8;
  o.refine_fraction = 1.0;
  const LightEstimate e = EstimateLights(lit, views, o, 1);
  ASSERT_GE(e.rounds.size(), 2u) << "a coarse round, then the finer level";
  double finer_data = -1.0;
  for (const LightRound& r : e.rounds) {
    if (r.level == 1) finer_data = r.solve.data;
  }
  ASSERT_GE(finer_data, 0.0) << "the finer level was not tried";
  EXPECT_GT(finer_data, 2.0 * coarse.rounds.back().solve.data);
  EXPECT_EQ(e.lights.VoxelCount(), 27) << "the finer grid was kept although it fits worse";
  EXPECT_EQ(e.active_voxels, coarse.active_voxels);
  ASSERT_EQ(e.notes.size(), 1u);
  EXPECT_NE(e.notes[0].find("fitted the pixels worse"), std::string::npos) << e.notes[0];
  // The pixels are the same (pixels_per_view 300 < refine_coarse_pixels): the same result.
  EXPECT_EQ(e.lights.intensity, coarse.lights.intensity);
  EXPECT_NEAR(e.train_rmse, coarse.train_rmse, 1e-12);
}

// Same seed, same lights whatever the thread count: the traces, the normal equations (with the
// growing pass's kept block), the solve's channels in parallel.
TEST(EstimateLights, SameSeedSameLightsWithOneOrTwoThreads) {
  SmallScene s;
  VoxelLightGrid truth = MakeVoxelGrid(s.geometry, 6, kSmallInset);
  const int light = 2 + 6 * 3 + 36 * 5;
  truth.intensity[light] = Eigen::Vector3f(2.0f, 1.5f, 1.0f);
  truth.weights[light] = {0.1f, 0.1f, 0.1f, 0.1f, 0.0f, 1.0f};
  const Scene lit = s.Lit(&truth);
  const std::vector<PosedImage> views = TrainingViews(lit);
  LightEstimationOptions o = SmallOptions();
  o.refine_levels = 1;
  o.refine_spp = 8;
  std::vector<LightEstimate> results;
  for (int threads : {1, 2}) {
    SetThreadCount(threads);
    results.push_back(EstimateLights(lit, views, o, 4));
  }
  SetThreadCount(0);
  ASSERT_GE(results[0].rounds.size(), 3u) << "a coarse round, the finer level and its growing pass";
  EXPECT_GT(results[0].active_voxels, 0);
  ASSERT_EQ(results[0].lights.VoxelCount(), results[1].lights.VoxelCount());
  for (int j = 0; j < results[0].lights.VoxelCount(); ++j) {
    ASSERT_EQ(results[0].lights.intensity[j], results[1].lights.intensity[j])
        << "voxel " << j;  // bit for bit
    ASSERT_EQ(results[0].lights.weights[j], results[1].lights.weights[j]) << "voxel " << j;
  }
  EXPECT_EQ(results[0].train_rmse, results[1].train_rmse);
}

// The chroma term: the solve's cost never rises with it (its L step minimises the coupled
// channels exactly), and the lit voxels' colours move toward the target chromaticity as its
// weight grows: the scene's two lights are warm (2, 1.5, 1) and blue (0.3, 0.3, 0.6).
TEST(SolveLights, TheChromaTermPullsTheVoxelColoursTogether) {
  SmallScene s;
  const std::vector<PosedImage> views = TrainingViews(s.Lit());
  const NormalEquations eq = SmallEquations(s, views, 0.0);
  std::vector<double> spread;
  for (const double weight : {0.0, 1.0, 100.0}) {
    LightEstimationOptions o;
    o.chroma_weight = weight;
    const LightCost cost(eq, o.penalty_weight, o.penalty_epsilon, weight);
    VoxelLightGrid grid = s.grid;
    for (auto& l : grid.intensity) l.setZero();
    const SolveReport r = SolveLights(eq, o, &grid);
    for (size_t i = 1; i < r.history.size(); ++i)
      EXPECT_LE(r.history[i], r.history[i - 1] * (1.0 + 1e-9))
          << "weight " << weight << " it " << i;
    // The power-weighted mean distance of the lit voxels' chromaticities from the target.
    const Eigen::Vector3d m = cost.chroma_target();
    double sum = 0.0, total = 0.0;
    for (int j = 0; j < grid.VoxelCount(); ++j) {
      const Eigen::Vector3d l = grid.intensity[j].cast<double>();
      if (l.sum() <= 0.0) continue;
      const double p = Luminance(grid.Power(j));
      sum += p * (l / l.sum() - m).norm();
      total += p;
    }
    ASSERT_GT(total, 0.0) << weight;
    spread.push_back(sum / total);
    std::printf("chroma weight %g: colour spread %.4f, data %.5f\n", weight, spread.back(), r.data);
  }
  EXPECT_GT(spread[0], 0.05) << "the two lights' colours differ: the test needs them to";
  EXPECT_LT(spread[1], spread[0]);
  EXPECT_LT(spread[2], 0.25 * spread[0]);
}

// The solve's moves: on equations of one voxel light, a start with the light in the neighbouring
// voxel (a local minimum of the log penalty) ends with it in its own voxel, at the cost of the
// truth or below.
TEST(SolveLights, MovesALightIntoItsVoxel) {
  SmallScene s;
  VoxelLightGrid truth = s.grid;
  truth.intensity[4].setZero();
  const Scene lit = s.Lit(&truth);
  const std::vector<PosedImage> views = TrainingViews(lit);
  const NormalEquations eq = SmallEquations(s, views, 0.0);
  LightEstimationOptions o;
  o.penalty_weight = 1e-3;
  const LightCost cost(eq, o.penalty_weight, o.penalty_epsilon);
  VoxelLightGrid start = truth;
  // One voxel over in x: a plain solve stays there (cost 1.5x the truth's); starting one voxel
  // over in y instead, a plain solve found the way on its own with clang (not with GCC).
  std::swap(start.intensity[22], start.intensity[21]);
  std::swap(start.weights[22], start.weights[21]);
  o.move_voxels = 8;
  o.move_iterations = 15;
  for (int passes : {0, 2}) {
    o.move_passes = passes;
    VoxelLightGrid grid = start;
    const SolveReport r = SolveLights(eq, o, &grid);
    const int strongest = StrongestVoxel(grid);
    if (passes == 0) {
      EXPECT_NE(strongest, 22)
          << "without moves the start should stay stuck (else this test proves nothing)";
    } else {
      EXPECT_EQ(strongest, 22);
      EXPECT_GE(r.moves, 1);
      EXPECT_LE(r.cost, cost.Evaluate(LightCost::Pack(truth)) * 1.001);
    }
  }
}

TEST(EstimateLights, PenaltyZeroAndHugeStayFinite) {
  SmallScene s;
  const Scene lit = s.Lit();
  const std::vector<PosedImage> views = Render(lit, {CornellLightViews(16, 12)[0]}, 16);
  LightEstimationOptions o;
  o.grid = 3;
  o.boundary_inset = kSmallInset;
  o.pixels_per_view = 150;
  o.rounds = 1;
  o.paths.spp = 4;
  o.refine_levels = 0;  // the counts are compared on one grid (refinement runs only with w > 0)
  int previous_active = 1 << 30;
  for (double w : {0.0, 1e-3, 1e6}) {
    o.penalty_weight = w;
    const LightEstimate e = EstimateLights(lit, views, o, 2);
    for (int j = 0; j < 27; ++j) {
      ASSERT_TRUE(e.lights.intensity[j].allFinite()) << "w " << w;
      for (float l : e.lights.weights[j]) ASSERT_TRUE(std::isfinite(l) && l >= 0.0f && l <= 1.0f);
    }
    EXPECT_LE(e.active_voxels, previous_active) << "w " << w;
    previous_active = e.active_voxels;
    if (w >= 1e6) {
      EXPECT_EQ(e.active_voxels, 0) << "a huge penalty switches every voxel off";
    }
  }
}

// A voxel that no path reaches (inside a closed box): a zero column of the Gram matrix. It stays
// dark and nothing becomes NaN.
TEST(EstimateLights, UnreachableVoxelStaysDark) {
  SmallScene s;
  Scene lit = s.geometry;
  SyntheticScene closed;
  closed.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(-0.2, -0.2, 0.2), Eigen::Vector3d(0.2, 0.2, 0.5)),
       Eigen::Vector3f::Constant(0.5f)});
  SceneMesh box;
  box.name = "closed box";
  box.mesh = closed.ToMesh(1);
  box.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Constant(0.5f));
  lit.meshes.push_back(box);
  lit.voxel_lights = s.grid;
  lit.voxel_lights->intensity[4].setZero();  // (0, 0, 0.33) is inside the closed box
  const std::vector<PosedImage> views = Render(lit, {CornellLightViews(16, 12)[0]}, 16);
  LightEstimationOptions o;
  o.grid = 3;
  o.boundary_inset = kSmallInset;
  o.pixels_per_view = 150;
  o.rounds = 1;
  o.paths.spp = 4;
  const LightEstimate e = EstimateLights(lit, views, o, 2);
  EXPECT_EQ(e.lights.intensity[4], Eigen::Vector3f::Zero());
  for (int j = 0; j < 27; ++j) EXPECT_TRUE(e.lights.intensity[j].allFinite());
}

// A box lit through an opening in its ceiling by a light above it, outside the mesh's bounding box
// (as a real room is lit by lights that were never scanned). With grid_margin the grid reaches
// the light: its voxel holds the power, and novel views are within 5 % (the grid over the box puts
// the light under the ceiling, which lights the walls' tops the ceiling shades).
// A 1 m box open at the front (y = -0.5); the ceiling (z = 1) has a 0.4 m hole in its middle, or
// there is none.
Scene BoxWithAnOpenCeiling(bool ceiling = true) {
  Scene box;
  const auto quad = [&](const std::string& name, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                        const Eigen::Vector3f& c, const Eigen::Vector3f& d,
                        const Eigen::Vector3f& albedo) {
    box.meshes.push_back(MakeQuad(name, a, b, c, d, albedo));
  };
  const Eigen::Vector3f white(0.7f, 0.7f, 0.7f), red(0.6f, 0.1f, 0.1f), green(0.1f, 0.5f, 0.1f);
  const float h = 0.5f, o = 0.2f;
  quad("floor", {-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}, white);
  quad("back", {-h, h, 0}, {h, h, 0}, {h, h, 1}, {-h, h, 1}, white);
  quad("red", {-h, -h, 0}, {-h, h, 0}, {-h, h, 1}, {-h, -h, 1}, red);
  quad("green", {h, -h, 0}, {h, -h, 1}, {h, h, 1}, {h, h, 0}, green);
  if (!ceiling) return box;
  quad("ceiling front", {-h, -h, 1}, {-h, -o, 1}, {h, -o, 1}, {h, -h, 1}, white);
  quad("ceiling back", {-h, o, 1}, {-h, h, 1}, {h, h, 1}, {h, o, 1}, white);
  quad("ceiling left", {-h, -o, 1}, {-h, o, 1}, {-o, o, 1}, {-o, -o, 1}, white);
  quad("ceiling right", {o, -o, 1}, {o, o, 1}, {h, o, 1}, {h, -o, 1}, white);
  return box;
}

// Three training views into the box and two novel ones.
std::vector<PosedView> BoxViews() {
  const CameraIntrinsics k = CameraIntrinsics::FromHorizontalFov(40, 30, 60.0);
  std::vector<PosedView> cameras;
  for (const auto& [eye, target] : std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>{
           {{0.0, -1.1, 0.55}, {0.0, 0.5, 0.5}},     // training
           {{-0.3, -1.0, 0.8}, {0.2, 0.5, 0.3}},     // training
           {{0.3, -1.0, 0.3}, {-0.2, 0.5, 0.7}},     // training
           {{0.35, -0.9, 0.6}, {-0.3, 0.5, 0.5}},    // novel
           {{-0.4, -0.8, 0.35}, {0.3, 0.5, 0.85}}})  // novel
    cameras.push_back({k, LookAt(eye, target)});
  return cameras;
}

// BoxViews rendered: the training views and the novel ones.
std::pair<std::vector<PosedImage>, std::vector<PosedImage>> RenderBoxViews(const Scene& lit,
                                                                           int spp) {
  const std::vector<PosedImage> all = Render(lit, BoxViews(), spp);
  return {{all.begin(), all.begin() + 3}, {all.begin() + 3, all.end()}};
}

LightEstimationOptions OpenBoxOptions() {
  LightEstimationOptions options;
  options.pixels_per_view = 600;
  options.refine_levels = 0;
  return options;
}

// Mean noise-corrected relative RMSE over `novel` of `lit`'s geometry lit by `lights` alone.
double NovelViewsError(const Scene& lit, const VoxelLightGrid& lights,
                       const std::vector<PosedImage>& novel, const LightEstimationOptions& options,
                       int spp) {
  Scene model = WithoutLights(lit);
  model.voxel_lights = lights;
  const PathTracer tracer(model);
  double sum = 0.0;
  for (size_t i = 0; i < novel.size(); ++i)
    sum += CompareRender(tracer, novel[i], options, spp, 7 + i).rmse_bias;
  return sum / novel.size();
}

TEST(EstimateLights, TheExtendedGridFindsALightOutsideTheScan) {
  Scene lit = BoxWithAnOpenCeiling();
  // The light: a 4 cm square at z = 1.177 (a voxel centre of the extended grid), facing down.
  SceneMesh light;
  light.name = "light";
  const float l = 0.02f, z = 1.177f;
  light.mesh.vertices = {{-l, -l, z}, {l, -l, z}, {l, l, z}, {-l, l, z}};
  light.mesh.faces = {{0, 2, 1}, {0, 3, 2}};
  light.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Zero());
  light.emission = Eigen::Vector3f(1500.0f, 1250.0f, 1000.0f);
  lit.meshes.push_back(light);
  const auto [train, novel] = RenderBoxViews(lit, 512);
  LightEstimationOptions options = OpenBoxOptions();
  const auto novel_error = [&](const VoxelLightGrid& lights) {
    return NovelViewsError(lit, lights, novel, options, 256);
  };
  const LightEstimate inside = EstimateLights(lit, train, options, 5);
  options.grid_margin = 0.2;
  const LightEstimate extended = EstimateLights(lit, train, options, 5);
  const double inside_error = novel_error(inside.lights),
               extended_error = novel_error(extended.lights);
  const Eigen::Vector3d centroid = extended.lights.PowerCentroid();
  std::printf("novel views: grid over the box %.4f, extended grid %.4f; centroid %.3f %.3f %.3f\n",
              inside_error, extended_error, centroid.x(), centroid.y(), centroid.z());
  {
    // The best a voxel light can do: one point at the light's place, facing down.
    VoxelLightGrid oracle = extended.lights;
    for (Eigen::Vector3f& i : oracle.intensity) i.setZero();
    const int j = 3 + 7 * 3 + 49 * 6;
    ASSERT_LT((oracle.VoxelCenter(j) - Eigen::Vector3d(0, 0, 1.177)).norm(), 1e-3);
    oracle.intensity[j] = Eigen::Vector3f(1500.0f, 1250.0f, 1000.0f) * 0.0016f;
    oracle.weights[j] = {0, 0, 0, 0, 0, 1};
    std::printf("a point light at the light's place: novel views %.4f\n", novel_error(oracle));
  }
  EXPECT_GT(extended.lights.bounds.max().z(), 1.177) << "the grid does not reach the light";
  EXPECT_GT(centroid.z(), 1.05) << "the power is not above the ceiling";
  EXPECT_LT(std::hypot(centroid.x(), centroid.y()), 0.15);
  EXPECT_LT(extended_error, 0.05);
  EXPECT_GT(inside_error, 2.0 * extended_error) << "the grid over the box alone did as well";
}

// The box without its ceiling, lit from beyond the scan by the sky: a distant light, brightest from
// above, weaker through the open front (rendered by our tracer). The voxels over the box alone
// cannot stand for it; with `distant` the estimate puts most of the light there, from above, and
// novel views are within 5 %.
TEST(EstimateLights, TheDistantLightFindsTheSkyBeyondTheScan) {
  Scene lit = BoxWithAnOpenCeiling(false);
  VoxelLightGrid sky = MakeVoxelGrid(lit, 1, 0.5);
  sky.distant = true;
  sky.distant_intensity = Eigen::Vector3f(3.0f, 2.8f, 2.4f);
  sky.distant_weights = {0.0f, 0.0f, 0.0f, 0.3f, 1.0f, 0.0f};  // from +z, and from -y (the front)
  lit.voxel_lights = sky;
  const auto [train, novel] = RenderBoxViews(lit, 256);
  LightEstimationOptions options = OpenBoxOptions();
  const auto novel_error = [&](const VoxelLightGrid& lights) {
    return NovelViewsError(lit, lights, novel, options, 128);
  };
  Scene geometry = WithoutLights(lit);
  geometry.voxel_lights.reset();
  const LightEstimate voxels = EstimateLights(geometry, train, options, 5);
  options.distant = true;
  const LightEstimate distant = EstimateLights(geometry, train, options, 5);
  const double voxels_error = novel_error(voxels.lights),
               distant_error = novel_error(distant.lights);
  const auto& w = distant.lights.distant_weights;
  std::printf(
      "novel views: voxels only %.4f, with the distant light %.4f; distant share %.3f, L_d %.3f "
      "%.3f %.3f, lambda_d %.2f %.2f %.2f %.2f %.2f %.2f\n",
      voxels_error, distant_error, distant.distant_share, distant.lights.distant_intensity.x(),
      distant.lights.distant_intensity.y(), distant.lights.distant_intensity.z(), w[0], w[1], w[2],
      w[3], w[4], w[5]);
  ASSERT_TRUE(distant.lights.distant);
  EXPECT_FALSE(voxels.lights.distant);
  EXPECT_GT(distant.distant_share, 0.8);
  EXPECT_EQ(*std::max_element(w.begin(), w.end()), w[4]) << "the sky is not brightest from above";
  EXPECT_LT(distant_error, 0.05);
  EXPECT_GT(voxels_error, 2.0 * distant_error) << "the voxels alone did as well";
}

// A light that the views see only through bounces: it faces up, the cameras look down at the
// floor. Its power is still found in the upper half of the room.
TEST(EstimateLights, FindsALightSeenOnlyThroughBounces) {
  SmallScene s;
  VoxelLightGrid truth = s.grid;
  truth.intensity[4].setZero();
  truth.weights[22] = {0, 0, 0, 0, 1, 0};  // +z only: lights the ceiling
  const Scene lit = s.Lit(&truth);
  const CameraIntrinsics k = CameraIntrinsics::FromHorizontalFov(20, 15, 60.0);
  const std::vector<PosedView> floor_views = {{k, LookAt({0.0, -0.9, 1.0}, {0.0, 0.3, 0.0})},
                                              {k, LookAt({0.8, 0.8, 1.0}, {-0.2, -0.2, 0.0})}};
  const std::vector<PosedImage> views = Render(lit, floor_views, 64);
  LightEstimationOptions o = SmallOptions();
  o.rounds = 2;
  for (int levels : {0, 1}) {  // the coarse grid, then with adaptive refinement
    o.refine_levels = levels;
    const LightEstimate e = EstimateLights(lit, views, o, 2);
    double upper = 0.0, total = 0.0;
    for (int j = 0; j < e.lights.VoxelCount(); ++j) {
      const double p = Luminance(e.lights.Power(j));
      total += p;
      if (e.lights.VoxelCenter(j).z() > 1.0) upper += p;
    }
    ASSERT_GT(total, 0.0) << "refine_levels " << levels;
    EXPECT_GT(upper / total, 0.5) << "refine_levels " << levels;
  }
}

// Albedo x light scale: the albedo is given, so halving it doubles the estimated light (in
// direct light, where the prediction is linear in the albedo).
TEST(EstimateLights, AlbedoFixesTheScaleGauge) {
  SmallScene s;
  const Scene lit = s.Lit();
  const std::vector<PosedImage> views =
      Render(lit, {CornellLightViews(16, 12)[0], CornellLightViews(16, 12)[1]}, 32, 2);
  LightEstimationOptions o;
  o.grid = 3;
  o.boundary_inset = kSmallInset;
  o.pixels_per_view = 150;
  o.rounds = 1;
  o.paths.max_depth = 2;
  const auto total_power = [&](const Scene& scene) {
    return EstimateLights(scene, views, o, 3).lights.TotalPowerLuminance();
  };
  Scene half = lit;
  for (auto& a : half.meshes[0].albedo.values) a *= 0.5f;
  if (half.meshes[0].albedo.kind == SurfaceAlbedo::Kind::kConstant)
    half.meshes[0].albedo.constant *= 0.5f;
  EXPECT_NEAR(total_power(half) / total_power(lit), 2.0, 0.1);
}

TEST(EstimateLights, MasksSaturatedAndEmitterPixels) {
  SmallScene s;
  const Scene lit = s.Lit();
  std::vector<PosedImage> views = Render(lit, {CornellLightViews(16, 12)[0]}, 16);
  // A burnt-out patch (above the saturation level, which nothing else reaches) and an
  // emitter-bright spot.
  for (int v = 2; v < 5; ++v) {
    for (int u = 2; u < 6; ++u) views[0].image(u, v) = Eigen::Vector3f::Constant(40.0f);
  }
  const PathTracer tracer(s.geometry);
  LightEstimationOptions o;
  o.saturation = 30.0;
  PixelMaskCounts counts;
  Image<uint8_t> valid = ValidPixels(tracer, views[0], o, &counts);
  EXPECT_EQ(counts.saturated, 12u);
  EXPECT_EQ(valid(3, 3), 0);
  EXPECT_EQ(counts.valid + counts.saturated + counts.emitter + counts.miss, 16u * 12u);
  views = Render(lit, {CornellLightViews(16, 12)[0]}, 16);
  views[0].image(12, 8) = Eigen::Vector3f::Constant(500.0f);
  o.saturation = 0.0;
  valid = ValidPixels(tracer, views[0], o, &counts);
  EXPECT_EQ(counts.emitter, 9u) << "the bright pixel and its 8 neighbours";
  EXPECT_EQ(valid(12, 8), 0);
  EXPECT_EQ(valid(11, 7), 0);
}

// The tiles of CompareRender: a render against a reference 1.2 times too bright has a relative
// error of 0.2 / 1.2 whatever the tile size; 4 x 4 tiles keep that error and divide the noise
// by about 4 (pixels are sampled independently), so the noise-corrected error is steadier. (The
// Cornell box with its area light: voxel lights, points, give fireflies whose heavy tail makes any
// noise estimate from a few samples unreliable.)
TEST(CompareRender, TilesKeepTheErrorAndShrinkTheNoise) {
  const PathTracer lit(MakeCornellBoxScene());
  const PosedView view = CornellLightViews(32, 24)[0];
  LightEstimationOptions o;
  RenderOptions half = o.paths;
  half.spp = 128;
  const ImageRgb a = lit.Render(view, half, 7).radiance, b = lit.Render(view, half, 8).radiance;
  PosedImage reference{view, ImageRgb(a.width(), a.height())};
  double noise = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    reference.image.data()[i] = 0.6f * (a.data()[i] + b.data()[i]);
    noise += 0.25 * (1.2 * (a.data()[i] - b.data()[i])).cast<double>().squaredNorm();
  }
  const double reference_noise_rms = std::sqrt(noise / (3.0 * a.size()));
  const ViewError pixels = CompareRender(lit, reference, o, 16, 3, reference_noise_rms, nullptr, 1);
  const ViewError tiles = CompareRender(lit, reference, o, 16, 3, reference_noise_rms, nullptr, 4);
  std::printf("pixels: rmse %.4f noise %.4f bias %.4f; 4x4 tiles: rmse %.4f noise %.4f bias %.4f\n",
              pixels.rmse, pixels.noise, pixels.rmse_bias, tiles.rmse, tiles.noise,
              tiles.rmse_bias);
  EXPECT_EQ(tiles.pixels, pixels.pixels);
  EXPECT_GT(pixels.noise, 0.0);
  EXPECT_LT(tiles.noise, pixels.noise / 2.5);
  EXPECT_GT(tiles.noise, pixels.noise / 6.0);
  EXPECT_NEAR(tiles.rmse_bias, 0.2 / 1.2, 0.02);
  EXPECT_NEAR(pixels.rmse_bias, 0.2 / 1.2, 0.05);
}

TEST(EstimateLights, BadInputIsAClearError) {
  SmallScene s;
  const PathTracer tracer(s.geometry);
  LightEstimationOptions o;
  std::vector<PosedImage> views = Views({CornellLightViews(16, 12)[0]});
  views[0].image = ImageRgb(8, 6);
  try {
    SamplePixels(tracer, views, o, 1);
    FAIL() << "a size mismatch was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("image 8x6 but intrinsics say 16x12"), std::string::npos)
        << e.what();
  }
  views = Views({CornellLightViews(16, 12)[0]});
  views[0].image(3, 4) = Eigen::Vector3f(NAN, 0, 0);
  EXPECT_THROW(SamplePixels(tracer, views, o, 1), Error);
  EXPECT_THROW(SamplePixels(tracer, {}, o, 1), Error);
  o.paths.spp = 3;
  EXPECT_THROW(o.Validate(), Error);
  o.paths.spp = 4;
  o.refine_spp = 5;  // odd: no two halves
  EXPECT_THROW(o.Validate(), Error);
  o.refine_spp = 0;
  o.refine_levels = 6;  // a 448^3 grid
  EXPECT_THROW(o.Validate(), Error);
  o.refine_levels = 1;
  o.refine_fraction = std::nan("");
  EXPECT_THROW(o.Validate(), Error);
  o.refine_fraction = 0.05;
  EXPECT_NO_THROW(o.Validate());
}

// The memory cap. The dense normal equations are refused before any path is traced;
// the cache is stopped while it grows; the same estimate goes through under a sufficient cap.
TEST(EstimateLights, MemoryCapIsAClearError) {
  SmallScene s;
  const std::vector<PosedImage> views = Render(s.Lit(), CornellLightViews(16, 12), 4);
  LightEstimationOptions o;
  o.paths.spp = 4;
  o.rounds = 1;
  o.pixels_per_view = 150;
  o.refine_levels = 0;  // the coarse grid's caps first; the refinement level's at the end
  o.grid = 20;          // 48000 parameters: 2 x 3 dense 48000^2 Gram matrices = 110 GB
  EXPECT_NEAR(NormalEquationsBoundBytes(20), 2.0 * 3.0 * 48000.0 * 48000.0 * 8.0, 1.0);
  try {
    EstimateLights(s.geometry, views, o, 1);
    FAIL() << "a 20^3 grid was accepted under a 4000 MB cap";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("normal equations of a 20^3 voxel grid"), std::string::npos) << what;
    EXPECT_NE(what.find("memory cap of 4000 MB"), std::string::npos) << what;
  }
  // grid 3: 162 parameters, 1.3 MB of equations; the cache of 900 pixels with up to 162 entries
  // of 16 bytes each needs up to 2.3 MB per trace.
  o.grid = 3;
  o.boundary_inset = kSmallInset;
  const PathTracer tracer(s.geometry);
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, o, 1);
  const LightCache full = TraceLightCache(tracer, MakeVoxelGrid(s.geometry, 3, kSmallInset),
                                          VoxelSplitting{}, views, pixels, o, 1);
  ASSERT_GT(full.NonZeros(), 10000u);
  o.memory_cap =
      1.0 + 0.5 * static_cast<double>(full.Bytes()) / 1e6;  // equations fit, caches do not
  try {
    EstimateLights(s.geometry, views, o, 1);
    FAIL() << "a cache of " << full.Bytes() << " bytes was accepted under a cap of " << o.memory_cap
           << " MB";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("path-coefficient cache outgrew the memory cap"),
              std::string::npos)
        << e.what();
  }
  o.memory_cap = 1.5 + 4.0 * static_cast<double>(full.Bytes()) / 1e6;
  const LightEstimate estimate = EstimateLights(s.geometry, views, o, 1);
  EXPECT_GT(Luminance(estimate.lights.Power(StrongestVoxel(estimate.lights))), 0.0);
  // The finer level's dense equations are refused before it traces, naming the option to lower.
  o.refine_levels = 1;
  o.refine_fraction = 0.0;  // every lit coarse voxel is split: 6^3 = 216 candidates, 28 MB
  try {
    EstimateLights(s.geometry, views, o, 1);
    FAIL() << "a refinement level over the cap of " << o.memory_cap << " MB was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("normal equations of refinement level 1"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("refine_max_voxels"), std::string::npos) << e.what();
  }
  o.memory_cap = 0.5;
  EXPECT_THROW(o.Validate(), Error);
}

}  // namespace
}  // namespace genscene::inverse
