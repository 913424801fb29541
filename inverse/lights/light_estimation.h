// Light estimation (issue 7; the paper's section II and Fig. 3): voxel lights (core/light_set.h)
// from known geometry and albedo and posed linear images.
//
// Build / solve / report:
//  1. SamplePixels picks random valid pixels per view (the camera ray hits a reflecting surface;
//     saturated pixels and pixels that see an emitter directly are masked).
//  2. TraceLightCache traces camera paths through them once and, at every path vertex, splits: a
//     shadow ray to every voxel (or to voxels drawn in proportion to the current estimate). It
//     records the coefficient that multiplies each product x_jk = L_j lambda_jk, so that the
//     predicted pixel is P_i = sum_jk a_ijk (*) x_jk (per channel; path throughput x BRDF x
//     cosine / r^2 x visibility x the voxel's face projection max(0, w . d_k)).
//  3. NormalEquations reduces the cache to G_c = sum_i a_ic a_ic^T, b_c = sum_i a_ic I_ic: one
//     cost evaluation is then O(parameters^2), independent of the number of pixels. Two
//     independent halves of the paths give the unbiased cross product instead (FromCaches).
//  4. LightCost / SolveLights minimise
//         f(L, lambda) = (1/E) sum_i sum_c (P_ic - I_ic)^2 + w sum_j log(1 + s_j / eps),
//     E = sum_i sum_c I_ic^2 (so the data term is the squared relative residual), s_j = sum_c
//     L_jc, eps = penalty_epsilon * s_ref (s_ref: the summed intensity of the best uniform
//     lighting), L >= 0, 0 <= lambda <= 1 (the upper bound fixes the L x lambda scale gauge).
//     The log term charges a voxel's first activation and then plateaus (the paper's activation
//     penalty). The solve alternates between L and lambda; each block is a bound-constrained
//     quadratic solved exactly by coordinate descent, with the log term majorised by its tangent
//     (reweighted L1), so the true cost never increases.
//  5. EstimateLights runs rounds: trace, solve, then re-trace with voxel sampling proportional to
//     the estimated powers (the paper's remedy for starting without the right sampling
//     distribution), accumulating the normal equations, until the voxel powers stop changing.
//     Drawn voxels are used only beyond split_depth; with the default (every vertex connects to
//     every voxel) a later round adds fresh paths, not a better sampling distribution.
//  6. Adaptive refinement (refine_levels): a grid twice as fine, traced and solved over only the
//     finer voxels near the voxels that hold light, with growing passes that add the neighbours of
//     the finer solution's lights. A point per coarse voxel cannot hold an extended light (a 0.5 m
//     ceiling light: 5-7 % training error at best on 7^3, 1-2 % as 4x4 points); the result is the
//     finer grid, dark outside the candidates, unless it fits the pixels worse than the coarser
//     grid (its data term is larger): then the coarser result stands (a note says so).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/image.h"
#include "core/light_set.h"
#include "render/path_tracer.h"
#include "render/scene.h"

namespace genscene::inverse {

struct LightEstimationOptions {
  static constexpr const char* kSection = "lights";

