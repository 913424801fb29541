// The Levenberg-Marquardt driver of vertex refinement and the entry points of
// vertex_refinement.h. The terms of E are in data_term.cpp and regularisers.cpp, the linear solve
// in linear_solve.cpp, the fold guard in fold_guard.cpp.
#include "inverse/refine/vertex_refinement.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/check.h"
#include "core/options.h"
#include "inverse/refine/data_term.h"
#include "inverse/refine/linear_solve.h"
#include "inverse/refine/regularisers.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on
using namespace refine_detail;

void RefineOptions::Validate() const {
  RequireRange("held_out_z", held_out_z, -1e6, 1e6);
  RequireRange("iterations", iterations, 0, 1000);
  paths.Validate();
  RequireRange("pixels_per_view", pixels_per_view, 0, 1 << 26);
  const auto require_depth = [](const char* name, int depth) {
    if (depth == 0 || depth < -1)
      throw Error(Format("option ", name, " = ", depth, " must be -1 or >= 1"));
  };
  require_depth("jacobian_max_depth", jacobian_max_depth);
  RequireRange("noise", noise, 1e-6, 10.0);
  RequireRange("prior_sigma", prior_sigma, 1e-9, 1e6);
  if (prior_tangent_sigma != 0.0)
    RequireRange("prior_tangent_sigma", prior_tangent_sigma, 1e-9, 1e6);
  if (relax_sigma != 0.0) RequireRange("relax_sigma", relax_sigma, 1e-9, 1e6);
  if (smooth_sigma != 0.0) RequireRange("smooth_sigma", smooth_sigma, 1e-9, 1e6);
  RequireRange("damping", damping, 0.0, 1e12);
  RequireRange("max_step", max_step, 1e-6, 100.0);
  RequireRange("max_retries", max_retries, 0, 100);
  RequireRange("average_after", average_after, 0, 1000);
  RequireRange("tolerance", tolerance, 0.0, 1.0);
  RequireRange("robust", robust, 0.0, 1e6);
  RequireRange("prior_robust", prior_robust, 0.0, 1e6);
  RequireRange("edge_margin", edge_margin, 0, 100);
  RequireRange("direct_max_vertices", direct_max_vertices, 0, 1 << 30);
}

