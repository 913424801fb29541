// Vertex refinement speed against error.
//  1. The paper's replica (Fig. 4) with our own renderer: the icosphere in the Cornell box
//     (MakeIcosphereBox), one 106 x 80 reference view, two vertices that face the camera perturbed
//     by 20 % of the radius. Per iteration: seconds, image relative RMSE, the two vertices' errors
//     as a fraction of their perturbation, Jacobian non-zeros per pixel. Writes
//     OUT/fig4_refine.png: the reference, then the shading-only render (every albedo grey) per
//     iteration.
//  2. With --cycles ../shared/data: the same from Blender Cycles' icosphere_flat and
//     icosphere_smooth renders (cbox-cycles), with their geometry.
//  3. Every vertex perturbed with noise sigma = 5 % of the radius (per coordinate, or with
//     --radial-noise 1 along the radius): RMS vertex error per iteration and flipped faces, from
//     the replica's view and the two high ones behind the sphere (--views 3, the default), or with
//     --views N from the replica's and up to five more around the sphere (AroundTheSphere);
//     --noise-seed N draws other noise.
// Run by hand:  build/bench/bench_refine [--out DIR] [--ref-spp N] [--spp N] [--iterations N]
//               [--max-depth D] [--threads N] [--sections 123] [--seed N] [--prior M]
//               [--prior-tangent M] [--relax M] [--prior-robust K] [--robust K] [--damping D]
//               [--refined-only 0|1] [--refine-unseen 0|1] [--perturbation F] [--flat 0|1]
//               [--jacobian-depth D] [--average-after K] [--views N] [--radial-noise 0|1]
//               [--noise-seed N] [--smooth M] [--edge-margin PX]
// --help lists every flag. Diagnostics: --radial 1 also prints, per iteration, the
// Levenberg-Marquardt state and the vertex errors split along the sphere's radius and across it
// (2: per vertex too); --gradcheck the objective along the gradient; --views-png the references.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <utility>

#include "core/frame_source.h"
#include "core/image_io.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/synthetic.h"
#include "inverse/refine/vertex_refinement.h"
#include "render/formats/scene_io.h"
#include "render/procedural.h"

using namespace genscene;
using namespace genscene::inverse;
using namespace genscene::render;
namespace fs = std::filesystem;