  int grid = 7;                 // voxels per axis over the scene's bounding box
  double boundary_inset = 0.1;  // the outer voxel centres lie this many voxels inside the
                                // bounding box (0.5: cells that tile it; see MakeVoxelGrid)
  int pixels_per_view = 3000;   // sampled pixels per training view
  // Camera paths per sampled pixel (spp; box filter over the pixel; even: two independent halves
  // give the normal equations), max_depth (-1: Russian roulette ends a path) and rr_depth.
  render::RenderOptions paths = render::RenderOptions::Paths(16);
  int direct_paths = 2;           // of each half's paths, those whose first vertex connects to
                                  // every voxel (direct light); deeper vertices draw voxels
  int split_depth = 1 << 20;      // path vertices up to this depth connect to every voxel
                                  // (default: all; the coefficients' noise is shared by the
                                  // voxels instead of drawn per voxel); deeper ones draw
                                  // resample_voxels voxels
  double penalty_weight = 1e-3;   // w of the activation penalty
  double penalty_epsilon = 0.01;  // eps relative to s_ref
  int rounds = 1;                 // tracing rounds at most (1 = no resampling); the normal
                                  // equations of all rounds add up. With the default split_depth
                                  // a later round only adds fresh paths: on the replica a second
                                  // round changed the powers 3 % and the refined result not at all
  double round_tolerance = 0.05;  // stop when the voxel powers change less than this (relative)
  int resample_voxels = 8;        // voxels drawn per deeper path vertex (indirect light):
                                  // uniformly in round 0, then by the estimated powers
  double resample_uniform = 0.1;  // share of the uniform distribution in the resampling pmf
  int max_iterations = 300;       // alternating iterations per solve
  int move_passes = 1;            // passes of moves handing a lit voxel's light to a neighbour
                                  // (EstimateLights: in a final solve after the rounds)
  int move_voxels = 4;            // the strongest voxels that try moves
  int move_iterations = 10;       // alternating iterations after a move
  double tolerance = 1e-7;        // stop when the cost decreases less than this (relative)
  double saturation = 0.0;        // observed values >= this are masked (0: no saturation)
  double emitter_factor = 8.0;    // pixels brighter than this x the view's 95th percentile
                                  // luminance are taken for emitters seen directly (masked)
  double noise_correction = 0.5;  // gamma of NormalEquations::FromCaches, in [0, 1]: the share
                                  // of the coefficients' noise taken out of G; near 1 G can be
                                  // indefinite and the solve diverge
  int refine_levels = 1;          // adaptive refinement: levels of a grid twice as fine, each
                                  // traced and solved over the voxels near the previous level's
                                  // lights only (0: none)
  int refine_coarse_pixels = 1000;  // with refine_levels > 0, the coarse rounds (which only find
                                    // where the lights are) use this many of each view's sampled
                                    // pixels (0: all of them)
  double refine_fraction = 0.05;  // voxels with at least this share of the largest power are split
  double refine_reach = 1.0;      // the finer voxels within this many (coarser) voxel sizes of a
                                  // split voxel's centre, per axis, are the next level's candidates
  double refine_penalty_scale =
      0.1;                        // the finer levels' penalty weight, relative to penalty_weight
  int refine_max_voxels = 500;    // candidates per finer level at most; when the lights need more,
                                  // refinement stops and the coarser result stands
  int refine_spp = 32;            // camera paths per pixel at the finer levels (0: spp)
  int refine_grow = 1;            // passes per finer level that add the neighbours (within
                                  // refine_reach finer voxels) of its lights and solve again
  double active_fraction = 1e-3;  // voxels with at least this share of the largest power are
                                  // "active" in reports
  double memory_cap = 4000.0;     // MB the path-coefficient caches and the normal equations
                                  // may take; exceeding it is an error (checked before tracing
                                  // for the equations, while tracing for the caches)