namespace {

// --- The refined meshes as the tracer's parameters ----------------------------------------------
// DifferentiablePathTracer numbers the parameter vertices mesh by mesh in scene order; the API
// takes and gives positions per refined mesh, in the caller's order.

// The tracer's `refined` mask; throws Error for an index out of range, an emitter or a repeat.
std::vector<bool> RefinedMask(const Scene& scene, const std::vector<int>& refined_meshes) {
  std::vector<bool> mask(scene.meshes.size(), false);
  for (int m : refined_meshes) {
    if (m < 0 || m >= static_cast<int>(scene.meshes.size())) {
      throw Error(Format("vertex refinement: mesh ", m, " to refine, but the scene has ",
                         scene.meshes.size(), " meshes"));
    }
    if (scene.meshes[m].IsEmitter()) {
      throw Error(Format("vertex refinement: mesh ", m, " (", scene.meshes[m].name,
                         ") is an emitter and cannot be refined"));
    }
    if (mask[m]) throw Error(Format("vertex refinement: mesh ", m, " is given twice"));
    mask[m] = true;
  }
  return mask;
}

size_t VertexCount(const Scene& scene, const std::vector<int>& refined_meshes) {
  size_t count = 0;
  for (int m : refined_meshes) count += scene.meshes[m].mesh.vertices.size();
  return count;
}

// The positions per refined mesh as the tracer's parameter vector; throws Error naming `what`
// when they do not match the meshes.
Eigen::VectorXd Pack(const DifferentiablePathTracer& tracer, const std::vector<int>& refined_meshes,
                     const std::vector<Eigen::VectorXd>& per_mesh, const char* what) {
  if (per_mesh.size() != refined_meshes.size()) {
    throw Error(Format("vertex refinement: ", what, " has positions for ", per_mesh.size(),
                       " meshes, but ", refined_meshes.size(), " are refined"));
  }
  Eigen::VectorXd x(3 * tracer.VertexCount());
  for (size_t k = 0; k < refined_meshes.size(); ++k) {
    const int m = refined_meshes[k];
    const Eigen::Index n =
        3 * static_cast<Eigen::Index>(tracer.scene().meshes[m].mesh.vertices.size());
    if (per_mesh[k].size() != n) {
      throw Error(Format("vertex refinement: ", what, " has ", per_mesh[k].size(),
                         " coordinates for mesh ", m, ", which has ", n / 3, " vertices"));
    }
    x.segment(3 * tracer.ParameterVertex(m, 0), n) = per_mesh[k];
  }
  return x;
}

// The tracer's parameter vector `x` per refined mesh.
std::vector<Eigen::VectorXd> Unpack(const DifferentiablePathTracer& tracer,
                                    const std::vector<int>& refined_meshes,
                                    const Eigen::VectorXd& x) {
  std::vector<Eigen::VectorXd> per_mesh;
  for (int m : refined_meshes) {
    const Eigen::Index n =
        3 * static_cast<Eigen::Index>(tracer.scene().meshes[m].mesh.vertices.size());
    per_mesh.push_back(x.segment(3 * tracer.ParameterVertex(m, 0), n));
  }
  return per_mesh;
}

// The scene's refined meshes with their vertices at `positions` (per mesh), normals area-weighted.
std::vector<TriangleMesh> MeshesAt(const Scene& scene, const std::vector<int>& refined_meshes,
                                   const std::vector<Eigen::VectorXd>& positions) {
  std::vector<TriangleMesh> meshes;
  for (size_t k = 0; k < refined_meshes.size(); ++k) {
    TriangleMesh mesh = scene.meshes[refined_meshes[k]].mesh;
    for (size_t v = 0; v < mesh.vertices.size(); ++v)
      mesh.vertices[v] = positions[k].segment<3>(3 * v).cast<float>();
    mesh.ComputeVertexNormals();
    meshes.push_back(std::move(mesh));
  }
  return meshes;
}

// --- Geometry of the refined meshes --------------------------------------------------------------

// Mean edge length of the refined meshes (each edge counted once per face side).
double MeanEdgeLength(const DifferentiablePathTracer& tracer) {
  double sum = 0.0;
  size_t count = 0;
  for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
    if (tracer.ParameterVertex(static_cast<int>(m), 0) < 0) continue;
    const TriangleMesh& mesh = tracer.scene().meshes[m].mesh;
    for (const Eigen::Vector3i& f : mesh.faces) {
      for (int k = 0; k < 3; ++k)
        sum += (mesh.vertices[f[k]] - mesh.vertices[f[(k + 1) % 3]]).norm(), ++count;
    }
  }
  return count > 0 ? sum / count : 1.0;
}

// The faces of the refined meshes in parameter-vertex indices (3 v per face: x at 3 v).
std::vector<Eigen::Vector3i> ParameterFaces(const DifferentiablePathTracer& tracer) {
  std::vector<Eigen::Vector3i> faces;
  for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
    const int mesh = static_cast<int>(m);
    if (tracer.ParameterVertex(mesh, 0) < 0) continue;
    for (const Eigen::Vector3i& f : tracer.scene().meshes[m].mesh.faces) {
      faces.emplace_back(tracer.ParameterVertex(mesh, f[0]), tracer.ParameterVertex(mesh, f[1]),
                         tracer.ParameterVertex(mesh, f[2]));
    }
  }
  return faces;
}

// --- Levenberg-Marquardt -------------------------------------------------------------------------

std::chrono::steady_clock::time_point Now() {
  return std::chrono::steady_clock::now();
}
double SecondsSince(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(Now() - since).count();
}

// What stays fixed over the iterations: the pixel sample, the data term's scale and the vertices
// held in place.
struct Problem {
  std::vector<PixelRef> pixels;
  double rms = 0.0;        // s, the RMS of the reference over the pixels
  double scale = 0.0;      // noise * s: the residuals' unit
  double channels = 0.0;   // 3 per pixel
  std::vector<bool> held;  // vertices that no fitted pixel sees directly (unless refine_unseen)
};

