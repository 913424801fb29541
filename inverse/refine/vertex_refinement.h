// Vertex refinement (the paper's section IV): the vertex positions x of chosen meshes of a scene,
// estimated from posed images through the differentiable path tracer by Levenberg-Marquardt on
//
//   E(x) = sum_p sum_c HuberCost(r_pc, robust)                              data
//        + sum_i HuberCost(sqrt(d_i^T P_i d_i), prior_robust)                prior
//        + sum_i |T_i (x_i - c_i)|^2 / (2 relax_sigma^2)                     relaxation
//        + sum_i (k_i - mean_{j in ring(i)} k_j)^2 / (2 smooth_sigma^2)      bending
//   r_pc = (I_c(x) - I*_c) / (noise * s),  d_i = x_i - x0_i,  T_i = I - n_i n_i^T,
//   P_i = n0_i n0_i^T / prior_sigma^2 + (I - n0_i n0_i^T) / prior_tangent_sigma^2,
//   k_i = n_i . (x_i - c_i) * l / l_i
//
//   data:       path-traced pixel I(x) against the reference I*, s the RMS of I* (noise, robust)
//   prior:      distance from the start x0 at its normals n0 (prior_sigma, prior_tangent_sigma)
//   relaxation: offset across the surface from the centroid c_i of the one-ring (relax_sigma)
//   bending:    change of curvature; l_i: mean squared edge length at i, l: mean l_i (smooth_sigma)
//
// The terms' details are next to their code: data_term.h, regularisers.h. Each iteration traces
// the sampled pixels with fresh random numbers (residuals from the full paths, the sparse Jacobian
// from their first jacobian_max_depth segments), forms the normal equations with Huber's IRLS
// weights and solves the damped system (sparse Cholesky up to direct_max_vertices refined
// vertices, else preconditioned conjugate gradients; linear_solve.h). A trust region (max_step)
// and the fold guard bound the step, which is kept only when a trace with the same random numbers
// shows a lower E; steps after average_after are averaged. Visibility changes are not
// differentiated (as in the paper).
#pragma once

#include <functional>
#include <vector>

#include "core/image.h"
#include "core/view_set.h"
#include "render/differentiable_tracer.h"

namespace genscene::inverse {

struct RefineOptions {
  static constexpr const char* kSection = "refine";

  int iterations = 5;  // Levenberg-Marquardt iterations (accepted or not)
  render::RenderOptions paths = render::RenderOptions::Paths(64);  // per pixel and evaluation
  int pixels_per_view = 0;          // pixels sampled per view (0 = every pixel)
  bool refine_unseen = false;       // also move vertices that no sampled pixel sees directly
  bool refined_pixels_only = true;  // fit only pixels whose camera ray sees a refined mesh
  int edge_margin = 1;              // pixels within this distance of a silhouette are left out
  int jacobian_max_depth =
      2;  // longest path whose derivatives enter the Jacobian (2 = direct light; -1 = max_depth)
  double noise = 0.05;  // relative pixel noise that weighs the data term
  double robust = 3.0;  // Huber threshold of the residuals, in noise units (0 = none)
  double prior_sigma =
      0.003;  // standard deviation of the prior on vertex positions, m (along the normal)
  double prior_tangent_sigma = 0.0;  // the same across the surface, m (0 = prior_sigma: isotropic)
  double relax_sigma = 0.001;   // relaxation across the surface: SD of a vertex's offset from its
                                // one-ring's centroid, m (0 = off)
  double smooth_sigma = 0.002;  // bending: SD of a vertex's offset along its normal from its
                                // neighbours' mean offset, m (0 = off)
  double prior_robust =
      2.0;                 // Huber threshold of the prior, in standard deviations (0 = quadratic)
  double damping = 1e-3;   // initial Levenberg-Marquardt damping (times diag of J^T J)
  double max_step = 0.25;  // largest vertex move per step, in mean edge lengths (trust region)
  bool resample = true;    // fresh random numbers every iteration (same within one)
  int average_after = 2;  // step k > this moves 1 / (k - average_after) of the way (0 = full steps)
  int max_retries = 6;    // rejected steps per iteration before giving up
  double tolerance = 1e-5;         // stop when an accepted step lowers E by less than this fraction
  int direct_max_vertices = 3000;  // larger problems are solved by conjugate gradients
  // The stage's gate (apps/refine.h): refine a workspace only when its lights fit the keyframes
  // better than a constant ambient light (else their renders carry no geometric information).
  bool fit_gate = true;
  // The held-out gate (apps/refine.h): the refined mesh is kept only when it fits a fresh sample
  // of pixels better than the unrefined one by at least this many standard errors of the paired
  // per-pixel difference (HeldOutComparison::improvement_z); a gain within the noise keeps the
  // unrefined mesh.
  double held_out_z = 2.0;