  template <typename V>
  void Visit(V&& v) {
    v("grid", grid, "voxels", "voxels per axis over the scene's bounding box");
    v("boundary_inset", boundary_inset, "voxels",
      "outer voxel centres this far inside the bounding box (0.5: cells tile it)");
    v("pixels_per_view", pixels_per_view, "", "random valid pixels sampled per training view");
    paths.VisitPaths(v, "camera paths per sampled pixel (even: two independent halves)");
    v("direct_paths", direct_paths, "",
      "paths per half whose first vertex connects to every voxel");
    v("split_depth", split_depth, "vertices",
      "path vertices up to this depth connect to every voxel (deeper: drawn)");
    v("penalty_weight", penalty_weight, "", "weight of the log activation penalty (0: none)");
    v("penalty_epsilon", penalty_epsilon, "",
      "activation scale, relative to the best uniform lighting");
    v("rounds", rounds, "", "tracing rounds at most (later rounds resample voxels by power)");
    v("round_tolerance", round_tolerance, "", "stop when the voxel powers change less than this");
    v("resample_voxels", resample_voxels, "",
      "voxels drawn per deeper path vertex (indirect light)");
    v("resample_uniform", resample_uniform, "", "share of uniform voxel sampling when resampling");
    v("max_iterations", max_iterations, "", "alternating L / lambda iterations per solve");
    v("move_passes", move_passes, "",
      "passes of moves that hand a lit voxel's light to a neighbour (0: none)");
    v("move_voxels", move_voxels, "", "the strongest voxels that try moves");
    v("move_iterations", move_iterations, "",
      "alternating iterations after a move before it is judged");
    v("tolerance", tolerance, "", "relative cost decrease that ends a solve");
    v("saturation", saturation, "", "observed values at or above this are masked (0: none)");
    v("emitter_factor", emitter_factor, "", "mask pixels brighter than this x the 95th percentile");
    v("noise_correction", noise_correction, "",
      "share of the coefficient noise taken out of the Gram matrix");
    v("refine_levels", refine_levels, "",
      "adaptive refinement: levels of twice finer voxels near the lights (0: none)");
    v("refine_coarse_pixels", refine_coarse_pixels, "",
      "with refinement, sampled pixels per view the coarse rounds use (0: all)");
    v("refine_fraction", refine_fraction, "",
      "voxels with this share of the largest power are split");
    v("refine_reach", refine_reach, "voxels",
      "finer candidates within this many coarser voxels of a split one");
    v("refine_penalty_scale", refine_penalty_scale, "",
      "penalty weight of the finer levels, relative to penalty_weight");
    v("refine_max_voxels", refine_max_voxels, "",
      "candidate voxels per finer level at most (more: refinement stops)");
    v("refine_grow", refine_grow, "",
      "passes per finer level that add its lights' neighbours and solve again");
    v("refine_spp", refine_spp, "",
      "camera paths per sampled pixel at the finer levels (0: spp; even)");
    v("active_fraction", active_fraction, "",
      "share of the largest voxel power that counts as active");
    v("memory_cap", memory_cap, "MB",
      "memory the path-coefficient caches and normal equations may take (error beyond)");
  }
  void Validate() const;
};

struct SampledPixel {
  int view = 0;
  int u = 0, v = 0;
  Eigen::Vector3f observed = Eigen::Vector3f::Zero();
};

struct PixelMaskCounts {
  size_t valid = 0, miss = 0, emitter = 0, saturated = 0;
};

// Random valid pixels (up to pixels_per_view per view, without replacement; every valid pixel
// when there are fewer), in view order then raster order. Throws Error when a view's image does
// not match its intrinsics or holds a non-finite value, and when no pixel at all is valid.
std::vector<SampledPixel> SamplePixels(const render::PathTracer& tracer,
                                       const std::vector<PosedImage>& views,
                                       const LightEstimationOptions& options, uint64_t seed,
                                       std::vector<PixelMaskCounts>* counts = nullptr);

// The grid over the scene's bounding box (non-emitting meshes), dims^3 voxels, all dark. The
// outer layer of voxel centres lies `boundary_inset` voxel sizes inside the box (default: the
// option's; 0.5: the box split into dims^3 cells; smaller: the grid grows so that lights can sit
// near the walls and the ceiling, where real lights are).
VoxelLightGrid MakeVoxelGrid(const render::Scene& scene, int dims,
                             double boundary_inset = LightEstimationOptions().boundary_inset);

// Per sampled pixel, the coefficients of the parameters p = 6 j + k (sorted, RGB), compressed.
struct LightCache {
  int parameters = 0;  // 6 x voxels
  std::vector<SampledPixel> pixels;
  std::vector<size_t> row_begin;  // pixels + 1 entries into index / coefficient
  std::vector<int32_t> index;
  std::vector<Eigen::Vector3f> coefficient;
  render::RayCounts rays;