namespace {

struct Settings {
  fs::path out = "bench_out";
  int ref_spp = 1024, spp = RefineOptions().paths.spp, iterations = 5, max_depth = -1;
  double perturbation = 0.2;  // of the radius
  double prior_sigma = RefineOptions().prior_sigma;
  double prior_tangent_sigma = RefineOptions().prior_tangent_sigma;
  double robust = RefineOptions().robust;
  double damping = RefineOptions().damping;
  double prior_robust = RefineOptions().prior_robust;
  double relax_sigma = RefineOptions().relax_sigma;
  double smooth_sigma = RefineOptions().smooth_sigma;
  bool refined_only = RefineOptions().refined_pixels_only;
  bool refine_unseen = RefineOptions().refine_unseen;
  int jacobian_depth = RefineOptions().jacobian_max_depth;
  int average_after = RefineOptions().average_after;
  int edge_margin = RefineOptions().edge_margin;
  int views = 3;              // section 3's views (AroundTheSphere)
  uint64_t noise_seed = 99;   // section 3's noise
  bool radial_noise = false;  // section 3's noise along the radius instead of per coordinate
  bool smooth = true;         // the replica's sphere shades with area-weighted vertex normals
  std::string sections = "123";
  uint64_t seed = 1;   // of the refinement's random numbers
  std::string cycles;  // ../shared/data: section 2 from the Cycles renders
  int radial = 0;  // diagnostic: 1 the LM state and radial / tangential errors, 2 per vertex too
  bool gradcheck = false;  // diagnostic: the objective along -gradient against its slope
  bool views_png = false;  // diagnostic: the references side by side
};

void Paste(ImageRgb& canvas, const ImageRgb& image, int x0) {
  for (int v = 0; v < image.height(); ++v) {
    for (int u = 0; u < image.width(); ++u) canvas(x0 + u, v) = image(u, v);
  }
}

// The mesh's vertices, (x, y, z) each.
Eigen::VectorXd VertexPositions(const TriangleMesh& mesh) {
  Eigen::VectorXd x(3 * mesh.vertices.size());
  for (size_t v = 0; v < mesh.vertices.size(); ++v)
    x.segment<3>(3 * v) = mesh.vertices[v].cast<double>();
  return x;
}

RefineOptions OptionsOf(const Settings& s) {
  RefineOptions options;
  options.paths.spp = s.spp;
  options.iterations = s.iterations;
  options.paths.max_depth = s.max_depth;
  options.jacobian_max_depth = s.jacobian_depth;
  options.average_after = s.average_after;
  options.edge_margin = s.edge_margin;
  options.prior_sigma = s.prior_sigma;
  options.prior_tangent_sigma = s.prior_tangent_sigma;
  options.robust = s.robust;
  options.damping = s.damping;
  options.prior_robust = s.prior_robust;
  options.relax_sigma = s.relax_sigma;
  options.smooth_sigma = s.smooth_sigma;
  options.refined_pixels_only = s.refined_only;
  options.refine_unseen = s.refine_unseen;
  return options;
}

// Diagnostic (--gradcheck): the data term along -gradient against its slope, and along the way
// from `start` to the truth against the Gauss-Newton model.
void GradientCheck(const Scene& scene, int sphere, const std::vector<PosedImage>& targets,
                   const Eigen::VectorXd& truth, const Eigen::VectorXd& start,
                   const RefineOptions& options) {
  std::vector<bool> mask(scene.meshes.size(), false);
  mask[sphere] = true;
  DifferentiablePathTracer tracer(scene, mask);
  tracer.SetPositions(start);
  const RefineLinearization l = LinearizeRefinement(tracer, targets, options);
  const Eigen::VectorXd d = -l.gradient.normalized();
  std::printf("gradient check: E %.6g, |g| %.4g\n", l.cost, l.gradient.norm());
  for (double eps : {1e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2}) {
    tracer.SetPositions(start + eps * d);
    const double e = LinearizeRefinement(tracer, targets, options).cost;
    std::printf("  eps %.0e: E change %.6g, predicted %.6g\n", eps, e - l.cost,
                -eps * l.gradient.norm());
  }
  const Eigen::VectorXd to_truth = truth - start;
  const double curvature = LinearizeRefinement(tracer, targets, options, 1, &to_truth).curvature;
  std::printf(
      "  slope towards the truth: AD %.6g per unit t, Gauss-Newton curvature %.6g: model E(1) - "
      "E(0) = %.6g\n",
      l.gradient.dot(to_truth), curvature, l.gradient.dot(to_truth) + 0.5 * curvature);
  for (double t : {0.0, 0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 1.0}) {
    tracer.SetPositions(start + t * to_truth);
    std::printf("  t %.2f: E %.6g\n", t, LinearizeRefinement(tracer, targets, options).cost);
  }
}

// Diagnostic (--radial 1): the LM state and the vertex errors `d` = x - truth split along the
// sphere's radius (signed) and across it, for the watched vertices and as RMS over all; with
// --radial 2 every vertex's radial error, marked F (facing `view`), s (side) or b (back).
void PrintRadialErrors(const RefineIteration& it, const Eigen::VectorXd& d,
                       const Eigen::VectorXd& truth, const std::vector<int>& watched,
                       const PosedView& view, int radial_level) {
  const int vertices = static_cast<int>(d.size() / 3);
  std::printf("   cost %.6g step %.5f rejected %d damping %.3g accepted %d\n", it.cost, it.step_rms,
              it.rejected, it.damping, it.accepted ? 1 : 0);
  // Both spheres are centred at (0, 0, 0.201).
  const auto split = [&](int v) {
    const Eigen::Vector3d e = d.segment<3>(3 * v);
    const Eigen::Vector3d n =
        (truth.segment<3>(3 * v) - Eigen::Vector3d(0.0, 0.0, 0.201)).normalized();
    return std::make_pair(e.dot(n), (e - e.dot(n) * n).norm());
  };
  for (int v : watched) {
    const auto [radial, across] = split(v);
    std::printf("   v%d radial %+.5f tangential %.5f\n", v, radial, across);
  }
  double rad = 0.0, tan = 0.0;
  for (int v = 0; v < vertices; ++v) {
    const auto [radial, across] = split(v);
    rad += radial * radial;
    tan += across * across;
  }
  if (radial_level == 2) {
    std::printf("   radial mm:");
    const Eigen::Vector3d eye = view.world_from_camera.translation().cast<double>();
    for (int v = 0; v < vertices; ++v) {
      const Eigen::Vector3d p = truth.segment<3>(3 * v),
                            n = (p - Eigen::Vector3d(0.0, 0.0, 0.201)).normalized();
      std::printf(" %d%s:%+.1f", v,
                  n.dot((eye - p).normalized()) > 0.3 ? "F"
                  : n.dot(eye - p) > 0                ? "s"
                                                      : "b",
                  1000.0 * split(v).first);
    }
    std::printf("\n");
  }
  std::printf("   all: radial RMS %.5f tangential RMS %.5f\n", std::sqrt(rad / vertices),
              std::sqrt(tan / vertices));
}

// Refines `sphere` of `scene` from `start` against `targets`; prints the table; returns the
// shading renders per iteration.
std::vector<ImageRgb> RunCase(const char* name, const Scene& scene, int sphere,
                              const std::vector<PosedImage>& targets, const Eigen::VectorXd& truth,
                              const Eigen::VectorXd& start, const std::vector<int>& watched,
                              const Settings& s) {
  const PosedView& view = targets[0].view;
  const std::vector<int> refined = {sphere};
  const RefineOptions options = OptionsOf(s);
  RefineOptions none = options;
  none.iterations = 0;
  const double truth_rmse = RefineVertices(scene, refined, targets, none).history[0].data_rmse;
  if (s.gradcheck) GradientCheck(scene, sphere, targets, truth, start, options);

  // The sphere at the start, for the flipped faces.
  TriangleMesh start_mesh = scene.meshes[sphere].mesh;
  for (size_t v = 0; v < start_mesh.vertices.size(); ++v)
    start_mesh.vertices[v] = start.segment<3>(3 * v).cast<float>();
  const int vertices = static_cast<int>(start_mesh.vertices.size());
  std::printf(
      "\n%s: %d vertices, %zu view(s) of %dx%d, %d spp per evaluation; image RMSE of the truth "
      "itself %.4f\n",
      name, vertices, targets.size(), view.intrinsics.width, view.intrinsics.height, s.spp,
      truth_rmse);
  std::printf("%5s %9s %10s %11s %12s %12s %9s %8s\n", "iter", "seconds", "image", "vertex RMS",
              "watched max", "(fraction)", "nnz/px", "flipped");
  std::vector<ImageRgb> shading;
  RenderOptions render;
  render.spp = 64;
  const double perturbation = (start - truth).cwiseAbs().maxCoeff() > 0 ? [&] {
    double m = 0.0;
    for (int v : watched) m = std::max(m, (start - truth).segment<3>(3 * v).norm());
    return m;
  }() : 1.0;
  double total = 0.0;
  const auto progress = [&](const RefineIteration& it, const DifferentiablePathTracer& at) {
    const Eigen::VectorXd d = at.Positions() - truth;
    double watched_max = 0.0;
    for (int v : watched) watched_max = std::max(watched_max, d.segment<3>(3 * v).norm());
    if (s.radial > 0) PrintRadialErrors(it, d, truth, watched, view, s.radial);
    total += it.seconds;
    std::printf("%5d %9.2f %10.4f %11.5f %12.5f %12.3f %9.1f %8d\n", it.iteration, it.seconds,
                it.data_rmse, std::sqrt(d.squaredNorm() / at.VertexCount()), watched_max,
                watched_max / perturbation, it.jacobian_nonzeros_per_pixel,
                FlippedFaces(start_mesh, at.scene().meshes[sphere].mesh));
    std::fflush(stdout);
    shading.push_back(PathTracer(ShadingOnly(at.scene())).Render(view, render, 3).radiance);
  };
  const RefineResult result =
      RefineVertices(scene, refined, targets, options, s.seed, progress, {start});
  std::printf("total %.1f s for %zu iterations (%.2f s per iteration)\n", total,
              result.history.size() - 1,
              (total - result.history[0].seconds) / std::max<size_t>(1, result.history.size() - 1));
  return shading;
}

// The replica's reference image (our path tracer, s.ref_spp) and its true sphere vertices.
std::pair<ImageRgb, Eigen::VectorXd> ReferenceAndTruth(const IcosphereBox& box, const Settings& s) {
  RenderOptions render;
  render.spp = s.ref_spp;
  render.max_depth = s.max_depth;
  return {PathTracer(box.scene).Render(box.view, render, 1234).radiance,
          VertexPositions(box.scene.meshes[box.sphere].mesh)};
}

void Replica(const Settings& s) {
  const IcosphereBox box = MakeIcosphereBox(s.smooth);
  const auto [reference, truth] = ReferenceAndTruth(box, s);
  const SpikeAndDent start =
      PerturbFacingVertices(box.scene.meshes[box.sphere].mesh, box.center, box.radius,
                            box.view.world_from_camera.translation(), s.perturbation * box.radius);
  const std::vector<ImageRgb> shading =
      RunCase("1. Replica (our renderer, two vertices +-20 % of r)", box.scene, box.sphere,
              {{box.view, reference}}, truth, start.positions, {start.spike, start.dent}, s);
  ImageRgb canvas(reference.width() * (1 + static_cast<int>(shading.size())), reference.height());
  Paste(canvas, reference, 0);
  for (size_t i = 0; i < shading.size(); ++i)
    Paste(canvas, shading[i], reference.width() * (1 + static_cast<int>(i)));
  WritePng(s.out / "fig4_refine.png", canvas);
  std::printf("-> %s (reference, then the shading render of iterations 0..%zu)\n",
              (s.out / "fig4_refine.png").c_str(), shading.size() - 1);
}

void Cycles(const fs::path& data, const Settings& s) {
  for (const char* variant : {"icosphere_flat", "icosphere_smooth"}) {
    const fs::path root = data / "cbox-cycles" / variant;
    const Scene scene = LoadCyclesScene(root);
    int sphere = -1;
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
      if (scene.meshes[m].name.find("ico") != std::string::npos) sphere = static_cast<int>(m);
    }
    if (sphere < 0) {
      std::printf("%s: no icosphere mesh\n", variant);
      continue;
    }
    auto source = OpenFrameSource((root / "views" / "full").string(), SourceOptions());
    const auto frame = source->Next();
    const PosedView view{frame->intrinsics, *frame->world_from_camera, frame->timestamp};
    const Eigen::VectorXd truth = VertexPositions(scene.meshes[sphere].mesh);
    const Eigen::Vector3d center(0.0, 0.0, 0.201);
    const SpikeAndDent start = PerturbFacingVertices(scene.meshes[sphere].mesh, center, 0.2,
                                                     view.world_from_camera.translation(), 0.04);
    const std::string name = std::string("2. Cycles ") + variant + " (two vertices +-20 % of r)";
    RunCase(name.c_str(), scene, sphere, {{view, frame->color}}, truth, start.positions,
            {start.spike, start.dent}, s);
  }
}