Problem SetUp(const DifferentiablePathTracer& tracer, const std::vector<PosedImage>& targets,
              const RefineOptions& options, uint64_t seed) {
  Problem p;
  const PathTracer plain(tracer.scene());  // built once for the pixel sample and the seen vertices
  p.pixels = SamplePixels(tracer, plain, targets, options.pixels_per_view, options.edge_margin,
                          options.refined_pixels_only, seed);
  p.rms = ReferenceRms(targets, p.pixels);
  p.scale = options.noise * p.rms;
  p.held.assign(tracer.VertexCount(), false);
  if (!options.refine_unseen) {
    const std::vector<bool> seen = SeenVertices(tracer, plain, targets, p.pixels);
    for (size_t v = 0; v < seen.size(); ++v) p.held[v] = !seen[v];
  }
  p.channels = 3.0 * p.pixels.size();
  return p;
}

// One iteration's linear model of E at x.
struct Linearisation {
  NormalEquations equations;
  Eigen::VectorXd prior_gradient;             // of the regularisers
  std::vector<Eigen::Matrix3d> prior_blocks;  // w_i P_i
  double cost = 0.0;                          // E(x)
};

// Levenberg-Marquardt on E over the tracer's parameter vector x, from the tracer's positions x0.
// Start traces x0; each Iterate linearises E at x and tries damped steps until one lowers E. The
// tracer is left at x.
class LevenbergMarquardt {
 public:
  LevenbergMarquardt(DifferentiablePathTracer& tracer, const std::vector<PosedImage>& targets,
                     const RefineOptions& options, uint64_t seed)
      : tracer_(tracer),
        targets_(targets),
        options_(options),
        seed_(seed),
        problem_(SetUp(tracer, targets, options, seed)),
        initial_(tracer.Positions()),
        x_(initial_),
        regularisers_(tracer, options, initial_, problem_.held),
        faces_(ParameterFaces(tracer)),
        mu_(options.damping),
        max_radius_(options.max_step * MeanEdgeLength(tracer)),
        radius_(max_radius_) {}

  int pixels() const { return static_cast<int>(problem_.pixels.size()); }
  const Eigen::VectorXd& initial() const { return initial_; }
  const Eigen::VectorXd& x() const { return x_; }

  RefineIteration Start();
  // Iteration `it` (1, 2, ...); `*start_cost` is E at x before its step.
  RefineIteration Iterate(int it, double* start_cost);

 private:
  Evaluation Trace(uint64_t seed, bool derivatives) const {
    return Evaluate(tracer_, targets_, problem_.pixels, options_, seed, problem_.scale,
                    derivatives);
  }
  double DataRmse() const {
    return std::sqrt(current_.sum_squared / problem_.channels) / problem_.rms;
  }
  Linearisation Linearise();
  bool TryStep(int it, uint64_t it_seed, const Linearisation& at, RefineIteration* record);

  DifferentiablePathTracer& tracer_;
  const std::vector<PosedImage>& targets_;
  const RefineOptions& options_;
  const uint64_t seed_;
  const Problem problem_;
  const Eigen::VectorXd initial_;  // x0
  Eigen::VectorXd x_;
  Regularisers regularisers_;
  const std::vector<Eigen::Vector3i> faces_;  // for the fold guard
  double mu_;                                 // damping
  const double max_radius_;                   // trust region: largest vertex move per step, m
  double radius_;
  Evaluation current_;  // the trace at x
};

RefineIteration LevenbergMarquardt::Start() {
  const auto start = Now();
  // With resampling every iteration traces its own linearisation: the start needs values only.
  current_ = Trace(seed_, !options_.resample);
  RefineIteration first;
  first.cost = current_.data_cost + regularisers_.Cost(x_);
  first.data_rmse = DataRmse();
  first.damping = options_.damping;
  first.accepted = true;
  first.seconds = SecondsSince(start);
  first.rays = current_.rays;
  return first;
}