  template <typename V>
  void Visit(V&& v) {
    v("iterations", iterations, "", "Levenberg-Marquardt iterations");
    v("fit_gate", fit_gate, "",
      "refine a workspace only when its lights fit the keyframes better than a constant ambient "
      "light (lights.json); else the unrefined mesh is kept");
    v("held_out_z", held_out_z, "",
      "keep the refined mesh only when it fits held-out pixels better by this many standard "
      "errors");
    paths.VisitPaths(v, "path samples per pixel and evaluation");
    v("pixels_per_view", pixels_per_view, "", "pixels sampled per view (0 = every pixel)");
    v("refine_unseen", refine_unseen, "",
      "also move the vertices no sampled pixel sees directly (only indirect light, mostly noise, "
      "speaks of them)");
    v("refined_pixels_only", refined_pixels_only, "",
      "fit only the pixels whose camera ray first hits a mesh being refined (elsewhere a vertex "
      "shows only through shadows and indirect light)");
    v("edge_margin", edge_margin, "px",
      "pixels this close to a silhouette are left out (0 = none)");
    v("jacobian_max_depth", jacobian_max_depth, "segments",
      "longest path whose derivatives enter the Jacobian (2 = direct light only; -1 = max_depth); "
      "the residuals always use max_depth");
    v("noise", noise, "", "relative pixel noise that weighs the data term");
    v("robust", robust, "",
      "Huber threshold of the residuals in noise units (0 = plain least squares)");
    v("prior_sigma", prior_sigma, "m",
      "standard deviation of the prior on the starting vertex positions, along the normal");
    v("prior_tangent_sigma", prior_tangent_sigma, "m",
      "the same across the surface, where a move slides the vertex along the surface (0 = "
      "prior_sigma)");
    v("relax_sigma", relax_sigma, "m",
      "standard deviation of a vertex's offset across the surface from the centroid of its "
      "neighbours: spreads the vertices evenly where the images cannot see them slide (0 = off)");
    v("smooth_sigma", smooth_sigma, "m",
      "bending: standard deviation of a vertex's offset along its normal from its one-ring's "
      "centroid, less its neighbours' mean offset (a discrete change of curvature); holds single "
      "vertices from walking where visibility misleads the images (0 = off)");
    v("prior_robust", prior_robust, "sigma",
      "Huber threshold of the prior's distance from the start, in standard deviations (0 = "
      "quadratic)");
    v("damping", damping, "", "initial Levenberg-Marquardt damping");
    v("max_step", max_step, "edges", "largest vertex move per step, in mean edge lengths");
    v("resample", resample, "",
      "fresh random numbers every iteration (the same for its trial steps)");
    v("average_after", average_after, "iterations",
      "later steps are averaged: step k moves 1 / (k - average_after) of the way, so the positions "
      "become the mean of the steps' targets, each fitted to its own random numbers (0 = full "
      "steps)");
    v("max_retries", max_retries, "", "rejected steps per iteration before stopping");
    v("tolerance", tolerance, "", "stop when a step lowers the cost by less than this fraction");
    v("direct_max_vertices", direct_max_vertices, "vertices",
      "largest problem solved by sparse Cholesky; larger ones by conjugate gradients");
  }
  void Validate() const;
};

struct RefineIteration {
  int iteration = 0;       // 0: the start
  double cost = 0.0;       // E at the positions after this iteration
  double data_rmse = 0.0;  // RMS of (I - I*) / RMS of I* over the sampled pixels and channels
  double step_rms = 0.0;   // RMS vertex move of this iteration's step, m (0 when rejected)
  double damping = 0.0;    // damping after this iteration
  int rejected = 0;        // steps rejected in this iteration
  int held = 0;            // vertex moves zeroed because they would turn a face over (all trials)
  bool accepted = false;
  double seconds = 0.0;                      // wall time of the iteration
  double jacobian_nonzeros_per_pixel = 0.0;  // non-zero scalar entries of the 3 rows of a pixel
  render::RayCounts rays;
};

// What RefineVertices returns: per refined mesh, in the order of `refined_meshes`, the mesh at the
// final positions (the scene's mesh with its vertices moved, float, area-weighted vertex normals)
// and its vertex positions in double precision before and after; and the figures per iteration.
struct RefineResult {
  std::vector<TriangleMesh> meshes;
  std::vector<Eigen::VectorXd> initial;    // x0 per mesh, (x, y, z) per vertex
  std::vector<Eigen::VectorXd> positions;  // final x per mesh, (x, y, z) per vertex
  int pixels = 0;                          // sampled pixels (each gives 3 residuals)
  std::vector<RefineIteration> history;    // the start, then one per iteration
};

// Called with each iteration's figures and the tracer at its positions (the scene at x, and x
// numbered as the tracer's parameter vertices: mesh by mesh in scene order).
using RefineProgress =
    std::function<void(const RefineIteration&, const render::DifferentiablePathTracer&)>;

// The guard every step of RefineVertices passes: zeroes the step of the vertices of every face
// (vertex indices into x, 3 coordinates each) that x + step would turn over (its normal at or
// past 90 degrees from its normal at `start`, or of zero area) while at x it is not, until no
// face turns over; returns how many vertices were held. A fold is never a better fit of a
// surface: it comes from a step the linear model over-reaches, or from noise on a thin face.
// Faces of zero area at `start` have no orientation and are not checked.
int HoldFoldingVertices(const std::vector<Eigen::Vector3i>& faces, const Eigen::VectorXd& start,
                        const Eigen::VectorXd& x, Eigen::VectorXd* step);

// Refines the vertices of the scene meshes `refined_meshes` (indices into scene.meshes, each once,
// no emitter) so that renders of the scene match the targets. They start at the scene's vertices,
// or at `start` when given: per refined mesh (same order), (x, y, z) per vertex in double
// precision. `seed` keys the random numbers of the traces and of the pixel sample. `progress` is
// called after the start and after every iteration.
// Throws Error when a mesh index is out of range, repeated or an emitter, when `start` does not
// match the meshes, when there are no targets or no vertices, or when a target's size does not
// match its view or the image is not finite.
RefineResult RefineVertices(const render::Scene& scene, const std::vector<int>& refined_meshes,
                            const std::vector<PosedImage>& targets, const RefineOptions& options,
                            uint64_t seed = 1, const RefineProgress& progress = {},
                            const std::vector<Eigen::VectorXd>& start = {});

// The data term of E at the tracer's positions and its gradient J^T r (3 per parameter vertex),
// for checks of the objective against finite differences.
struct RefineLinearization {
  double cost = 0.0;
  Eigen::VectorXd gradient;
  double curvature = 0.0;  // d^T J^T W J d along the given direction d (Gauss-Newton model)
};
RefineLinearization LinearizeRefinement(const render::DifferentiablePathTracer& tracer,
                                        const std::vector<PosedImage>& targets,
                                        const RefineOptions& options, uint64_t seed = 1,
                                        const Eigen::VectorXd* direction = nullptr);

// The image error of two sets of positions of the refined meshes (per mesh, as
// RefineResult::initial and positions) on the same pixels: a fresh sample (keyed by `seed`, drawn
// at `b`; with a seed other than the refinement's, pixels the refinement did not fit) traced with
// the same random numbers at both. RMS of (I - I*) over RMS of I*, as RefineIteration::data_rmse.
// improvement_z: the mean over the pixels of the paired difference of squared errors, a's minus
// b's, over its standard error (> 0: b fits better; 2: better by two standard errors).
struct HeldOutComparison {
  int pixels = 0;
  double rmse_a = 0.0, rmse_b = 0.0;
  double improvement_z = 0.0;
};
HeldOutComparison CompareOnFreshPixels(const render::Scene& scene,
                                       const std::vector<int>& refined_meshes,
                                       const std::vector<PosedImage>& targets,
                                       const RefineOptions& options, uint64_t seed,
                                       const std::vector<Eigen::VectorXd>& a,
                                       const std::vector<Eigen::VectorXd>& b);

// Faces whose normal turned by more than 90 degrees between `before` and `after` (same faces),
// plus faces that lost all their area: the tangles a refinement must not create.
int FlippedFaces(const TriangleMesh& before, const TriangleMesh& after);

}  // namespace genscene::inverse
