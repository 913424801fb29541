// Light estimation (the paper's section II and Fig. 3): voxel lights (core/light_set.h) from
// known geometry and albedo and posed linear images. This header declares the driver and
// includes the headers of the steps, so that it is the one to include.
//
// Build / solve / report:
//  1. SamplePixels (pixel_sampling.h) picks random valid pixels per view (the camera ray hits a
//     reflecting surface; saturated pixels and pixels that see an emitter directly are masked).
//  2. TraceLightCache (light_cache.h) traces camera paths through them once and, at every path
//     vertex, splits: a shadow ray to every voxel (or to voxels drawn in proportion to the
//     current estimate). It records the coefficient that multiplies each product
//     x_jk = L_j lambda_jk, so that the predicted pixel is P_i = sum_jk a_ijk (*) x_jk (per
//     channel; path throughput x BRDF x cosine / r^2 x visibility x the voxel's face projection
//     max(0, w . d_k)).
//  3. NormalEquations (normal_equations.h) reduces the cache to G_c = sum_i a_ic a_ic^T,
//     b_c = sum_i a_ic I_ic: one cost evaluation is then O(parameters^2), independent of the
//     number of pixels. Two independent halves of the paths give the unbiased cross product
//     instead (FromCaches).
//  4. LightCost / SolveLights (light_cost.h, light_solver.h) minimise
//         f(L, lambda) = (1/E) sum_i sum_c (P_ic - I_ic)^2 + w sum_j log(1 + s_j / eps),
//     E = sum_i sum_c I_ic^2 (so the data term is the squared relative residual), s_j = sum_c
//     L_jc, eps = penalty_epsilon * s_ref (s_ref: the summed intensity of the best uniform
//     lighting), L >= 0, 0 <= lambda <= 1 (the upper bound fixes the L x lambda scale gauge).
//     The log term charges a voxel's first activation and then plateaus (the paper's activation
//     penalty). The solve alternates between L and lambda; each block is a bound-constrained
//     quadratic solved exactly by coordinate descent, with the log term majorised by its tangent
//     (reweighted L1), so the true cost never increases.
//     With options.exposure, each solve alternates with a per-view gain step: the observations of
//     view v are scaled by h_v (NormalEquations::ScaleObserved: G is unchanged), the lights are
//     solved, and h_v = t_v / s_v with t_v = sum_i P_i I_i, s_v = sum_i I_i^2 over v's pixels
//     (the least-squares scale of v's observations onto the prediction, per channel for
//     white-balance), normalised to a geometric mean of 1 (the gauge: the overall scale belongs
//     to the lights) and clamped to [1/5, 5]; until the gains change less than 1e-3 (at most 6
//     steps). The camera's gain is g_v = 1 / h_v.
//  5. EstimateLights (this header) runs rounds: trace, solve, then re-trace with voxel sampling
//     proportional to the estimated powers (the paper's remedy for starting without the right
//     sampling distribution), accumulating the normal equations, until the voxel powers stop
//     changing. Drawn voxels are used only beyond split_depth; with the default (every vertex
//     connects to every voxel) a later round adds fresh paths, not a better sampling
//     distribution.
//  6. Adaptive refinement (refine_levels): a grid twice as fine, traced and solved over only the
//     finer voxels near the voxels that hold light, with growing passes that add the neighbours of
//     the finer solution's lights. A point per coarse voxel cannot hold an extended light (a 0.5 m
//     ceiling light: 5-7 % training error at best on 7^3, 1-2 % as 4x4 points); the result is the
//     finer grid, dark outside the candidates, unless it fits the pixels worse than the coarser
//     grid (its data term is larger): then the coarser result stands (a note says so).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/image.h"
#include "core/light_set.h"
#include "inverse/lights/joint_albedo.h"
#include "inverse/lights/light_cache.h"
#include "inverse/lights/light_cost.h"
#include "inverse/lights/light_metrics.h"
#include "inverse/lights/light_options.h"
#include "inverse/lights/light_solver.h"
#include "inverse/lights/normal_equations.h"
#include "inverse/lights/pixel_sampling.h"
#include "render/path_tracer.h"
#include "render/scene.h"

namespace genscene::inverse {

// The grid over the scene's bounding box (non-emitting meshes), dims^3 voxels, all dark. The
// outer layer of voxel centres lies `boundary_inset` voxel sizes inside the box (default: the
// option's; 0.5: the box split into dims^3 cells; smaller: the grid grows so that lights can sit
// near the walls and the ceiling, where real lights are). `margin` > 0 first grows the box by that
// share of its size on every side, so that voxels can stand for light from outside the scan.
// The lights' softening (VoxelLightGrid::Falloff) is `softening` times the voxels' smallest side.
VoxelLightGrid MakeVoxelGrid(const render::Scene& scene, int dims,
                             double boundary_inset = LightEstimationOptions().boundary_inset,
                             double margin = 0.0, double softening = 0.0, bool distant = false);

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
  double train_rmse = 0.0;  // relative RMSE of the final cache's prediction (times the gains)
  // With options.exposure: per training view, the camera's gain g (per channel), observed ~ g x
  // the model's radiance; geometric mean 1 over the views. Empty without.
  std::vector<Eigen::Vector3d> exposure_gains;
  int active_voxels = 0;
  // With options.distant: the distant light's share of the predicted radiance of the sampled
  // pixels (luminance, final cache), in [0, 1].
  double distant_share = 0.0;
  // Step 7: the joint albedo (layout and labels of JointAlbedoInputs::clusters) when some
  // alternation was kept, and every alternation's figures.
  std::optional<MeshColors> albedo;
  std::vector<JointAlbedoStep> albedo_steps;
  size_t albedo_probes = 0;  // shading probes of the joint albedo (0: the sampled pixels')
  // With probes: the ceiling's scale of the last albedo update, under the final lights (which
  // took 1 / scale); 1: none.
  double albedo_final_scale = 1.0;
  double albedo_seconds = 0.0;
  std::vector<std::string> notes;  // e.g. why adaptive refinement stopped early
};

// Steps 1-7. `scene`: geometry and albedo (emitters and lights in it are ignored). `joint`: the
// Mesh Colors albedo step 7 updates (null: no step 7); its clusters must be the albedo the scene's
// mesh carries.
LightEstimate EstimateLights(const render::Scene& scene, const std::vector<PosedImage>& views,
                             const LightEstimationOptions& options, uint64_t seed,
                             const JointAlbedoInputs* joint = nullptr);

// The scene without its emitters and lights: what light estimation traces.
render::Scene WithoutLights(const render::Scene& scene);

}  // namespace genscene::inverse