RefineIteration LevenbergMarquardt::Iterate(int it, double* start_cost) {
  const auto start = Now();
  RefineIteration record;
  record.iteration = it;
  // 1. Fresh random numbers each iteration (the same for its trials): a fixed sample would let
  //    the vertices fit its noise. A full step then lands on the optimum of its own sample's noise.
  const uint64_t it_seed = options_.resample ? seed_ + 7919 * static_cast<uint64_t>(it) : seed_;
  if (options_.resample) {
    tracer_.SetPositions(x_, true);
    current_ = Trace(it_seed, true);
    record.rays.intersect += current_.rays.intersect;
    record.rays.occluded += current_.rays.occluded;
  }
  // 2. The linear model at x.
  const Linearisation at = Linearise();
  record.jacobian_nonzeros_per_pixel = at.equations.nonzeros / problem_.pixels.size();
  record.cost = at.cost;
  // 3. Steps, each more damped and shorter than the last, until one lowers E.
  for (int attempt = 0; attempt <= options_.max_retries; ++attempt) {
    if (TryStep(it, it_seed, at, &record)) break;
  }
  if (!record.accepted) tracer_.SetPositions(x_);
  record.data_rmse = DataRmse();
  record.damping = mu_;
  record.seconds = SecondsSince(start);
  *start_cost = at.cost;
  return record;
}

Linearisation LevenbergMarquardt::Linearise() {
  regularisers_.Relinearise(x_);
  Linearisation at;
  at.equations = Assemble(current_, tracer_.VertexCount(), options_.robust,
                          tracer_.VertexCount() <= options_.direct_max_vertices);
  at.prior_gradient = regularisers_.Gradient(x_);
  at.prior_blocks = regularisers_.PriorBlocksAt(x_);
  at.cost = current_.data_cost + regularisers_.Cost(x_);
  return at;
}

// One trial step from x: solved with the damping mu, cut to the trust region, averaged, passed
// through the fold guard, and traced with the iteration's random numbers. Kept when it lowers E
// (then mu falls and the region grows), else mu rises and the region shrinks.
bool LevenbergMarquardt::TryStep(int it, uint64_t it_seed, const Linearisation& at,
                                 RefineIteration* record) {
  Eigen::VectorXd step =
      SolveStep(at.equations, at.prior_gradient, at.prior_blocks, regularisers_.Coupling(), mu_);
  // Trust region on the largest vertex move: the linear model holds over a fraction of an edge.
  double largest = 0.0;
  for (int v = 0; v < tracer_.VertexCount(); ++v)
    largest = std::max(largest, step.segment<3>(3 * v).norm());
  if (largest > radius_) step *= radius_ / largest;
  // Polyak-Ruppert averaging: step k > average_after moves 1 / (k - average_after) of the way, so
  // the positions become the mean of the steps' optima, each fitted to its own random numbers.
  if (options_.average_after > 0 && it > options_.average_after)
    step /= it - options_.average_after;
  record->held += HoldFoldingVertices(faces_, initial_, x_, &step);
  const Eigen::VectorXd trial = x_ + step;
  // Most steps are kept: trace the trial with derivatives, they are the next iteration's
  // (unless the next iteration draws new random numbers).
  const bool derivatives = it < options_.iterations && !options_.resample;
  tracer_.SetPositions(trial, derivatives);
  Evaluation evaluation = Trace(it_seed, derivatives);
  record->rays.intersect += evaluation.rays.intersect;
  record->rays.occluded += evaluation.rays.occluded;
  const double trial_cost = evaluation.data_cost + regularisers_.Cost(trial);
  if (trial_cost < at.cost) {
    x_ = trial;
    current_ = std::move(evaluation);
    record->accepted = true;
    record->cost = trial_cost;
    record->step_rms = std::sqrt(step.squaredNorm() / tracer_.VertexCount());
    mu_ = std::max(mu_ / 3.0, 1e-9);
    radius_ = std::min(2.0 * radius_, max_radius_);
    return true;
  }
  ++record->rejected;
  mu_ = std::max(mu_ * 4.0, 1e-6);
  radius_ *= 0.5;
  return false;
}

}  // namespace

