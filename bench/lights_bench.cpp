// Light estimation speed against error (issue 7, acceptance 1 and 5).
//  1. The paper's replica (Fig. 3) with our own renderer: the Cornell box of MakeCornellBoxScene
//     lit by its 0.5 m ceiling light, 3 training views + 2 novel views; the light removed, voxel
//     lights estimated on a 7^3 grid from 3000 pixels per view. For each penalty weight: active
//     voxels, training and novel relative RMSE (raw and with the Monte Carlo noise of both images
//     taken out), seconds. Writes OUT/fig3_lights.png: per weight, the voxel powers seen from above
//     (x-y, summed over z) and the first training view rendered with the estimate.
//  2. Time to error against plain first-order gradient descent on the per-pixel cost without the
//     cache (each step re-traces the paths of the sampled pixels and descends along the gradient
//     of their squared residual); written as a table and OUT/lights_time_to_error.png.
//  3. With CYCLES=../shared/data: the Cycles Cornell box, novel-view RMSE and the power-weighted
//     centroid of the voxels against the light.
// Run by hand:  build/bench/bench_lights [--out DIR] [--size WxH] [--ref-spp N] [--spp N]
//               [--eval-spp N] [--gamma G] [--weights w1,w2,..] [--threads N]
// Diagnostics (environment): VOXEL_TRUTH=1 (the truth is one voxel light the grid can hold),
// MAXDEPTH=N (references and estimation with that path length), ROUNDS=N, DIRECT=N, MVOX=N.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

#include "core/color.h"
#include "core/frame_source.h"
#include "core/image_io.h"
#include "inverse/scene_io.h"
#include "core/parallel.h"
#include "inverse/light_estimation.h"
#include "inverse/procedural.h"

using namespace genscene;
using namespace genscene::inverse;
namespace fs = std::filesystem;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Replica {
  Scene scene;
  std::vector<TrainingView> train, novel;
  std::vector<double> noise;  // RMS noise per channel of each reference (train, then novel)
};

// The references are slow to render: kept in `cache` (EXR + noise.txt) and reused when present.
Replica MakeReplica(int width, int height, int spp, const fs::path& cache) {
  Replica r;
  const fs::path dir = cache / ("replica_" + std::to_string(width) + "x" + std::to_string(height) + "_" + std::to_string(spp) +
                          (std::getenv("VOXEL_TRUTH") ? "_voxel" : "") + (std::getenv("MAXDEPTH") ? "_d" : ""));
  if (fs::exists(dir / "noise.txt")) {
    r.scene = MakeCornellBoxScene();
    const std::vector<View> views = CornellLightViews(width, height);
    FILE* f = std::fopen((dir / "noise.txt").c_str(), "r");
    for (size_t i = 0; i < views.size(); ++i) {
      double noise = 0.0;
      if (std::fscanf(f, "%lf", &noise) != 1) break;
      r.noise.push_back(noise);
      CameraResponse linear;
      linear.kind = CameraResponse::Kind::kLinear;
      TrainingView tv{views[i], ReadColorImage(dir / ("view" + std::to_string(i) + ".exr"), linear)};
      (i < 3 ? r.train : r.novel).push_back(std::move(tv));
    }
    std::fclose(f);
    return r;
  }
  r.scene = MakeCornellBoxScene();
  if (std::getenv("VOXEL_TRUTH")) {  // diagnostic: the truth is a voxel light the grid can represent
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
  if (std::getenv("MAXDEPTH")) ro.max_depth = std::atoi(std::getenv("MAXDEPTH"));
  const std::vector<View> views = CornellLightViews(width, height);
  ro.spp = spp / 2;
  for (size_t i = 0; i < views.size(); ++i) {
    const ImageRgb a = tracer.Render(views[i], ro, 1000 + i).radiance, b = tracer.Render(views[i], ro, 2000 + i).radiance;
    TrainingView tv{views[i], ImageRgb(a.width(), a.height())};
    double variance = 0.0;
    for (size_t p = 0; p < a.size(); ++p) {
      tv.image.data()[p] = 0.5f * (a.data()[p] + b.data()[p]);
      variance += 0.25 * (a.data()[p] - b.data()[p]).cast<double>().squaredNorm() / 3.0;
    }
    r.noise.push_back(std::sqrt(variance / a.size()));
    (i < 3 ? r.train : r.novel).push_back(std::move(tv));
  }
  fs::create_directories(dir);
  FILE* f = std::fopen((dir / "noise.txt").c_str(), "w");
  for (size_t i = 0; i < views.size(); ++i) {
    WriteExr(dir / ("view" + std::to_string(i) + ".exr"), i < 3 ? r.train[i].image : r.novel[i - 3].image);
    std::fprintf(f, "%.9g\n", r.noise[i]);
  }
  std::fclose(f);
  return r;
}

std::vector<TrainingView> ReadViews(const fs::path& folder) {
  std::vector<TrainingView> out;
  auto source = OpenFrameSource(folder.string(), SourceOptions());
  while (auto frame = source->Next()) {
    out.push_back({View{frame->intrinsics, *frame->world_from_camera, frame->timestamp}, frame->color});
  }
  return out;
}

// Section 3: the Cycles Cornell box (../shared/data/cbox-cycles): lights from the 3 training
// views, judged on the 2 novel views; the power-weighted centroid of the voxels against the light.
void Cycles(const fs::path& data, const std::vector<double>& weights, int spp, int eval_spp) {
  const fs::path root = data / "cbox-cycles";
  const Scene scene = LoadCyclesScene(root);
  const std::vector<TrainingView> train = ReadViews(root / "views" / "train"), novel = ReadViews(root / "views" / "novel");
  std::printf("\n3. Cycles cbox: %zu training views, %zu novel views %dx%d; light centre (0, 0, 0.998)\n", train.size(),
              novel.size(), train[0].image.width(), train[0].image.height());
  std::printf("%-9s %7s %9s %9s %9s %9s %22s %9s %8s\n", "weight", "active", "train", "train*", "novel", "novel*",
              "centroid", "dist/vox", "seconds");
  for (double weight : weights) {
    LightEstimationOptions o;
    o.penalty_weight = weight;
    o.spp = spp;
    const double t = Now();
    const LightEstimate e = EstimateLights(scene, train, o, 7);
    const double seconds = Now() - t;
    Scene lit = WithoutLights(scene);
    lit.voxel_lights = e.lights;
    const PathTracer lit_tracer(lit);
    double tr = 0, tr_b = 0, nv = 0, nv_b = 0;
    // Cycles' noise: about 0.0028 RMS per channel over the surface pixels (stats.json).
    for (const TrainingView& v : train) {
      const ViewError ve = CompareRender(lit_tracer, v, o, eval_spp, 5, 0.0028);
      tr += ve.rmse / train.size(), tr_b += ve.rmse_bias / train.size();
    }
    for (const TrainingView& v : novel) {
      const ViewError ve = CompareRender(lit_tracer, v, o, eval_spp, 5, 0.0028);
      nv += ve.rmse / novel.size(), nv_b += ve.rmse_bias / novel.size();
    }
    const Eigen::Vector3d centroid = e.lights.PowerCentroid();
    const double voxel = e.lights.bounds.sizes().x() / e.lights.dims.x();
    char c[64];
    std::snprintf(c, sizeof(c), "(%.3f, %.3f, %.3f)", centroid.x(), centroid.y(), centroid.z());
    std::printf("%-9g %7d %9.4f %9.4f %9.4f %9.4f %22s %9.2f %8.2f\n", weight, e.active_voxels, tr, tr_b, nv, nv_b, c,
                (centroid - Eigen::Vector3d(0, 0, 0.998)).norm() / voxel, seconds);
  }
}

}  // namespace

