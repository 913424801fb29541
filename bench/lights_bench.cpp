// Light estimation speed against error.
//  1. The paper's replica (Fig. 3) with our own renderer: the Cornell box of MakeCornellBoxScene
//     lit by its 0.5 m ceiling light, 3 training views + 2 novel views; the light removed, voxel
//     lights estimated on a 7^3 grid from 3000 pixels per view. For each penalty weight: active
//     voxels, training and novel relative RMSE (raw and with the Monte Carlo noise of both images
//     taken out), seconds. Writes OUT/fig3_lights.png: per weight, the voxel powers seen from above
//     (x-y, summed over z) and the first training view rendered with the estimate.
//  2. Time to error against plain first-order gradient descent on the per-pixel cost without the
//     cache (each step re-traces the paths of the sampled pixels and descends along the gradient
//     of their squared residual); written as a table and OUT/lights_time_to_error.png.
//  3. With --cycles ../shared/data: the Cycles Cornell box, novel-view RMSE and the power-weighted
//     centroid of the voxels against the light.
// Run by hand:  build/bench/bench_lights [--out DIR] [--size WxH] [--ref-spp N] [--spp N]
//               [--eval-spp N] [--gamma G] [--weights w1,w2,..] [--threads N]
//               [--gd-seconds S] [--gd-spp N]
// --gd-seconds: section 2's time budget for gradient descent (default: 10x the time the cached
// method took to its last error, so "not reached" means over 10x slower; 0 skips section 2).
// Overrides of the estimate's options (--help lists them: --max-depth, --rounds, --refine-*, ...)
// and diagnostics: --voxel-truth (the truth is one voxel light the grid can hold), --dump (the
// estimate's active voxels), --oracle (the replica's light as one voxel and as grids of points),
// --fine-check (a 14^3 grid solved around the replica's light), --solver-check (the solver's cost
// against the truth's).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>

#include "core/color.h"
#include "core/frame_source.h"
#include "core/image_io.h"
#include "core/parallel.h"
#include "inverse/lights/light_estimation.h"
#include "render/formats/scene_io.h"
#include "render/procedural.h"

using namespace genscene;
using namespace genscene::inverse;
using namespace genscene::render;
namespace fs = std::filesystem;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Replica {
  Scene scene;
  std::vector<PosedImage> train, novel;
  std::vector<double> noise;  // RMS noise per channel of each reference (train, then novel)
};

// The bench's flags beyond its own: overrides of the estimate's options (unset: the defaults) and
// the diagnostics.
struct Overrides {
  std::optional<int> max_depth, rounds, refine_levels, refine_coarse_pixels, refine_spp,
      refine_grow, direct_paths, resample_voxels, split_depth;
  std::optional<double> refine_penalty_scale, refine_fraction, refine_reach, grid_margin;
  bool distant = false;  // the estimate's distant light (--distant)
  uint64_t seed = 7;     // the estimate's seed (--seed)
  bool voxel_truth = false, dump = false, oracle = false, fine_check = false, solver_check = false;
  std::string cycles;  // ../shared/data: section 3 instead
  std::optional<std::string> exposure;
};
Overrides g_flags;

// The references are slow to render: kept in `cache` (EXR + noise.txt) and reused when present.
Replica MakeReplica(int width, int height, int spp, const fs::path& cache) {
  Replica r;
  const fs::path dir = cache / ("replica_" + std::to_string(width) + "x" + std::to_string(height) +
                                "_" + std::to_string(spp) + (g_flags.voxel_truth ? "_voxel" : "") +
                                (g_flags.max_depth ? "_d" : ""));
  if (fs::exists(dir / "noise.txt")) {
    r.scene = MakeCornellBoxScene();
    const std::vector<PosedView> views = CornellLightViews(width, height);
    FILE* f = std::fopen((dir / "noise.txt").c_str(), "r");
    for (size_t i = 0; i < views.size(); ++i) {
      double noise = 0.0;
      if (std::fscanf(f, "%lf", &noise) != 1) break;
      r.noise.push_back(noise);
      CameraResponse linear;
      linear.kind = CameraResponse::Kind::kLinear;
      PosedImage tv{views[i], ReadColorImage(dir / ("view" + std::to_string(i) + ".exr"), linear)};
      (i < 3 ? r.train : r.novel).push_back(std::move(tv));
    }
    std::fclose(f);
    return r;
  }
  r.scene = MakeCornellBoxScene();
  if (g_flags.voxel_truth) {  // diagnostic: the truth is a voxel light the grid can represent
    Scene s = WithoutLights(r.scene);
    VoxelLightGrid g = MakeVoxelGrid(s, 7);  // the estimate's grid (default inset)
    g.intensity[3 + 7 * 3 + 49 * 6] = Eigen::Vector3f(3.0f, 2.5f, 1.8f);
    g.weights[3 + 7 * 3 + 49 * 6] = {0.1f, 0.1f, 0.1f, 0.1f, 0.0f, 1.0f};
    s.voxel_lights = g;
    r.scene = s;
  }
  const PathTracer tracer(r.scene);
  RenderOptions ro;
  ro.spp = spp;
  if (g_flags.max_depth) ro.max_depth = *g_flags.max_depth;
  const std::vector<PosedView> views = CornellLightViews(width, height);
  for (size_t i = 0; i < views.size(); ++i) {
    const RenderHalves halves = RenderInHalves(tracer, views[i], ro, 1000 + i, 2000 + i);
    r.noise.push_back(halves.NoiseRms());
    (i < 3 ? r.train : r.novel).push_back(PosedImage{views[i], halves.mean});
  }
  fs::create_directories(dir);
  FILE* f = std::fopen((dir / "noise.txt").c_str(), "w");
  for (size_t i = 0; i < views.size(); ++i) {
    WriteExr(dir / ("view" + std::to_string(i) + ".exr"),
             i < 3 ? r.train[i].image : r.novel[i - 3].image);
    std::fprintf(f, "%.9g\n", r.noise[i]);
  }
  std::fclose(f);
  return r;
}

// The intensity of MakeCornellBoxScene's ceiling light seen as a point facing down: its radiance
// (18, 15, 11) times its area (0.5 m)^2. The diagnostics share it among voxels.
const Eigen::Vector3f kReplicaLightIntensity = Eigen::Vector3f(18.0f, 15.0f, 11.0f) * 0.25f;