RefineResult RefineVertices(const Scene& scene, const std::vector<int>& refined_meshes,
                            const std::vector<PosedImage>& targets, const RefineOptions& options,
                            uint64_t seed, const RefineProgress& progress,
                            const std::vector<Eigen::VectorXd>& start) {
  // 1. The inputs, and the tracer whose parameters are the refined meshes' vertices.
  options.Validate();
  const std::vector<bool> mask = RefinedMask(scene, refined_meshes);
  CheckTargets(targets);
  if (VertexCount(scene, refined_meshes) == 0)
    throw Error("vertex refinement: no vertices to refine");
  DifferentiablePathTracer tracer(scene, mask);
  if (!start.empty()) tracer.SetPositions(Pack(tracer, refined_meshes, start, "the start"));

  // 2. Levenberg-Marquardt from the starting positions.
  LevenbergMarquardt lm(tracer, targets, options, seed);
  RefineResult result;
  result.pixels = lm.pixels();
  result.history.push_back(lm.Start());
  if (progress) progress(result.history.back(), tracer);
  for (int it = 1; it <= options.iterations; ++it) {
    double cost = 0.0;
    result.history.push_back(lm.Iterate(it, &cost));
    const RefineIteration& record = result.history.back();
    if (progress) progress(record, tracer);
    if (!record.accepted) break;
    if (cost - record.cost < options.tolerance * cost) break;
  }

  // 3. The meshes at the final positions.
  result.initial = Unpack(tracer, refined_meshes, lm.initial());
  result.positions = Unpack(tracer, refined_meshes, lm.x());
  result.meshes = MeshesAt(scene, refined_meshes, result.positions);
  return result;
}

RefineLinearization LinearizeRefinement(const DifferentiablePathTracer& tracer,
                                        const std::vector<PosedImage>& targets,
                                        const RefineOptions& options, uint64_t seed,
                                        const Eigen::VectorXd* direction) {
  const std::vector<PixelRef> pixels =
      SamplePixels(tracer, PathTracer(tracer.scene()), targets, options.pixels_per_view,
                   options.edge_margin, options.refined_pixels_only, seed);
  const double scale = options.noise * ReferenceRms(targets, pixels);
  const Evaluation e = Evaluate(tracer, targets, pixels, options, seed, scale, true);
  RefineLinearization l;
  l.cost = e.data_cost;
  const NormalEquations n = Assemble(e, tracer.VertexCount(), options.robust, false);
  l.gradient = n.gradient;
  if (direction) {
    Eigen::VectorXd product;
    n.Multiply(*direction, &product);
    l.curvature = direction->dot(product);
  }
  return l;
}

HeldOutComparison CompareOnFreshPixels(const Scene& scene, const std::vector<int>& refined_meshes,
                                       const std::vector<PosedImage>& targets,
                                       const RefineOptions& options, uint64_t seed,
                                       const std::vector<Eigen::VectorXd>& a,
                                       const std::vector<Eigen::VectorXd>& b) {
  DifferentiablePathTracer tracer(scene, RefinedMask(scene, refined_meshes));
  const Eigen::VectorXd xa = Pack(tracer, refined_meshes, a, "the positions a"),
                        xb = Pack(tracer, refined_meshes, b, "the positions b");
  tracer.SetPositions(xb, false);
  const std::vector<PixelRef> pixels =
      SamplePixels(tracer, PathTracer(tracer.scene()), targets, options.pixels_per_view,
                   options.edge_margin, options.refined_pixels_only, seed);
  HeldOutComparison out;
  out.pixels = static_cast<int>(pixels.size());
  if (pixels.empty()) return out;
  const double rms = ReferenceRms(targets, pixels), channels = 3.0 * pixels.size();
  // Per pixel, the squared error summed over the channels.
  const auto errors_at = [&](const Eigen::VectorXd& x, double* rmse) {
    tracer.SetPositions(x, false);
    const Evaluation e = Evaluate(tracer, targets, pixels, options, seed, 1.0, false);
    *rmse = std::sqrt(e.sum_squared / channels) / rms;
    std::vector<double> squared(pixels.size(), 0.0);
    for (size_t i = 0; i < pixels.size(); ++i) {
      for (int c = 0; c < 3; ++c) squared[i] += e.rows[i][c].value() * e.rows[i][c].value();
    }
    return squared;
  };
  const std::vector<double> ea = errors_at(xa, &out.rmse_a), eb = errors_at(xb, &out.rmse_b);
  const double n = static_cast<double>(pixels.size());
  double mean = 0.0, var = 0.0;
  for (size_t i = 0; i < pixels.size(); ++i) mean += (ea[i] - eb[i]) / n;
  for (size_t i = 0; i < pixels.size(); ++i) var += (ea[i] - eb[i] - mean) * (ea[i] - eb[i] - mean);
  const double standard_error = pixels.size() > 1 ? std::sqrt(var / (n - 1.0) / n) : 0.0;
  out.improvement_z = standard_error > 0.0 ? mean / standard_error : 0.0;
  return out;
}

}  // namespace genscene::inverse