int main(int argc, char** argv) {
  // Line-buffered even into a file or pipe: a sweep runs for minutes and reports each round.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  fs::path out = "bench_out";
  int width = 160, height = 120, ref_spp = 1024, spp = LightEstimationOptions().spp, eval_spp = 256;
  double gamma = LightEstimationOptions().noise_correction;
  std::vector<double> weights = {0.0, 1e-4, 1e-3, 1e-2};
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--out")) out = argv[i + 1];
    if (!std::strcmp(argv[i], "--size")) std::sscanf(argv[i + 1], "%dx%d", &width, &height);
    if (!std::strcmp(argv[i], "--ref-spp")) ref_spp = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--threads")) SetThreadCount(std::atoi(argv[i + 1]));
    if (!std::strcmp(argv[i], "--spp")) spp = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--gamma")) gamma = std::atof(argv[i + 1]);
    if (!std::strcmp(argv[i], "--eval-spp")) eval_spp = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--weights")) {
      weights.clear();
      for (const char* p = argv[i + 1]; *p;) {
        char* end = nullptr;
        weights.push_back(std::strtod(p, &end));
        p = *end == ',' ? end + 1 : end;
      }
    }
  }
  fs::create_directories(out);
  if (std::getenv("SOLVER_CHECK")) {  // diagnostic: the solver's cost against the truth's
    const Replica replica = MakeReplica(width, height, ref_spp, out);
    Scene s = WithoutLights(replica.scene);
    VoxelLightGrid truth = MakeVoxelGrid(s, 7);
    truth.intensity[3 + 7 * 3 + 49 * 6] = Eigen::Vector3f(3.0f, 2.5f, 1.8f);
    truth.weights[3 + 7 * 3 + 49 * 6] = {0.1f, 0.1f, 0.1f, 0.1f, 0.0f, 1.0f};
    const PathTracer tracer(s);
    LightEstimationOptions o;
    o.spp = spp;
    o.direct_paths = spp / 2;
    o.noise_correction = gamma;
    o.penalty_weight = weights[0];
    const std::vector<SampledPixel> pixels = SamplePixels(tracer, replica.train, o, 7);
    LightEstimationOptions half = o;
    half.spp = spp / 2;
    VoxelSplitting all;
    const LightCache a = TraceLightCache(tracer, truth, all, replica.train, pixels, half, 1);
    const LightCache b = TraceLightCache(tracer, truth, all, replica.train, pixels, half, 2);
    const NormalEquations eq = NormalEquations::FromCaches(a, b, gamma);
    const LightCost cost(eq, o.penalty_weight, o.penalty_epsilon);
    double data = 0.0;
    const double at_truth = cost.Evaluate(LightCost::Pack(truth), nullptr, &data);
    std::printf("truth: cost %.6g data %.6g\n", at_truth, data);
    for (int it : {100, 300, 1000, 3000}) {
      o.max_iterations = it;
      VoxelLightGrid est = MakeVoxelGrid(s, 7);
      const SolveReport r = SolveLights(eq, o, &est);
      std::printf("solve %d: cost %.6g data %.6g iterations %d active %zu\n", it, r.cost, r.data, r.iterations,
                  est.ActiveVoxels(1e-3).size());
      if (it == 100) {
        for (int j : est.ActiveVoxels(1e-3)) {
          std::printf("  voxel (%d %d %d) L %.3f %.3f %.3f lambda %.2f %.2f %.2f %.2f %.2f %.2f\n", j % 7, j / 7 % 7, j / 49,
                      est.intensity[j][0], est.intensity[j][1], est.intensity[j][2], est.weights[j][0], est.weights[j][1],
                      est.weights[j][2], est.weights[j][3], est.weights[j][4], est.weights[j][5]);
        }
      }
    }
    VoxelLightGrid from_truth = truth;
    const SolveReport r = SolveLights(eq, o, &from_truth);
    std::printf("solve from truth: cost %.6g data %.6g iterations %d\n", r.cost, r.data, r.iterations);
    return 0;
  }
  if (std::getenv("CYCLES")) {
    Cycles(std::getenv("CYCLES"), weights, spp, eval_spp);
    return 0;
  }
  double t = Now();
  const Replica replica = MakeReplica(width, height, ref_spp, out);
  std::printf("replica: 5 views %dx%d at %d spp in %.1f s, %d threads\n", width, height, ref_spp, Now() - t,
              ThreadCount());
  std::printf("%-9s %7s %7s %9s %9s %9s %9s %9s %8s\n", "weight", "active", "rounds", "cache", "train", "train*",
              "novel", "novel*", "seconds");
  for (double weight : weights) {
    LightEstimationOptions o;
    o.penalty_weight = weight;
    o.spp = spp;
    o.noise_correction = gamma;
    if (std::getenv("MAXDEPTH")) o.max_depth = std::atoi(std::getenv("MAXDEPTH"));
    if (std::getenv("ROUNDS")) o.rounds = std::atoi(std::getenv("ROUNDS"));
    if (std::getenv("DIRECT")) o.direct_paths = std::atoi(std::getenv("DIRECT"));
    if (std::getenv("MVOX")) o.resample_voxels = std::atoi(std::getenv("MVOX"));
    if (std::getenv("SPLIT")) o.split_depth = std::atoi(std::getenv("SPLIT"));
    t = Now();
    const LightEstimate e = EstimateLights(replica.scene, replica.train, o, 7);
    const double seconds = Now() - t;
    for (const LightRound& r : e.rounds) {
      std::printf("   round %d: %zu nnz, %.2f s trace, %.2f s gram, %.2f s solve (%d it), active %d, change %.3f\n",
                  r.round, r.nonzeros, r.trace_seconds, r.gram_seconds, r.solve_seconds, r.solve.iterations,
                  r.active_voxels, r.power_change);
    }
    Scene lit = WithoutLights(replica.scene);
    lit.voxel_lights = e.lights;
    const PathTracer lit_tracer(lit);
    double train = 0, train_b = 0, novel = 0, novel_b = 0;
    for (size_t i = 0; i < replica.train.size(); ++i) {
      const ViewError ve = CompareRender(lit_tracer, replica.train[i], o, eval_spp, 5, replica.noise[i]);
      train += ve.rmse / 3, train_b += ve.rmse_bias / 3;
    }
    for (size_t i = 0; i < replica.novel.size(); ++i) {
      const ViewError ve = CompareRender(lit_tracer, replica.novel[i], o, eval_spp, 5, replica.noise[3 + i]);
      novel += ve.rmse / 2, novel_b += ve.rmse_bias / 2;
    }
    std::printf("%-9g %7d %7zu %9.4f %9.4f %9.4f %9.4f %9.4f %8.2f\n", weight, e.active_voxels, e.rounds.size(),
                e.train_rmse, train, train_b, novel, novel_b, seconds);
  }
  return 0;
}