  // Predicted radiance of every sampled pixel for the lights `grid` (same layout).
  std::vector<Eigen::Vector3f> Predict(const VoxelLightGrid& grid) const;
  size_t NonZeros() const { return index.size(); }
  // Adds the entries of `other`, a cache of the same pixels over other parameters (no parameter in
  // both). Traces of the same paths (same seed and options, every voxel connected at every vertex)
  // that connect to two sets of voxels give, merged, the trace that connects to both.
  void Merge(const LightCache& other);
  // Heap bytes held by the rows (index, coefficient, row_begin).
  size_t Bytes() const;
};

// Bytes of the normal equations EstimateLights may hold at once for a grid of `dims`^3 voxels: two
// sets (the running total and a round's) of three dense Gram matrices over all 6 dims^3 parameters.
double NormalEquationsBoundBytes(int dims);

// Traces `options.paths.spp` paths per pixel (random numbers keyed by seed, view, pixel, sample)
// and splits at every vertex as `splitting` says. Throws Error when the cache's rows would take
// more than `cap_bytes` (0: no cap), with a message that says which options lower it.
LightCache TraceLightCache(const render::PathTracer& tracer, const VoxelLightGrid& grid,
                           const render::VoxelSplitting& splitting,
                           const std::vector<PosedImage>& views,
                           const std::vector<SampledPixel>& pixels,
                           const LightEstimationOptions& options, uint64_t seed,
                           double cap_bytes = 0.0);

// Two independent caches of the same pixels with half of `options.paths.spp` each (keys seed_a and
// seed_b): the normal equations' noise correction takes their product
// (NormalEquations::FromCaches). The second cache gets what the first leaves of `cap_bytes` (0: no
// cap).
std::pair<LightCache, LightCache> TraceLightCacheHalves(
    const render::PathTracer& tracer, const VoxelLightGrid& grid,
    const render::VoxelSplitting& splitting, const std::vector<PosedImage>& views,
    const std::vector<SampledPixel>& pixels, const LightEstimationOptions& options, uint64_t seed_a,
    uint64_t seed_b, double cap_bytes = 0.0);

// The radiance of one sampled pixel for the lights `grid`, by the same walk and the same random
// numbers as TraceLightCache (a fresh render, for checking the cache).
Eigen::Vector3f RenderSampledPixel(const render::PathTracer& tracer, const VoxelLightGrid& grid,
                                   const render::VoxelSplitting& splitting,
                                   const SampledPixel& pixel, const std::vector<PosedImage>& views,
                                   const LightEstimationOptions& options, uint64_t seed);

// The cache reduced to its normal equations over the parameters that any pixel touches.
struct NormalEquations {
  int parameters = 0;                   // 6 x voxels
  std::vector<int> used;                // parameter index of each compact index
  std::array<Eigen::MatrixXd, 3> gram;  // per channel, compact x compact (both triangles stored)
  std::array<Eigen::VectorXd, 3> rhs;   // per channel, compact
  std::array<double, 3> observed_sq{};  // per channel, sum of I^2
  size_t pixels = 0;

  static NormalEquations FromCache(const LightCache& cache);
  // From two independent traces of the same pixels (rows a_i, b_i): the mean rows m = (a + b) / 2
  // and the half differences d = (a - b) / 2 give G_c = M^T M - gamma D^T D, b_c = M^T I.
  // M^T M alone carries the Monte Carlo variance of the coefficients in its expectation
  // (errors-in-variables: it acts as a regulariser that shrinks and smears the lights);
  // E[D^T D] is that variance, so gamma = 1 is unbiased (= (A^T B + B^T A) / 2), gamma = 0 the
  // plain Gram matrix of the mean rows. gamma < 1 keeps G safely positive definite.
  // `known`: the equations of the same caches before entries of further parameters were merged
  // in (LightCache::Merge); the entries of G between two of its parameters are taken from it and
  // only those with a new parameter are computed (dense rows only; sparse ones are recomputed).
  static NormalEquations FromCaches(const LightCache& first, const LightCache& second,
                                    double correction, const NormalEquations* known = nullptr);
  // Adds another cache's equations (same parameters), e.g. from a later tracing round.
  void Add(const NormalEquations& other);
};

// The cost f(L, lambda) above over the normal equations. Parameters packed per voxel as
// [L_r, L_g, L_b, lambda_0..lambda_5] (9 per voxel).
class LightCost {
 public:
  LightCost(const NormalEquations& equations, double penalty_weight, double penalty_epsilon);

  static Eigen::VectorXd Pack(const VoxelLightGrid& grid);
  static void Unpack(const Eigen::VectorXd& params, VoxelLightGrid* grid);

  // Cost, its data part (squared relative residual) and, when `gradient` is given, the gradient;
  // `gram_x` receives G_c x_c per channel (x_c: the products L_c lambda of the used parameters).
  // The channels are evaluated in parallel, each by one task (the sums do not depend on threads).
  double Evaluate(const Eigen::VectorXd& params, Eigen::VectorXd* gradient = nullptr,
                  double* data = nullptr, std::array<Eigen::VectorXd, 3>* gram_x = nullptr) const;
  double epsilon() const { return epsilon_; }
  const NormalEquations& equations() const { return eq_; }

