// The options of light estimation (section "lights" of the configuration), read and checked
// through Visit and Validate. light_estimation.h describes the method they steer.
#pragma once

#include "render/path_tracer.h"

namespace genscene::inverse {

struct LightEstimationOptions {
  static constexpr const char* kSection = "lights";

  int grid = 7;  // voxels per axis over the scene's bounding box
  // The grid reaches this share of the scene's size beyond its bounding box on every side (a scan
  // of part of a room: the light sources are often outside it). 0: the bounding box.
  double grid_margin = 0.0;
  double boundary_inset = 0.1;  // the outer voxel centres lie this many voxels inside the
                                // bounding box (0.5: cells that tile it; see MakeVoxelGrid)
  // A voxel light's falloff is 1 / (d^2 + e^2) with e this share of the voxels' smallest side
  // (VoxelLightGrid::softening): a wall next to a voxel centre is not lit without bound, and the
  // model's renders have no fireflies there. 0: point lights.
  double softening = 0.5;
  // A distant light (VoxelLightGrid::distant: six lobes at infinity) beside the voxels, for light
  // from beyond the scan that reaches it through openings (a window, the sky, an unscanned lamp):
  // the paths that leave the mesh after a bounce see it.
  bool distant = false;
  int pixels_per_view = 3000;  // sampled pixels per training view
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
  double chroma_weight = 0.0;     // w_chroma: voxel colours pulled toward the room's (LightCost)
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
  // Per-view camera exposure estimated with the lights (real cameras adapt per frame): "none",
  // "gain" (one gain per view) or "white-balance" (one per view and channel). The gains' geometric
  // mean over the views is 1 (per channel for white-balance): the overall scale is the lights'.
  std::string exposure = "none";
  // Joint albedo (joint_albedo.h; EstimateLights with JointAlbedoInputs): alternations of
  // per-texel albedo and lights after the lights' estimate (0: the clustering's albedo stays).
  int albedo_iterations = 3;
  double albedo_prior = 0.02;    // weight pulling a texel's albedo toward its cluster's
  double albedo_radius = 0.005;  // shading kernel radius, share of the scene's diagonal
  int albedo_min_pixels = 16;    // samples in a texel's kernel at least (else it widens)
  // Paths per shading probe: the shading is traced under the current lights at observed texels
  // albedo_radius / 3 apart (0: taken from the sampled pixels' paths instead).
  int albedo_probe_spp = 8;
  // With probes, the kernel averages the shading relative to the voxels' direct (shadowed)
  // shading at the probe plus this share of the probes' mean shading (ShadingGuide), and scales
  // it by the texel's own (0: the plain mean of the shading).
  double albedo_guide = 0.5;
  double albedo_ceiling = 0.9;     // the 95th percentile of the largest albedo channel at most
  double albedo_tolerance = 0.01;  // stop when the light cost falls less than this (relative)
  double memory_cap = 4000.0;      // MB the path-coefficient caches and the normal equations
                                   // may take; exceeding it is an error (checked before tracing
                                   // for the equations, while tracing for the caches)

  template <typename V>
  void Visit(V&& v) {
    v("grid", grid, "voxels", "voxels per axis over the scene's bounding box");
    v("grid_margin", grid_margin, "",
      "the grid reaches this share of the scene's size beyond its bounding box on every side");
    v("boundary_inset", boundary_inset, "voxels",
      "outer voxel centres this far inside the bounding box (0.5: cells tile it)");
    v("softening", softening, "voxels",
      "a voxel light's falloff is 1 / (d^2 + e^2), e this share of the voxels' smallest side");
    v("distant", distant, "",
      "a distant light (six lobes at infinity) lights the paths that leave the mesh: light from "
      "beyond the scan");
    v("pixels_per_view", pixels_per_view, "", "random valid pixels sampled per training view");
    paths.VisitPaths(v, "camera paths per sampled pixel (even: two independent halves)");
    v("direct_paths", direct_paths, "",
      "paths per half whose first vertex connects to every voxel");
    v("split_depth", split_depth, "vertices",
      "path vertices up to this depth connect to every voxel (deeper: drawn)");
    v("penalty_weight", penalty_weight, "", "weight of the log activation penalty (0: none)");
    v("penalty_epsilon", penalty_epsilon, "",
      "activation scale, relative to the best uniform lighting");
    v("chroma_weight", chroma_weight, "",
      "weight of the pull of every voxel's colour toward the best uniform light's (0: off)");
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
    v("exposure", exposure, "",
      "per-view camera gain estimated with the lights: none, gain or white-balance (per channel); "
      "geometric mean 1");
    v("albedo_iterations", albedo_iterations, "",
      "alternations of per-texel albedo and lights (0: the clustering's albedo stays)");
    v("albedo_prior", albedo_prior, "", "weight pulling a texel's albedo toward its cluster's");
    v("albedo_radius", albedo_radius, "",
      "shading smoothing radius of the joint albedo, share of the scene's diagonal");
    v("albedo_min_pixels", albedo_min_pixels, "",
      "joint albedo: shading samples in a texel's kernel at least (else 2x, then 4x as wide)");
    v("albedo_probe_spp", albedo_probe_spp, "",
      "joint albedo: paths per shading probe (probes albedo_radius / 3 apart over the observed "
      "surface; 0: the sampled pixels' shading)");
    v("albedo_guide", albedo_guide, "",
      "joint albedo with probes: the kernel averages the shading over the voxels' direct "
      "shading (with shadows) plus this share of the probes' mean (0: the plain mean)");
    v("albedo_ceiling", albedo_ceiling, "",
      "joint albedo: the 95th percentile of the largest channel at most this (scaled down)");
    v("albedo_tolerance", albedo_tolerance, "",
      "joint albedo stops when the light cost falls less than this (relative)");
    v("refine_spp", refine_spp, "",
      "camera paths per sampled pixel at the finer levels (0: spp; even)");
    v("active_fraction", active_fraction, "",
      "share of the largest voxel power that counts as active");
    v("memory_cap", memory_cap, "MB",
      "memory the path-coefficient caches and normal equations may take (error beyond)");
  }
  void Validate() const;
};

}  // namespace genscene::inverse