// The views of section 3: the replica's, then up to five more inside the box around the sphere (in
// this order: two high in the back corners, two low in the front corners, one low at the back
// wall), wider (f = 70 px) so that the sphere fits from half a metre. Together they see all but the
// vertices next to the floor.
std::vector<PosedView> AroundTheSphere(const IcosphereBox& box, int count) {
  std::vector<PosedView> views = {box.view};
  const Eigen::Vector3d eyes[] = {{-0.42, 0.42, 0.8},
                                  {0.42, 0.42, 0.8},
                                  {-0.44, -0.44, 0.1},
                                  {0.44, -0.44, 0.1},
                                  {0.0, 0.47, 0.12}};
  for (int i = 0; i + 1 < count && i < 5; ++i) {
    PosedView v = box.view;
    v.intrinsics = CameraIntrinsics{70.0, 70.0, 52.5, 39.5, 106, 80};
    v.world_from_camera = LookAt(eyes[i], box.center);
    views.push_back(v);
  }
  return views;
}

void AllVertices(const Settings& s) {
  const IcosphereBox box = MakeIcosphereBox(s.smooth);
  const auto [reference, truth] = ReferenceAndTruth(box, s);
  std::vector<PosedImage> targets = {{box.view, reference}};
  RenderOptions render;
  render.spp = s.ref_spp;
  render.max_depth = s.max_depth;
  const std::vector<PosedView> views = AroundTheSphere(box, s.views);
  const PathTracer renderer(box.scene);
  for (size_t i = 1; i < views.size(); ++i) {
    targets.push_back({views[i], renderer.Render(views[i], render, 1234 + i).radiance});
  }
  if (s.views_png) {  // diagnostic: the references side by side
    ImageRgb canvas(reference.width() * static_cast<int>(targets.size()), reference.height());
    for (size_t i = 0; i < targets.size(); ++i)
      Paste(canvas, targets[i].image, reference.width() * static_cast<int>(i));
    WritePng(s.out / "views.png", canvas);
  }
  Eigen::VectorXd start = truth;
  CounterRng rng(s.noise_seed, 1);
  if (s.radial_noise) {  // along each vertex's direction from the centre only
    for (int v = 0; v < start.size() / 3; ++v) {
      const Eigen::Vector3d n = (truth.segment<3>(3 * v) - box.center.cast<double>()).normalized();
      start.segment<3>(3 * v) += 0.05 * box.radius * rng.Normal() * n;
    }
  } else {
    for (int i = 0; i < start.size(); ++i) start[i] += 0.05 * box.radius * rng.Normal();
  }
  std::vector<int> all(truth.size() / 3);
  for (size_t v = 0; v < all.size(); ++v) all[v] = static_cast<int>(v);
  const std::string name = std::string("3. Every vertex perturbed, sigma = 5 % of r") +
                           (s.radial_noise ? " along the radius" : " per coordinate");
  RunCase(name.c_str(), box.scene, box.sphere, targets, truth, start, all, s);
}

}  // namespace