 private:
  const NormalEquations& eq_;
  double weight_, epsilon_, energy_;
};

struct SolveReport {
  int iterations = 0;
  int moves = 0;                  // light handed to a neighbouring voxel and kept
  double cost = 0.0, data = 0.0;  // final cost and its data part
  std::vector<double> history;    // cost after each iteration
};

// Minimises LightCost from `grid` (initial values; all-dark starts from the best uniform
// lighting) and writes the result into it, each voxel's lambdas scaled to a maximum of 1.
SolveReport SolveLights(const NormalEquations& equations, const LightEstimationOptions& options,
                        VoxelLightGrid* grid);

struct LightRound {
  int round = 0;
  int level = 0;        // refinement level (0: the coarse grid's rounds)
  int candidates = 0;   // voxels traced at a refinement level
  size_t nonzeros = 0;  // cache entries of this round
  uint64_t rays = 0;
  double trace_seconds = 0.0, gram_seconds = 0.0, solve_seconds = 0.0;
  SolveReport solve;
  int active_voxels = 0;
  double power_change = 0.0;  // relative change of the voxel powers (round > 0)
};

struct LightEstimate {
  VoxelLightGrid lights;
  std::vector<LightRound> rounds;
  std::vector<PixelMaskCounts> masks;  // per view
  size_t pixels = 0;                   // sampled pixels
  double seconds = 0.0;
  double train_rmse = 0.0;  // relative RMSE of the final cache's prediction
  int active_voxels = 0;
  std::vector<std::string> notes;  // e.g. why adaptive refinement stopped early
};

// Steps 1-5. `scene`: geometry and albedo (emitters and lights in it are ignored).
LightEstimate EstimateLights(const render::Scene& scene, const std::vector<PosedImage>& views,
                             const LightEstimationOptions& options, uint64_t seed);

// The scene without its emitters and lights: what light estimation traces.
render::Scene WithoutLights(const render::Scene& scene);

// Which pixels of a view light estimation uses (1) and why the others are left out.
Image<uint8_t> ValidPixels(const render::PathTracer& tracer, const PosedImage& view,
                           const LightEstimationOptions& options,
                           PixelMaskCounts* counts = nullptr);

// Relative RMSE sqrt(sum |P - R|^2 / sum |R|^2) of a render against a reference over the valid
// pixels (masked as SamplePixels does), and the part of it that is Monte Carlo noise of the
// render (from two half renders) and of the reference (given as its RMS noise per channel).
// With `block` > 1 the images are compared as means over block x block tiles (of their valid
// pixels, each tile weighted by its count): the noise variance of a tile mean is that of a pixel
// over the count (pixels are sampled independently), so subtracting it is far steadier when the
// per-pixel noise is much larger than the error being measured; errors finer than a tile are
// averaged away.
struct ViewError {
  size_t pixels = 0;
  double rmse = 0.0;       // raw
  double noise = 0.0;      // sqrt(render noise^2 + reference noise^2) on the same scale
  double rmse_bias = 0.0;  // sqrt(max(0, rmse^2 - noise^2)): the error of the expected images
};
// `lit`: the scene with the lights to judge (rendered with next-event estimation, `spp` in total).
ViewError CompareRender(const render::PathTracer& lit, const PosedImage& reference,
                        const LightEstimationOptions& options, int spp, uint64_t seed,
                        double reference_noise_rms = 0.0, ImageRgb* render = nullptr,
                        int block = 1);

// The baseline a light estimate must beat: each valid pixel (as CompareRender masks them)
// predicted as its camera ray's first hit's albedo times one ambient radiance per channel, fitted
// by least squares over all the views (no shadows, no bounces). `rmse` per view as ViewError::rmse.
struct AmbientBaseline {
  Eigen::Vector3d radiance = Eigen::Vector3d::Zero();
  std::vector<double> rmse;
  double mean_rmse = 0.0;
};
AmbientBaseline FitAmbientBaseline(const render::PathTracer& tracer,
                                   const std::vector<PosedImage>& views,
                                   const LightEstimationOptions& options);

}  // namespace genscene::inverse