// The five views of the replica (3 training, 2 novel) rendered with `lights` in its geometry,
// against their references.
std::vector<ViewError> ReplicaErrors(const Replica& replica, const VoxelLightGrid& lights,
                                     int eval_spp) {
  Scene lit = WithoutLights(replica.scene);
  lit.voxel_lights = lights;
  const PathTracer tracer(lit);
  std::vector<ViewError> errors;
  for (size_t i = 0; i < replica.train.size() + replica.novel.size(); ++i) {
    const PosedImage& reference =
        i < replica.train.size() ? replica.train[i] : replica.novel[i - replica.train.size()];
    errors.push_back(
        CompareRender(tracer, reference, LightEstimationOptions(), eval_spp, 5, replica.noise[i]));
  }
  return errors;
}

// The estimate's options as the flags override them.
void ApplyOverrides(LightEstimationOptions* o) {
  const auto set = [](const auto& flag, auto* value) {
    if (flag) *value = *flag;
  };
  set(g_flags.max_depth, &o->paths.max_depth);
  set(g_flags.rounds, &o->rounds);
  set(g_flags.refine_levels, &o->refine_levels);
  set(g_flags.refine_penalty_scale, &o->refine_penalty_scale);
  set(g_flags.refine_fraction, &o->refine_fraction);
  set(g_flags.refine_grow, &o->refine_grow);
  set(g_flags.refine_coarse_pixels, &o->refine_coarse_pixels);
  set(g_flags.refine_spp, &o->refine_spp);
  set(g_flags.refine_reach, &o->refine_reach);
  set(g_flags.direct_paths, &o->direct_paths);
  set(g_flags.resample_voxels, &o->resample_voxels);
  set(g_flags.split_depth, &o->split_depth);
  set(g_flags.exposure, &o->exposure);
  set(g_flags.grid_margin, &o->grid_margin);
  if (g_flags.distant) o->distant = true;
  o->Validate();
}

// ---- Figures (OpenCV: 8-bit BGR canvases, text labels) ----------------------------------------

// Linear RGB to 8-bit BGR, exposure `scale`, gamma 2.2.
cv::Mat ToBgr(const ImageRgb& image, float scale) {
  cv::Mat out(image.height(), image.width(), CV_8UC3);
  for (int v = 0; v < image.height(); ++v) {
    for (int u = 0; u < image.width(); ++u) {
      const Eigen::Vector3f c = image(u, v) * scale;
      auto enc = [](float x) {
        return cv::saturate_cast<uint8_t>(255.0f *
                                          std::pow(std::clamp(x, 0.0f, 1.0f), 1.0f / 2.2f));
      };
      out.at<cv::Vec3b>(v, u) = cv::Vec3b(enc(c.z()), enc(c.y()), enc(c.x()));
    }
  }
  return out;
}

// The voxel powers (luminance) summed along axis `drop` (2: seen from above, x right, y up; 1:
// seen from the front, x right, z up), `cell` pixels per voxel, inferno colour map over
// [0, `scale`], and the true emitters' bounding box `truth` outlined in white.
cv::Mat PowerMap(const VoxelLightGrid& g, int drop, int cell, double scale,
                 const Eigen::AlignedBox3d& truth) {
  const int a = 0, b = drop == 2 ? 1 : 2;
  const int na = g.dims[a], nb = g.dims[b];
  cv::Mat sum(nb, na, CV_64F, cv::Scalar(0.0));
  for (int j = 0; j < g.VoxelCount(); ++j) {
    const int idx[3] = {j % g.dims.x(), (j / g.dims.x()) % g.dims.y(),
                        j / (g.dims.x() * g.dims.y())};
    sum.at<double>(nb - 1 - idx[b], idx[a]) += Luminance(g.Power(j));
  }
  cv::Mat gray;
  sum.convertTo(gray, CV_8U, scale > 0.0 ? 255.0 / scale : 0.0);
  cv::Mat big, colour;
  cv::resize(gray, big, cv::Size(na * cell, nb * cell), 0, 0, cv::INTER_NEAREST);
  cv::applyColorMap(big, colour, cv::COLORMAP_INFERNO);
  for (int i = 0; i <= na; ++i)
    cv::line(colour, {i * cell, 0}, {i * cell, nb * cell}, cv::Scalar(60, 60, 60));
  for (int i = 0; i <= nb; ++i)
    cv::line(colour, {0, i * cell}, {na * cell, i * cell}, cv::Scalar(60, 60, 60));
  if (!truth.isEmpty() && g.VoxelCount() > 1) {
    // Voxel i's centre is at pixel (i + 0.5) cell along each axis.
    const Eigen::Vector3d c0 = g.VoxelCenter(0);
    const Eigen::Vector3d step = g.VoxelCenter(g.VoxelCount() - 1) - c0;
    auto to_px = [&](int axis, double world) {
      return (0.5 + (world - c0[axis]) / step[axis] * (g.dims[axis] - 1)) * cell;
    };
    const double a0 = to_px(a, truth.min()[a]), a1 = to_px(a, truth.max()[a]);
    const double b0 = nb * cell - to_px(b, truth.max()[b]),
                 b1 = nb * cell - to_px(b, truth.min()[b]);
    cv::rectangle(colour,
                  cv::Point(static_cast<int>(std::lround(a0)), static_cast<int>(std::lround(b0))),
                  cv::Point(static_cast<int>(std::lround(a1)), static_cast<int>(std::lround(b1))),
                  cv::Scalar(255, 255, 255), 1);
  }
  return colour;
}

double MaxProjectedPower(const VoxelLightGrid& g) {
  double best = 0.0;
  for (int drop : {1, 2}) {
    std::vector<double> sum(static_cast<size_t>(g.VoxelCount()), 0.0);
    for (int j = 0; j < g.VoxelCount(); ++j) {
      const int x = j % g.dims.x(), y = (j / g.dims.x()) % g.dims.y(),
                z = j / (g.dims.x() * g.dims.y());
      best = std::max(best, sum[static_cast<size_t>(x + g.dims.x() * (drop == 2 ? y : z))] +=
                            Luminance(g.Power(j)));
    }
  }
  return best;
}

struct Fig3Row {
  std::string label;
  VoxelLightGrid lights;  // empty dims for the reference row
  ImageRgb render;
};