int main(int argc, char** argv) {
  Settings s;
  int threads = 0;
  CLI::App app{
      "bench_refine: vertex refinement on the paper's Fig. 4 replica (section 1), the Cycles "
      "renders "
      "(section 2, with --cycles) and every vertex perturbed (section 3): per iteration seconds, "
      "image error "
      "and vertex errors."};
  app.add_option("--out", s.out, "folder for the figure")->capture_default_str();
  app.add_option("--ref-spp", s.ref_spp, "paths per pixel of the references")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--spp", s.spp, "paths per pixel of the refinement")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--iterations", s.iterations, "Levenberg-Marquardt iterations")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-depth", s.max_depth, "longest path (Mitsuba convention; -1 = unlimited)")
      ->capture_default_str();
  app.add_option("--threads", threads, "worker threads (0: all cores)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--sections", s.sections, "which sections to run (digits 1, 2, 3)")
      ->capture_default_str();
  app.add_option("--perturbation", s.perturbation,
                 "section 1's perturbation, a fraction of the radius")
      ->capture_default_str();
  app.add_option("--prior", s.prior_sigma, "prior_sigma [m]")->capture_default_str();
  app.add_option("--prior-tangent", s.prior_tangent_sigma, "prior_tangent_sigma [m]")
      ->capture_default_str();
  app.add_option("--robust", s.robust, "Huber threshold of the residuals in noise units")
      ->capture_default_str();
  app.add_option("--refine-unseen", s.refine_unseen, "refine vertices no pixel sees (0 or 1)")
      ->capture_default_str();
  app.add_option("--refined-only", s.refined_only,
                 "only pixels whose first hit is a refined mesh (0 or 1)")
      ->capture_default_str();
  app.add_option("--relax", s.relax_sigma, "relax_sigma [m]")->capture_default_str();
  app.add_option("--smooth", s.smooth_sigma, "smooth_sigma [m]")->capture_default_str();
  app.add_option("--prior-robust", s.prior_robust, "prior_robust [sigma]")->capture_default_str();
  app.add_option("--damping", s.damping, "initial Levenberg-Marquardt damping")
      ->capture_default_str();
  app.add_option("--seed", s.seed, "seed of the refinement's random numbers")
      ->capture_default_str();
  app.add_option("--jacobian-depth", s.jacobian_depth, "jacobian_max_depth [segments]")
      ->capture_default_str();
  app.add_option("--average-after", s.average_after, "average the steps after this many iterations")
      ->capture_default_str();
  app.add_option("--edge-margin", s.edge_margin, "pixels next to silhouettes left out [px]")
      ->capture_default_str();
  app.add_option("--views", s.views, "section 3's views")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--noise-seed", s.noise_seed, "section 3's noise draw")->capture_default_str();
  app.add_option("--radial-noise", s.radial_noise, "section 3's noise along the radius (0 or 1)")
      ->capture_default_str();
  bool flat = !s.smooth;
  app.add_option("--flat", flat, "the replica's sphere flat-shaded (0 or 1)")
      ->capture_default_str();
  app.add_option("--cycles", s.cycles,
                 "../shared/data: section 2 from the Cycles renders of DATA/cbox-cycles");
  app.add_option(
         "--radial", s.radial,
         "diagnostic: 1 prints the LM state and radial / tangential errors, 2 per vertex too")
      ->check(CLI::Range(0, 2));
  app.add_flag("--gradcheck", s.gradcheck,
               "diagnostic: the objective along -gradient against its slope");
  app.add_flag("--views-png", s.views_png, "diagnostic: write the references side by side");
  CLI11_PARSE(app, argc, argv);
  s.smooth = !flat;
  if (threads > 0) SetThreadCount(threads);
  fs::create_directories(s.out);
  std::printf(
      "Vertex refinement: Levenberg-Marquardt on the sparse forward-mode AD path tracer, %d "
      "threads\n",
      ThreadCount());
  if (s.sections.find('1') != std::string::npos) Replica(s);
  if (s.sections.find('2') != std::string::npos) {
    if (!s.cycles.empty()) {
      Cycles(s.cycles, s);
    } else {
      std::printf("\n2. Cycles: skipped (give --cycles ../shared/data)\n");
    }
  }
  if (s.sections.find('3') != std::string::npos) AllVertices(s);
  return 0;
}
