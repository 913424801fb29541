// The whole chain of `genscene run` and `genscene demo`: ingest -> fusion -> meshing -> texturing
// -> albedo -> lights -> refine -> export, on one workspace (DESIGN.md §2). Each stage is skipped
// when its outputs exist and were made from inputs of the same content with the same options
// (WS/stages.json); every output is written atomically and the stage's completion marker last, so
// a run killed in any stage and started again finishes with the same files, and a run with a
// changed option or recording re-runs exactly the stages that depend on it.
//
// Export (WS/export/): model.ply (the refined mesh subdivided to its Mesh Colors texels, albedo as
// 8-bit sRGB vertex colours: MeshLab, Open3D, Blender), model.xml (Mitsuba 3: the refined mesh,
// albedo per face, the voxel lights as emissive cube faces, the keyframe cameras), trajectory.txt
// (TUM format: timestamp tx ty tz qx qy qz qw).
#pragma once

#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "apps/ingest.h"
#include "core/cli.h"
#include "core/frame_source.h"
#include "core/workspace.h"
#include "fusion/kinect_fusion.h"
#include "inverse/lights/light_estimation.h"
#include "inverse/refine/vertex_refinement.h"
#include "meshing/marching_cubes.h"
#include "texturing/albedo.h"
#include "texturing/backproject.h"

namespace genscene::apps {

// How the "evaluate" stage judges a model against a synthetic ground truth.
struct EvaluationOptions {
  static constexpr const char* kSection = "evaluate";
  int views = 3;        // novel views, between the keyframes
  int truth_spp = 128;  // samples per pixel of the ground-truth renders
  int model_spp = 64;   // samples per pixel of the model's renders
  int block = 4;        // compare means over block x block pixel tiles (1: pixel by pixel)
  template <typename V>
  void Visit(V&& v) {
    v("views", views, "", "novel views judged against the synthetic ground truth");
    v("truth_spp", truth_spp, "", "samples per pixel of the ground-truth renders");
    v("model_spp", model_spp, "",
      "samples per pixel of the model's renders (two halves: the noise is measured)");
    v("block", block, "pixels",
      "compare the means of block x block pixel tiles, with their noise taken out (1: pixel by "
      "pixel)");
  }
  void Validate() const;
};

// The renders the lights and refine stages write beside their figures: the training views with
// the estimated lights (`lights/train_*`, and their relative RMSE in the summary) and refinement's
// image of the first view after each iteration (`refine/iter_*`).
struct PreviewOptions {
  static constexpr const char* kSection = "preview";
  int lights_spp = 64;  // samples per pixel of the lights stage's training-view renders
  int refine_spp = 16;  // samples per pixel of refinement's per-iteration renders (0 = none)
  template <typename V>
  void Visit(V&& v) {
    v("lights_spp", lights_spp, "",
      "samples per pixel of the lights stage's renders of the training views (two halves: the "
      "figures take their noise out)");
    v("refine_spp", refine_spp, "",
      "samples per pixel of refinement's render of the first view after each iteration (0: none)");
  }
  void Validate() const;
};

// The stages' options, as flags and config sections of `genscene run` and `genscene demo`.
struct ChainOptions {
  fusion::FusionOptions fusion;
  meshing::MeshingOptions meshing;
  texturing::TexturingOptions texturing;
  texturing::AlbedoOptions albedo;
  inverse::LightEstimationOptions lights;
  inverse::RefineOptions refine;
  EvaluationOptions evaluate;
  PreviewOptions preview;
  void AddTo(CommandLine& cli);
};

// The options `genscene run` starts from: the stages' own defaults, except depth to 4 m (a
// Kinect-class sensor's noise there is about 2.6 cm, farther it passes 6 cm and fills the volume
// with noise: 1.5 M triangles from five NYU frames to 9.8 m), fragments under 200 triangles
// removed, the mesh simplified within 2 mm (a fifth of a voxel; real depth noise is larger), and
// vertex refinement on 3000 sampled pixels per view at 16 paths for 3 iterations, so that a real
// recording's model takes minutes on 2 cores, not hours (every pixel of a 640x480 view at 64
// paths: 150 s an iteration).
ChainOptions RunChainOptions();

// The options `genscene demo` starts from: a decimated mesh (the Cornell box is planar), a 5^3
// light grid and small pixel samples, so that the whole chain takes about a minute on 2 cores.
ChainOptions DemoChainOptions();

struct StageRow {
  std::string stage;
  double seconds = 0.0;
  double peak_megabytes = 0.0;  // the process's peak resident memory after the stage
  bool skipped = false;
  std::string result;                 // the stage's own figures
  std::vector<std::string> warnings;  // every warning the stage gave (console, log, summary)
  bool failed = false;                // the stage stopped with an error (result: "failed: ...")
};

// The stage RunChain is running now (one of ChainStages()), or nullptr between stages; safe to
// read from a signal handler.
const char* RunningStage();

// The chain's stages in order, for --help texts and the kill-and-resume test.
const std::vector<std::string>& ChainStages();

// Runs the chain on `input` into `ws`, appending one row per stage to `rows` and a line per event
// to `log` (the workspace's genscene.log). Every warning a stage gives (spdlog::warn anywhere below
// it, or a warning its summary returns) reaches the console, the log and the stage's row. `redo`:
// run stages whose outputs are up to date. When `input` holds a ground truth (scene.json of
// genscene-synth), an "evaluate" stage follows. `until`: the last stage to run (empty: all); throws
// Error when it names no stage.
void RunChain(const std::string& input, const SourceOptions& source, const ChainOptions& options,
              uint64_t seed, const Workspace& ws, bool redo, std::ostream& log,
              std::vector<StageRow>& rows, const std::string& until = "");

// The demo's judge: novel views between the keyframes rendered from the synthetic ground truth
// (`truth`, the scene of input/scene.json, at `truth_spp`) and from the model (refined mesh,
// albedo, voxel lights, `model_spp`); relative RMSE with the Monte Carlo noise of both renders
// taken out (CompareRender). Writes WS/evaluation/: novel_NN_truth.png, novel_NN_model.png,
// evaluation.json.
struct DemoEvaluation {
  std::vector<inverse::ViewError> views;
  double relative_rmse = 0.0;  // mean over the views, noise taken out
};
DemoEvaluation EvaluateAgainstTruth(const Workspace& ws, const std::filesystem::path& input,
                                    const render::Scene& truth,
                                    const inverse::LightEstimationOptions& lights,
                                    const EvaluationOptions& options, uint64_t seed);

// WS/summary.json: the input, the seed and a row per stage (a skipped stage keeps the row of the
// run that made its outputs), for `genscene report`.
void WriteSummaryJson(const Workspace& ws, const std::string& input, uint64_t seed,
                      const std::vector<StageRow>& rows);

// The summary table printed at the end of a run.
std::string SummaryTable(const std::vector<StageRow>& rows);

// One line on an ingested sequence.
std::string Describe(const IngestSummary& summary);

// Peak resident memory of this process so far, in MB.
double PeakMegabytes();

}  // namespace genscene::apps