// Fig. 3 of the paper: one row per penalty weight (and the reference first): the voxel powers
// seen from above and from the front (the true emitters outlined), and the first training view
// rendered with the estimate. `grid`: the estimate's (empty) grid, for the reference row's maps.
void WriteFig3(const fs::path& path, const std::vector<Fig3Row>& rows, float exposure,
               const VoxelLightGrid& grid, const Eigen::AlignedBox3d& truth) {
  const int cell = 24, gap = 6;
  double scale = 0.0;
  for (const Fig3Row& r : rows) {
    if (r.lights.VoxelCount() > 0) scale = std::max(scale, MaxProjectedPower(r.lights));
  }
  std::vector<cv::Mat> lines;
  for (const Fig3Row& r : rows) {
    const int side = 7 * cell;
    const VoxelLightGrid& g = r.lights.VoxelCount() > 0 ? r.lights : grid;
    const cv::Mat top = PowerMap(g, 2, side / g.dims.x(), scale, truth);
    const cv::Mat front = PowerMap(g, 1, side / g.dims.x(), scale, truth);
    cv::Mat image = ToBgr(r.render, exposure), image_big;
    cv::resize(image, image_big, cv::Size(image.cols * top.rows / image.rows, top.rows), 0, 0,
               cv::INTER_NEAREST);
    cv::Mat line(top.rows + 24, top.cols + front.cols + image_big.cols + 2 * gap, CV_8UC3,
                 cv::Scalar(255, 255, 255));
    top.copyTo(line(cv::Rect(0, 24, top.cols, top.rows)));
    front.copyTo(line(cv::Rect(top.cols + gap, 24, front.cols, front.rows)));
    image_big.copyTo(
        line(cv::Rect(top.cols + front.cols + 2 * gap, 24, image_big.cols, image_big.rows)));
    cv::putText(line, r.label, {4, 17}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
    lines.push_back(line);
  }
  cv::Mat canvas;
  cv::vconcat(lines, canvas);
  if (!cv::imwrite(path.string(), canvas))
    std::fprintf(stderr, "bench_lights: cannot write %s\n", path.c_str());
}

// ---- Time to error: the cached normal equations against plain gradient descent ----------------

// Per parameter p = 6 j + k, the RGB product L_j lambda_jk (what the cache's rows multiply).
std::vector<Eigen::Vector3f> Products(const VoxelLightGrid& g) {
  std::vector<Eigen::Vector3f> x(static_cast<size_t>(6 * g.VoxelCount()));
  for (int j = 0; j < g.VoxelCount(); ++j) {
    for (int k = 0; k < 6; ++k)
      x[static_cast<size_t>(6 * j + k)] = g.intensity[j] * g.weights[j][k];
  }
  return x;
}

// Predicted pixels of `rows` for the products x.
std::vector<Eigen::Vector3d> PredictProducts(const LightCache& rows,
                                             const std::vector<Eigen::Vector3f>& x) {
  std::vector<Eigen::Vector3d> p(rows.pixels.size(), Eigen::Vector3d::Zero());
  for (size_t i = 0; i < rows.pixels.size(); ++i) {
    for (size_t e = rows.row_begin[i]; e < rows.row_begin[i + 1]; ++e) {
      p[i] +=
          rows.coefficient[e].cwiseProduct(x[static_cast<size_t>(rows.index[e])]).cast<double>();
    }
  }
  return p;
}

// sqrt(sum |P - I|^2 / sum |I|^2) over the rows' pixels.
double RelativeError(const LightCache& rows, const std::vector<Eigen::Vector3f>& x) {
  const std::vector<Eigen::Vector3d> p = PredictProducts(rows, x);
  double num = 0.0, den = 0.0;
  for (size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector3d observed = rows.pixels[i].observed.cast<double>();
    num += (p[i] - observed).squaredNorm();
    den += observed.squaredNorm();
  }
  return std::sqrt(num / den);
}

struct CurvePoint {
  double seconds = 0.0, error = 0.0;
};

// First time a curve's error is at or below `target` (NaN: never).
double TimeTo(const std::vector<CurvePoint>& curve, double target) {
  for (const CurvePoint& c : curve) {
    if (c.error <= target) return c.seconds;
  }
  return std::nan("");
}

void WriteCurves(const fs::path& path, const std::vector<CurvePoint>& cached,
                 const std::vector<CurvePoint>& gd, double max_seconds) {
  const int w = 640, h = 430, left = 60, right = 20, top = 30, bottom = 50;
  cv::Mat canvas(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  double e_min = 1e30, e_max = 0.0;
  for (const auto* c : {&cached, &gd}) {
    for (const CurvePoint& p : *c)
      e_min = std::min(e_min, p.error), e_max = std::max(e_max, p.error);
  }
  const double t0 = 0.1, l0 = std::log10(t0), l1 = std::log10(std::max(max_seconds, 1.0));
  const double y0 = std::log10(e_min * 0.9), y1 = std::log10(e_max * 1.1);
  auto px = [&](const CurvePoint& p) {
    const double x = (std::log10(std::max(p.seconds, t0)) - l0) / (l1 - l0);
    const double y = (std::log10(p.error) - y0) / (y1 - y0);
    return cv::Point(left + static_cast<int>(x * (w - left - right)),
                     h - bottom - static_cast<int>(y * (h - top - bottom)));
  };
  cv::rectangle(canvas, {left, top}, {w - right, h - bottom}, cv::Scalar(0, 0, 0));
  for (double t = t0; t <= max_seconds * 1.001; t *= 10.0) {
    const cv::Point p = px({t, e_min});
    cv::line(canvas, {p.x, top}, {p.x, h - bottom}, cv::Scalar(220, 220, 220));
    char text[32];
    std::snprintf(text, sizeof text, "%g s", t);
    cv::putText(canvas, text, {p.x - 12, h - bottom + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  for (int i = 0; i <= 4; ++i) {
    const double e = std::pow(10.0, y0 + (y1 - y0) * i / 4.0);
    const cv::Point p = px({t0, e});
    char text[32];
    std::snprintf(text, sizeof text, "%.3f", e);
    cv::putText(canvas, text, {4, p.y + 4}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
  }
  const std::pair<const std::vector<CurvePoint>*, cv::Scalar> curves[2] = {
      {&cached, cv::Scalar(200, 80, 0)}, {&gd, cv::Scalar(0, 0, 220)}};
  for (const auto& [curve, colour] : curves) {
    for (size_t i = 0; i < curve->size(); ++i) {
      const cv::Point p = px((*curve)[i]);
      cv::circle(canvas, p, 2, colour, cv::FILLED);
      if (i > 0) cv::line(canvas, px((*curve)[i - 1]), p, colour, 1, cv::LINE_AA);
    }
  }
  cv::putText(canvas, "cached normal equations (trace once, then solve)",
              {left + 10, (top + h - bottom) / 2}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(200, 80, 0), 1, cv::LINE_AA);
  cv::putText(canvas, "gradient descent, re-tracing every step",
              {left + 10, (top + h - bottom) / 2 + 18}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(0, 0, 220), 1, cv::LINE_AA);
  cv::putText(canvas, "seconds (log)", {w / 2 - 40, h - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(canvas, "relative RMSE on the training pixels (log)", {left, top - 10},
              cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  if (!cv::imwrite(path.string(), canvas))
    std::fprintf(stderr, "bench_lights: cannot write %s\n", path.c_str());
}

// Section 2. Both methods start from the scene without lights and the same sampled pixels and are
// judged by the same independent evaluation trace of those pixels (relative RMSE of the
// prediction; not timed). The cached method traces once (two halves, as EstimateLights's first
// round) and solves with 1, 2, 5, ... iterations; gradient descent re-traces the pixels with
// `gd_spp` paths at every step (fresh random numbers: nothing is kept between steps), takes the
// gradient of the squared relative residual over the products x_jk = L_j lambda_jk >= 0 and a
// projected step with a backtracking (Armijo) line search on that step's paths.
// `budget` < 0: ten times the cached method's time.
void TimeToError(const Replica& replica, const LightEstimationOptions& options, int gd_spp,
                 double budget, const fs::path& out) {
  const Scene scene = WithoutLights(replica.scene);
  const PathTracer tracer(scene);
  const VoxelLightGrid dark = MakeVoxelGrid(scene, options.grid, options.boundary_inset);
  VoxelSplitting splitting;
  splitting.all_until_depth = options.split_depth;
  splitting.SetPmf(std::vector<double>(static_cast<size_t>(dark.VoxelCount()), 1.0),
                   options.resample_voxels);
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, replica.train, options, 7);
  const LightCache eval =
      TraceLightCache(tracer, dark, splitting, replica.train, pixels, options, 99);
  std::printf(
      "\ntime to error: replica, %zu pixels, w = %g; error = relative RMSE of the prediction on an "
      "independent"
      " %d-spp trace of the same pixels (%zu nnz)\n",
      pixels.size(), options.penalty_weight, options.paths.spp, eval.NonZeros());
  {  // the products and the cache's own prediction agree (a check of Products / PredictProducts)
    VoxelLightGrid g = dark;
    for (int j = 0; j < g.VoxelCount(); ++j)
      g.intensity[j] = Eigen::Vector3f(0.1f, 0.2f, 0.3f) * (1 + j % 3);
    const std::vector<Eigen::Vector3f> a = eval.Predict(g);
    const std::vector<Eigen::Vector3d> b = PredictProducts(eval, Products(g));
    double worst = 0.0;
    for (size_t i = 0; i < a.size(); ++i)
      worst = std::max(worst, (a[i].cast<double>() - b[i]).norm() / (b[i].norm() + 1e-12));
    std::printf(
        "   check: products prediction against LightCache::Predict, max relative difference %.2e\n",
        worst);
  }

  // The cached method.
  std::vector<CurvePoint> cached;
  double t = Now();
  const auto [a, b] =
      TraceLightCacheHalves(tracer, dark, splitting, replica.train, pixels, options, 1, 2);
  const NormalEquations eq = NormalEquations::FromCaches(a, b, options.noise_correction);
  const double setup = Now() - t;
  std::printf("   cached: trace + normal equations %.2f s\n   %-10s %9s %9s\n", setup, "iterations",
              "seconds", "error");
  for (int iterations : {1, 2, 3, 5, 10, 20, 50, 100, 300}) {
    LightEstimationOptions o = options;
    o.max_iterations = iterations;
    o.move_passes = 0;
    VoxelLightGrid g = dark;
    t = Now();
    const SolveReport r = SolveLights(eq, o, &g);
    cached.push_back({setup + Now() - t, RelativeError(eval, Products(g))});
    std::printf("   %-10d %9.2f %9.4f\n", r.iterations, cached.back().seconds, cached.back().error);
    if (r.iterations < iterations) break;  // converged: longer solves are the same
  }

  // Plain gradient descent without the cache.
  if (budget < 0.0) budget = 10.0 * cached.back().seconds;
  std::vector<CurvePoint> gd;
  LightEstimationOptions step_options = options;
  step_options.paths.spp = gd_spp;
  step_options.direct_paths = std::min(options.direct_paths, gd_spp / 2);
  const size_t params = static_cast<size_t>(6 * dark.VoxelCount());
  std::vector<Eigen::Vector3f> x(params, Eigen::Vector3f::Zero());
  double elapsed = 0.0, alpha = 0.0;
  const double target = cached.back().error;
  std::printf(
      "   gradient descent, %d paths per pixel per step, budget %.0f s\n   %-10s %9s %9s %11s\n",
      gd_spp, budget, "step", "seconds", "error", "step size");
  for (int step = 0; elapsed < budget; ++step) {
    t = Now();
    const LightCache rows =
        TraceLightCache(tracer, dark, splitting, replica.train, pixels, step_options, 1000 + step);
    double energy = 0.0;
    for (const SampledPixel& p : rows.pixels) energy += p.observed.cast<double>().squaredNorm();
    if (step == 0) {  // start: the best uniform lighting for these paths (as SolveLights starts)
      double num = 0.0, den = 0.0;
      std::vector<Eigen::Vector3d> s(rows.pixels.size(), Eigen::Vector3d::Zero());
      for (size_t i = 0; i < rows.pixels.size(); ++i) {
        for (size_t e = rows.row_begin[i]; e < rows.row_begin[i + 1]; ++e)
          s[i] += rows.coefficient[e].cast<double>();
        num += s[i].dot(rows.pixels[i].observed.cast<double>());
        den += s[i].squaredNorm();
      }
      std::fill(x.begin(), x.end(), Eigen::Vector3f::Constant(static_cast<float>(num / den)));
    }
    auto cost = [&](const std::vector<Eigen::Vector3f>& at,
                    std::vector<Eigen::Vector3d>* residual) {
      std::vector<Eigen::Vector3d> p = PredictProducts(rows, at);
      double f = 0.0;
      for (size_t i = 0; i < p.size(); ++i) {
        p[i] -= rows.pixels[i].observed.cast<double>();
        f += p[i].squaredNorm();
      }
      if (residual) *residual = std::move(p);
      return f / energy;
    };
    std::vector<Eigen::Vector3d> residual;
    const double f = cost(x, &residual);
    std::vector<Eigen::Vector3d> gradient(params, Eigen::Vector3d::Zero());
    for (size_t i = 0; i < rows.pixels.size(); ++i) {
      for (size_t e = rows.row_begin[i]; e < rows.row_begin[i + 1]; ++e) {
        gradient[static_cast<size_t>(rows.index[e])] +=
            2.0 / energy * rows.coefficient[e].cast<double>().cwiseProduct(residual[i]);
      }
    }
    if (alpha == 0.0) {  // first step size: move the largest product by its own size
      double g_max = 0.0;
      for (const Eigen::Vector3d& g : gradient) g_max = std::max(g_max, g.cwiseAbs().maxCoeff());
      alpha = g_max > 0.0 ? x[0].maxCoeff() / g_max : 1.0;
    }
    alpha *= 2.0;
    std::vector<Eigen::Vector3f> next(params);
    for (int tries = 0; tries < 40; ++tries, alpha *= 0.5) {
      double linear = 0.0, square = 0.0;
      for (size_t q = 0; q < params; ++q) {
        next[q] = (x[q].cast<double>() - alpha * gradient[q]).cwiseMax(0.0).cast<float>();
        const Eigen::Vector3d d = (next[q] - x[q]).cast<double>();
        linear += gradient[q].dot(d);
        square += d.squaredNorm();
      }
      if (cost(next, nullptr) <= f + linear + 0.5 * square / alpha) break;
    }
    x.swap(next);
    elapsed += Now() - t;
    gd.push_back({elapsed, RelativeError(eval, x)});
    if (step < 10 || step % 10 == 9)
      std::printf("   %-10d %9.2f %9.4f %11.3g\n", step + 1, elapsed, gd.back().error, alpha);
    if (gd.back().error <= target) break;
  }
  std::printf("   %-10zu %9.2f %9.4f (last step)\n", gd.size(), gd.back().seconds, gd.back().error);

  std::printf("   %-9s %12s %12s %9s\n", "error", "cached (s)", "descent (s)", "ratio");
  const double best_gd = std::min_element(gd.begin(), gd.end(), [](auto& l, auto& r) {
                           return l.error < r.error;
                         })->error;
  for (const CurvePoint& c : cached) {
    const double ours = TimeTo(cached, c.error), theirs = TimeTo(gd, c.error);
    if (std::isnan(theirs)) {
      char ratio[32];
      std::snprintf(ratio, sizeof ratio, ">%.1fx", gd.back().seconds / ours);
      std::printf("   %-9.4f %12.2f %12s %9s (descent's best in %.0f s: %.4f)\n", c.error, ours,
                  "not reached", ratio, gd.back().seconds, best_gd);
    } else {
      std::printf("   %-9.4f %12.2f %12.2f %8.1fx\n", c.error, ours, theirs, theirs / ours);
    }
  }
  double last = 0.0;
  for (const auto* curve : {&cached, &gd}) {
    for (const CurvePoint& c : *curve) last = std::max(last, c.seconds);
  }
  WriteCurves(out / "lights_time_to_error.png", cached, gd, last);
  std::printf("   plot: %s\n", (out / "lights_time_to_error.png").c_str());
}

// The estimate's rounds (levels, cache size, time, data term, active voxels) and notes.
void PrintRounds(const LightEstimate& e) {
  for (const LightRound& r : e.rounds) {
    if (r.level > 0) std::printf("   level %d: %d candidate voxels\n", r.level, r.candidates);
    std::printf(
        "   round %d: %zu nnz, %.2f s trace, %.2f s gram, %.2f s solve (%d it), data %.4g, active "
        "%d, change %.3f\n",
        r.round, r.nonzeros, r.trace_seconds, r.gram_seconds, r.solve_seconds, r.solve.iterations,
        r.solve.data, r.active_voxels, r.power_change);
  }
  for (const std::string& note : e.notes) std::printf("   note: %s\n", note.c_str());
}

// Section 3: the Cycles Cornell box (../shared/data/cbox-cycles): lights from the 3 training
// views, judged on the 2 novel views; the power-weighted centroid of the voxels against the light.
void Cycles(const fs::path& data, const std::vector<double>& weights, int spp, int eval_spp) {
  const fs::path root = data / "cbox-cycles";
  const Scene scene = LoadCyclesScene(root);
  const std::vector<PosedImage> train = ReadPosedImages(root / "views" / "train"),
                                novel = ReadPosedImages(root / "views" / "novel");
  std::printf(
      "\n3. Cycles cbox: %zu training views, %zu novel views %dx%d; light centre (0, 0, 0.998)\n",
      train.size(), novel.size(), train[0].image.width(), train[0].image.height());
  std::printf("%-9s %7s %9s %9s %9s %9s %22s %9s %8s\n", "weight", "active", "train", "train*",
              "novel", "novel*", "centroid", "dist/vox", "seconds");
  for (double weight : weights) {
    LightEstimationOptions o;
    o.penalty_weight = weight;
    o.paths.spp = spp;
    ApplyOverrides(&o);
    const double t = Now();
    const LightEstimate e = EstimateLights(scene, train, o, g_flags.seed);
    PrintRounds(e);
    const double seconds = Now() - t;
    Scene lit = WithoutLights(scene);
    lit.voxel_lights = e.lights;
    const PathTracer lit_tracer(lit);
    double tr = 0, tr_b = 0, nv = 0, nv_b = 0;
    // Cycles' noise: about 0.0028 RMS per channel over the surface pixels (stats.json).
    for (const PosedImage& v : train) {
      const ViewError ve = CompareRender(lit_tracer, v, o, eval_spp, 5, 0.0028);
      tr += ve.rmse / train.size(), tr_b += ve.rmse_bias / train.size();
    }
    for (const PosedImage& v : novel) {
      const ViewError ve = CompareRender(lit_tracer, v, o, eval_spp, 5, 0.0028);
      nv += ve.rmse / novel.size(), nv_b += ve.rmse_bias / novel.size();
    }
    const Eigen::Vector3d centroid = e.lights.PowerCentroid();
    const double voxel = e.lights.bounds.sizes().x() / e.lights.dims.x();
    char c[64];
    std::snprintf(c, sizeof(c), "(%.3f, %.3f, %.3f)", centroid.x(), centroid.y(), centroid.z());
    std::printf("%-9g %7d %9.4f %9.4f %9.4f %9.4f %22s %9.2f %8.2f\n", weight, e.active_voxels, tr,
                tr_b, nv, nv_b, c, (centroid - Eigen::Vector3d(0, 0, 0.998)).norm() / voxel,
                seconds);
    if (e.lights.distant)
      std::printf("          distant light: %.3f of the light\n", e.distant_share);
  }
}

}  // namespace

int main(int argc, char** argv) {
  // Line-buffered even into a file or pipe: a sweep runs for minutes and reports each round.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  fs::path out = "bench_out";
  int width = 160, height = 120, ref_spp = 1024, spp = LightEstimationOptions().paths.spp,
      eval_spp = 256, gd_spp = 2;
  double gd_seconds = -1.0;  // -1: ten times the cached method's time
  double gamma = LightEstimationOptions().noise_correction;
  std::vector<double> weights = {0.0, 1e-4, 1e-3, 1e-2};
  int threads = 0;
  std::string size = "160x120";
  CLI::App app{
      "bench_lights: light estimation on our replica of the paper's Fig. 3 (a Cornell box lit by a "
      "0.5 m ceiling light, 3 training + 2 novel views). Section 1 sweeps the penalty weights: a "
      "table of "
      "active voxels, training and novel relative RMSE (raw and with the Monte Carlo noise of both "
      "images "
      "taken out, *) and seconds, and OUT/fig3_lights.png. Section 2 compares time to error with "
      "plain "
      "gradient descent on the per-pixel cost (a table and OUT/lights_time_to_error.png). The "
      "references "
      "are rendered once and kept in OUT."};
  app.add_option("--out", out, "folder for the references, the figure and the plot")
      ->capture_default_str();
  app.add_option("--size", size, "reference size, WIDTHxHEIGHT")->capture_default_str();
  app.add_option("--ref-spp", ref_spp, "paths per pixel of the references")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--spp", spp, "paths per sampled pixel of the coarse rounds (even)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--eval-spp", eval_spp,
                 "paths per pixel of the renders of the estimate that are judged")
      ->check(CLI::Range(2, 1 << 20))
      ->capture_default_str();
  app.add_option("--gamma", gamma, "noise_correction of the normal equations")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--weights", weights, "penalty weights of the sweep, comma-separated")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option(
         "--gd-seconds", gd_seconds,
         "gradient descent's time budget (0: skip section 2; -1: ten times the cached method's)")
      ->capture_default_str();
  app.add_option("--gd-spp", gd_spp, "paths per pixel of every gradient-descent step")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--threads", threads, "worker threads (0: all cores)")
      ->check(CLI::NonNegativeNumber);
  app.add_option(
      "--cycles", g_flags.cycles,
      "../shared/data: run the Cycles Cornell box of DATA/cbox-cycles instead (section 3)");
  const char* overrides = "Overrides of the estimate's options (default: the estimate's defaults)";
  app.add_option("--max-depth", g_flags.max_depth,
                 "path length of the references and the estimate (Mitsuba convention)")
      ->group(overrides);
  app.add_option("--rounds", g_flags.rounds, "resampling rounds")->group(overrides);
  app.add_option("--refine-levels", g_flags.refine_levels, "adaptive refinement levels")
      ->group(overrides);
  app.add_option("--refine-penalty-scale", g_flags.refine_penalty_scale,
                 "penalty scale per refinement level")
      ->group(overrides);
  app.add_option("--refine-fraction", g_flags.refine_fraction,
                 "share of the power whose voxels are split")
      ->group(overrides);
  app.add_option("--refine-grow", g_flags.refine_grow, "neighbourhood grown around split voxels")
      ->group(overrides);
  app.add_option("--refine-coarse-pixels", g_flags.refine_coarse_pixels,
                 "pixels per view of the coarse level")
      ->group(overrides);
  app.add_option("--refine-spp", g_flags.refine_spp, "paths per pixel of the refinement levels")
      ->group(overrides);
  app.add_option("--grid-margin", g_flags.grid_margin,
                 "share of the scene's size the grid reaches beyond its box")
      ->group(overrides);
  app.add_option("--seed", g_flags.seed,
                 "the estimate's seed (the spread over seeds is the estimate's own noise)")
      ->capture_default_str()
      ->group(overrides);
  app.add_flag("--distant", g_flags.distant,
               "a distant light (six lobes at infinity) beside the voxels")
      ->group(overrides);
  app.add_option("--exposure", g_flags.exposure,
                 "per-view exposure step: none, gain or white-balance")
      ->group(overrides);
  app.add_option("--refine-reach", g_flags.refine_reach, "voxels a split reaches")
      ->group(overrides);
  app.add_option("--direct-paths", g_flags.direct_paths,
                 "paths per pixel of the direct-light connections")
      ->group(overrides);
  app.add_option("--resample-voxels", g_flags.resample_voxels, "voxels kept for resampling")
      ->group(overrides);
  app.add_option("--split-depth", g_flags.split_depth,
                 "path depth up to which vertices connect to every voxel")
      ->group(overrides);
  const char* diagnostics = "Diagnostics";
  app.add_flag("--voxel-truth", g_flags.voxel_truth,
               "the truth is one voxel light the grid can hold")
      ->group(diagnostics);
  app.add_flag("--dump", g_flags.dump, "print the estimate's active voxels")->group(diagnostics);
  app.add_flag("--oracle", g_flags.oracle,
               "render the replica's light as one voxel and as grids of points")
      ->group(diagnostics);
  app.add_flag("--fine-check", g_flags.fine_check, "solve a 14^3 grid around the replica's light")
      ->group(diagnostics);
  app.add_flag("--solver-check", g_flags.solver_check, "the solver's cost against the truth's")
      ->group(diagnostics);
  CLI11_PARSE(app, argc, argv);
  if (std::sscanf(size.c_str(), "%dx%d", &width, &height) != 2 || width <= 0 || height <= 0) {
    std::fprintf(stderr, "bench_lights: --size %s: expected WIDTHxHEIGHT, e.g. 160x120\n",
                 size.c_str());
    return 2;
  }
  if (spp % 2 != 0) {
    std::fprintf(stderr, "bench_lights: --spp %d: must be even (two independent halves)\n", spp);
    return 2;
  }
  if (threads > 0) SetThreadCount(threads);
  fs::create_directories(out);
  if (g_flags.solver_check) {  // diagnostic: the solver's cost against the truth's
    const Replica replica = MakeReplica(width, height, ref_spp, out);
    Scene s = WithoutLights(replica.scene);
    VoxelLightGrid truth = MakeVoxelGrid(s, 7);
    truth.intensity[3 + 7 * 3 + 49 * 6] = Eigen::Vector3f(3.0f, 2.5f, 1.8f);
    truth.weights[3 + 7 * 3 + 49 * 6] = {0.1f, 0.1f, 0.1f, 0.1f, 0.0f, 1.0f};
    const PathTracer tracer(s);
    LightEstimationOptions o;
    o.paths.spp = spp;
    o.direct_paths = spp / 2;
    o.noise_correction = gamma;
    o.penalty_weight = weights[0];
    const std::vector<SampledPixel> pixels = SamplePixels(tracer, replica.train, o, 7);
    VoxelSplitting all;
    const auto [a, b] = TraceLightCacheHalves(tracer, truth, all, replica.train, pixels, o, 1, 2);
    const NormalEquations eq = NormalEquations::FromCaches(a, b, gamma);
    const LightCost cost(eq, o.penalty_weight, o.penalty_epsilon);
    double data = 0.0;
    const double at_truth = cost.Evaluate(LightCost::Pack(truth), nullptr, &data);
    std::printf("truth: cost %.6g data %.6g\n", at_truth, data);
    for (int it : {100, 300, 1000, 3000}) {
      o.max_iterations = it;
      VoxelLightGrid est = MakeVoxelGrid(s, 7);
      const SolveReport r = SolveLights(eq, o, &est);
      std::printf("solve %d: cost %.6g data %.6g iterations %d active %zu\n", it, r.cost, r.data,
                  r.iterations, est.ActiveVoxels(1e-3).size());
      if (it == 100) {
        for (int j : est.ActiveVoxels(1e-3)) {
          std::printf("  voxel (%d %d %d) L %.3f %.3f %.3f lambda %.2f %.2f %.2f %.2f %.2f %.2f\n",
                      j % 7, j / 7 % 7, j / 49, est.intensity[j][0], est.intensity[j][1],
                      est.intensity[j][2], est.weights[j][0], est.weights[j][1], est.weights[j][2],
                      est.weights[j][3], est.weights[j][4], est.weights[j][5]);
        }
      }
    }
    VoxelLightGrid from_truth = truth;
    const SolveReport r = SolveLights(eq, o, &from_truth);
    std::printf("solve from truth: cost %.6g data %.6g iterations %d\n", r.cost, r.data,
                r.iterations);
    return 0;
  }
  if (!g_flags.cycles.empty()) {
    Cycles(g_flags.cycles, weights, spp, eval_spp);
    return 0;
  }
  double t = Now();
  const Replica replica = MakeReplica(width, height, ref_spp, out);
  std::printf("replica: 5 views %dx%d at %d spp in %.1f s, %d threads\n", width, height, ref_spp,
              Now() - t, ThreadCount());
  if (g_flags.fine_check) {  // diagnostic: the fine level's cost at the oracle and at the solve
    Scene s = WithoutLights(replica.scene);
    VoxelLightGrid fine = MakeVoxelGrid(s, 14), oracle = fine;
    VoxelSplitting sp;
    sp.enabled.assign(fine.VoxelCount(), false);
    int top_count = 0;
    for (int f = 0; f < fine.VoxelCount(); ++f) {
      const Eigen::Vector3d c = fine.VoxelCenter(f);
      if (std::abs(c.x()) < 0.32 && std::abs(c.y()) < 0.32 && c.z() > 1.6) sp.enabled[f] = true;
      if (std::abs(c.x()) < 0.32 && std::abs(c.y()) < 0.32 && c.z() > 1.95) ++top_count;
    }
    for (int f = 0; f < fine.VoxelCount(); ++f) {
      const Eigen::Vector3d c = fine.VoxelCenter(f);
      if (std::abs(c.x()) < 0.32 && std::abs(c.y()) < 0.32 && c.z() > 1.95) {
        oracle.intensity[f] = kReplicaLightIntensity / static_cast<float>(top_count);
        oracle.weights[f] = {0, 0, 0, 0, 0, 1};
      }
    }
    const PathTracer tracer(s);
    LightEstimationOptions o;
    o.paths.spp = spp;
    o.noise_correction = gamma;
    const std::vector<SampledPixel> pixels = SamplePixels(tracer, replica.train, o, 7);
    const auto [a, b] = TraceLightCacheHalves(tracer, fine, sp, replica.train, pixels, o, 1, 2);
    const NormalEquations eq = NormalEquations::FromCaches(a, b, gamma);
    for (double w : weights) {
      o.penalty_weight = w;
      const LightCost cost(eq, w, o.penalty_epsilon);
      double data = 0.0;
      const double at_oracle = cost.Evaluate(LightCost::Pack(oracle), nullptr, &data);
      std::printf("w %g oracle (%d top voxels): cost %.6g data %.6g\n", w, top_count, at_oracle,
                  data);
      VoxelLightGrid est = fine;
      const SolveReport r = SolveLights(eq, o, &est);
      std::printf("  solve: cost %.6g data %.6g iterations %d active %zu\n", r.cost, r.data,
                  r.iterations, est.ActiveVoxels(1e-3).size());
      VoxelLightGrid from = oracle;
      const SolveReport r2 = SolveLights(eq, o, &from);
      std::printf("  solve from oracle: cost %.6g data %.6g iterations %d active %zu\n", r2.cost,
                  r2.data, r2.iterations, from.ActiveVoxels(1e-3).size());
      for (VoxelLightGrid* g : {&est, &from}) {
        const std::vector<ViewError> errors = ReplicaErrors(replica, *g, eval_spp);
        double tr = 0, nv = 0;
        for (size_t i = 0; i < errors.size(); ++i)
          (i < 3 ? tr : nv) += errors[i].rmse_bias / (i < 3 ? 3 : 2);
        std::printf("  %s: train* %.4f novel* %.4f\n", g == &est ? "solve" : "from oracle", tr, nv);
      }
    }
    return 0;
  }
  if (g_flags.oracle) {  // diagnostic: the replica's light as voxel lights with its power
    const Scene s = WithoutLights(replica.scene);
    const auto judge = [&](const VoxelLightGrid& g, const std::string& label) {
      const std::vector<ViewError> errors = ReplicaErrors(replica, g, eval_spp);
      for (size_t i = 0; i < errors.size(); ++i) {
        std::printf("oracle %s view %zu: rmse %.4f corrected %.4f\n", label.c_str(), i,
                    errors[i].rmse, errors[i].rmse_bias);
      }
    };
    // The one voxel of the 7^3 grid under the light.
    VoxelLightGrid one = MakeVoxelGrid(s, 7);
    const int j = 3 + 7 * 3 + 49 * 6;
    one.intensity[j] = kReplicaLightIntensity;
    one.weights[j] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f};
    judge(one, "one voxel at z " + std::to_string(one.VoxelCenter(j).z()));
    // Point grids n x n over [-a, a]^2 at z 1.99, the light's power shared.
    for (auto [n, a] :
         {std::pair{2, 0.16}, std::pair{4, 0.32}, std::pair{3, 0.24}, std::pair{4, 0.25}}) {
      VoxelLightGrid g;
      g.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-a, -a, 1.98), Eigen::Vector3d(a, a, 2.0));
      g.dims = Eigen::Vector3i(n, n, 1);
      g.intensity.assign(n * n, kReplicaLightIntensity / static_cast<float>(n * n));
      g.weights.assign(n * n, {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f});
      judge(g, std::to_string(n) + "x" + std::to_string(n) + " points over +-" + std::to_string(a));
    }
    return 0;
  }
  std::printf("%-9s %7s %7s %9s %9s %9s %9s %9s %8s\n", "weight", "active", "rounds", "cache",
              "train", "train*", "novel", "novel*", "seconds");
  std::vector<Fig3Row> fig3 = {
      {"reference (training view 1)", VoxelLightGrid(), replica.train[0].image}};
  fig3[0].lights.dims.setZero();
  std::vector<float> luminance;
  for (size_t i = 0; i < replica.train[0].image.size(); ++i) {
    luminance.push_back(static_cast<float>(Luminance(replica.train[0].image.data()[i])));
  }
  std::nth_element(luminance.begin(), luminance.begin() + luminance.size() * 95 / 100,
                   luminance.end());
  const float exposure = 0.8f / std::max(1e-6f, luminance[luminance.size() * 95 / 100]);
  for (double weight : weights) {
    LightEstimationOptions o;
    o.penalty_weight = weight;
    o.paths.spp = spp;
    o.noise_correction = gamma;
    ApplyOverrides(&o);
    t = Now();
    const LightEstimate e = EstimateLights(replica.scene, replica.train, o, g_flags.seed);
    const double seconds = Now() - t;
    PrintRounds(e);
    if (g_flags.dump) {
      for (int j : e.lights.ActiveVoxels(1e-3)) {
        const Eigen::Vector3d c = e.lights.VoxelCenter(j);
        const auto& l = e.lights.weights[j];
        std::printf(
            "  voxel at (%.3f %.3f %.3f) power %.3f L %.3f %.3f %.3f lambda %.2f %.2f %.2f %.2f "
            "%.2f %.2f\n",
            c.x(), c.y(), c.z(), Luminance(e.lights.Power(j)), e.lights.intensity[j][0],
            e.lights.intensity[j][1], e.lights.intensity[j][2], l[0], l[1], l[2], l[3], l[4], l[5]);
      }
    }
    Scene lit = WithoutLights(replica.scene);
    lit.voxel_lights = e.lights;
    const PathTracer lit_tracer(lit);
    double train = 0, train_b = 0, novel = 0, novel_b = 0;
    ImageRgb render;
    for (size_t i = 0; i < replica.train.size(); ++i) {
      const ViewError ve = CompareRender(lit_tracer, replica.train[i], o, eval_spp, 5,
                                         replica.noise[i], i == 0 ? &render : nullptr);
      train += ve.rmse / 3, train_b += ve.rmse_bias / 3;
    }
    for (size_t i = 0; i < replica.novel.size(); ++i) {
      const ViewError ve =
          CompareRender(lit_tracer, replica.novel[i], o, eval_spp, 5, replica.noise[3 + i]);
      novel += ve.rmse / 2, novel_b += ve.rmse_bias / 2;
    }
    std::printf("%-9g %7d %7zu %9.4f %9.4f %9.4f %9.4f %9.4f %8.2f\n", weight, e.active_voxels,
                e.rounds.size(), e.train_rmse, train, train_b, novel, novel_b, seconds);
    char label[160];
    std::snprintf(label, sizeof label, "w %g: %d active, novel %.3f, %.0f s", weight,
                  e.active_voxels, novel, seconds);
    fig3.push_back({label, e.lights, std::move(render)});
  }
  Eigen::AlignedBox3d light_box;
  for (const SceneMesh& m : replica.scene.meshes) {
    if (!m.IsEmitter()) continue;
    for (const Eigen::Vector3f& p : m.mesh.vertices) light_box.extend(p.cast<double>());
  }
  WriteFig3(out / "fig3_lights.png", fig3, exposure, MakeVoxelGrid(WithoutLights(replica.scene), 7),
            light_box);
  std::printf(
      "figure: %s (rows: reference, then each weight; columns: voxel powers from above (x right, y "
      "up) and"
      " from the front (x right, z up) with the true light outlined, training view 1 rendered with "
      "the"
      " estimate)\n",
      (out / "fig3_lights.png").c_str());
  if (gd_seconds != 0.0) {
    LightEstimationOptions o;
    o.paths.spp = spp;
    o.noise_correction = gamma;
    o.penalty_weight = 0.0;  // both methods minimise the data term alone
    TimeToError(replica, o, gd_spp, gd_seconds, out);
  }
  return 0;
}
