#include "apps/chain.h"

#include <spdlog/sinks/base_sink.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <utility>

#include "apps/fuse.h"
#include "apps/holdout.h"
#include "apps/ingest.h"
#include "apps/lights.h"
#include "apps/refine.h"
#include "apps/scene_inputs.h"
#include "apps/texture.h"
#include "core/check.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/light_set.h"
#include "core/mesh_colors.h"
#include "core/options.h"
#include "core/options_json.h"
#include "core/ply_io.h"
#include "core/trajectory.h"
#include "core/tsdf_volume.h"
#include "render/formats/gltf_export.h"
#include "render/formats/mitsuba_xml.h"
#include "render/formats/scene_io.h"
#include "render/path_tracer.h"
#include "render/scene.h"

namespace genscene::apps {

namespace fs = std::filesystem;

void ChainOptions::AddTo(CommandLine& cli) {
  cli.Add(fusion, "Fusion");
  cli.Add(meshing, "Meshing");
  cli.Add(texturing, "Texturing");
  cli.Add(albedo, "Albedo");
  cli.Add(lights, "Light estimation (flags --lights-*)", "lights");
  cli.Add(refine, "Vertex refinement (flags --refine-*)", "refine");
  cli.Add(evaluate, "Evaluation against a synthetic ground truth (flags --evaluate-*)", "evaluate");
  cli.Add(preview, "The stages' renders (flags --preview-*)", "preview");
}

ChainOptions RunChainOptions() {
  ChainOptions o;
  o.fusion.preprocess.max_depth = 4.0;
  o.meshing.min_component_triangles = 200;
  o.meshing.denoise_iterations = 10;
  o.meshing.decimate_max_error = 0.002;
  o.refine.iterations = 3;
  o.refine.paths.spp = 16;
  o.refine.pixels_per_view = 3000;
  return o;
}

ChainOptions DemoChainOptions() {
  ChainOptions o;
  o.meshing.denoise_iterations = 10;
  o.meshing.decimate_max_error = 0.003;
  o.lights.grid = 5;
  o.lights.pixels_per_view = 1500;
  // The penalty weight is the default (1e-3): with the joint albedo free per texel, a weaker
  // penalty lets many voxels shape each wall's shading, and the walls' albedo takes what they
  // leave (1e-5: novel views 0.035, but the red wall's red channel 1.08x the white wall's, truth
  // 0.86x; docs/chain.md). Adaptive refinement is off for the same reason: its finer voxels
  // shape the walls' shading again (one level: the red channel 1.03x).
  o.lights.refine_levels = 0;
  o.lights.rounds = 3;  // the demo's figures (README) were measured with three resampling rounds
  o.refine.iterations = 3;
  o.refine.paths.spp = 8;
  o.refine.pixels_per_view = 1000;
  return o;
}

const std::vector<std::string>& ChainStages() {
  static const std::vector<std::string> stages = {"ingest",    "fusion", "meshing",
                                                  "texturing", "albedo", "lights",
                                                  "refine",    "export", "evaluate"};
  return stages;
}

namespace {
std::atomic<const char*> current_stage{nullptr};
}  // namespace

const char* RunningStage() {
  return current_stage.load();
}

double PeakMegabytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // kilobytes on Linux
}

std::string Describe(const IngestSummary& s) {
  return Format(s.frames, " frames ", s.width, "x", s.height, ", depth ", s.min_depth, "-",
                s.max_depth, " m, ", 100.0 * s.valid_depth_fraction, "% valid, ",
                s.frames_with_pose, " with pose");
}

namespace {

std::string Now() {
  const std::time_t t = std::time(nullptr);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M:%S", std::localtime(&t));
  return text;
}

// FNV-1a 64 of the parts' text, as 16 hex digits.
template <typename... Parts>
std::string Hash(const Parts&... parts) {
  uint64_t h = kFnv1aOffset;
  ((h = Fnv1a64(Format(parts) + '\x1f', h)), ...);
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(h));
  return text;
}

// Collects the text of every warning (and error) logged through spdlog while it is attached to the
// default logger; the default logger's own console sink still prints them.
class WarningCollector : public spdlog::sinks::base_sink<std::mutex> {
 public:
  std::vector<std::string> Take() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::exchange(messages_, {});
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    if (msg.level >= spdlog::level::warn)
      messages_.emplace_back(msg.payload.data(), msg.payload.size());
  }
  void flush_() override {}

 private:
  std::vector<std::string> messages_;
};

// Attaches a WarningCollector to the default logger for its lifetime.
class ScopedWarningCollector {
 public:
  ScopedWarningCollector() : sink_(std::make_shared<WarningCollector>()) {
    spdlog::default_logger()->sinks().push_back(sink_);
  }
  ~ScopedWarningCollector() {
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
  }
  ScopedWarningCollector(const ScopedWarningCollector&) = delete;
  ScopedWarningCollector& operator=(const ScopedWarningCollector&) = delete;
  std::vector<std::string> Take() { return sink_->Take(); }

 private:
  std::shared_ptr<WarningCollector> sink_;
};

// Runs one stage: skipped when its outputs exist and were made from inputs of the same content with
// the same settings (the stage's fingerprint: its settings and the content of every input file,
// kept in WS/stages.json), else timed, logged and summarised. A live camera is never the same
// input twice. Warnings logged while the stage runs go into its row and the log.
class StageRunner {
 public:
  StageRunner(const Workspace& ws, bool redo, std::ostream& log, std::vector<StageRow>& rows,
              std::string until)
      : ws_(ws), redo_(redo), log_(log), rows_(rows), until_(std::move(until)) {
    if (fs::exists(ws.StageFingerprints())) {
      try {
        stored_ = nlohmann::json::parse(ReadTextFile(ws.StageFingerprints()));
      } catch (const std::exception&) {  // unreadable: every stage runs again
      }
      if (!stored_.is_object()) stored_ = nlohmann::json::object();
    }
  }

  template <typename F>
  void Run(const std::string& stage, const std::vector<fs::path>& outputs,
           const std::vector<fs::path>& inputs, const std::string& settings, F&& body) {
    if (done_) return;
    done_ = stage == until_;
    const auto& stages = ChainStages();
    const size_t index = std::find(stages.begin(), stages.end(), stage) - stages.begin() + 1;
    std::string fingerprint = Hash(stage, settings);
    for (const fs::path& in : inputs) fingerprint = Hash(fingerprint, Content(in));
    const bool outputs_exist = std::all_of(outputs.begin(), outputs.end(),
                                           [](const fs::path& p) { return fs::exists(p); });
    if (!redo_ && outputs_exist && stored_.value(stage, std::string()) == fingerprint) {
      StageRow row{stage,
                   0.0,
                   PeakMegabytes(),
                   true,
                   "up to date (" + outputs.front().string() + "), skipped",
                   {}};
      log_ << Now() << " " << stage << ": " << row.result << "\n" << std::flush;
      rows_.push_back(row);
      return;
    }
    // The stage is the running one before its line is printed: a Ctrl-C the line prompted names it.
    current_stage.store(stages[index - 1].c_str());
    std::fprintf(stderr, "[%zu/%zu] %s\n", index, stages.size(), stage.c_str());
    log_ << Now() << " " << stage << ": start\n" << std::flush;
    const auto start = std::chrono::steady_clock::now();
    warnings_.Take();
    std::string result;
    try {
      result = body();
    } catch (const std::exception& e) {
      StageRow failed{
          stage,
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
          PeakMegabytes(),
          false,
          Format("failed: ", e.what()),
          warnings_.Take()};
      failed.failed = true;
      LogWarnings(stage, failed.warnings);
      log_ << Now() << " " << stage << ": error: " << e.what() << "\n" << std::flush;
      rows_.push_back(std::move(failed));
      current_stage.store(nullptr);
      throw;
    }
    current_stage.store(nullptr);
    StageRow row{stage,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                 PeakMegabytes(),
                 false,
                 result,
                 warnings_.Take()};
    LogWarnings(stage, row.warnings);
    log_ << Now() << " " << stage << ": done in " << Format(row.seconds) << " s: " << result << "\n"
         << std::flush;
    rows_.push_back(row);
    stored_[stage] = fingerprint;  // after the stage's outputs: a killed stage has none
    WriteTextFileAtomically(ws_.StageFingerprints(), stored_.dump(1) + "\n");
  }

 private:
  // The content fingerprint of an input file or folder, once per run (no stage writes what an
  // earlier one read; the recording is read by two).
  std::string Content(const fs::path& path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) {  // openni2[:URI]: a live camera
      return Hash(path.string(), std::chrono::system_clock::now().time_since_epoch().count());
    }
    auto it = content_.find(path.string());
    if (it == content_.end())
      it = content_.emplace(path.string(), Hash(ContentFingerprint(path))).first;
    return it->second;
  }

  const Workspace& ws_;
  nlohmann::json stored_ = nlohmann::json::object();
  std::map<std::string, std::string> content_;
  bool redo_;
  std::ostream& log_;
  std::vector<StageRow>& rows_;
  std::string until_;
  bool done_ = false;  // the `until` stage has run
  ScopedWarningCollector warnings_;

  void LogWarnings(const std::string& stage, const std::vector<std::string>& warnings) {
    for (const std::string& w : warnings)
      log_ << Now() << " " << stage << ": warning: " << w << "\n";
  }
};

// A stage's own warnings (returned in its summary) go to the console and the stage's row.
void Warn(const std::vector<std::string>& warnings) {
  for (const std::string& w : warnings) spdlog::warn("{}", w);
}

// The workspace's model as a scene: `mesh` with the Mesh Colors albedo and the voxel lights.
render::Scene LoadModel(const Workspace& ws, const fs::path& mesh,
                        std::vector<std::string>* warnings) {
  render::Scene scene = LoadGeometry({{}, mesh, ws.ModelAlbedo()}, ws, warnings);
  scene.meshes.front().name = "model";
  scene.voxel_lights = ReadLightsJson(ws.Lights());
  return scene;
}

// WS/export/: model.ply, model.glb, model.xml (+ model_meshes/), trajectory.txt. model.xml is
// written last.
std::string ExportModel(const Workspace& ws, std::vector<std::string>* warnings) {
  const fs::path dir = ws.ExportDir();
  fs::create_directories(dir);
  const fs::path mesh_path = ws.ModelMesh();
  const TriangleMesh mesh = ReadPly(mesh_path);
  const MeshColors albedo = ReadMeshColors(ws.ModelAlbedo(), mesh);
  const TriangleMesh colored = albedo.ToSubdividedMesh(mesh);
  WritePly(dir / "model.ply", colored);
  WriteTumTrajectory(dir / "trajectory.txt", ReadTumTrajectory(ws.Trajectory()));

  const render::Scene scene = LoadModel(ws, mesh_path, warnings);
  std::vector<PosedView> views;  // the keyframe cameras as sensors
  for (const PosedImage& v : ReadPosedImages(ws.Keyframes())) views.push_back(v.view);
  // model.glb: the albedo atlas, the observed colour of texture.mcol as a material variant, the
  // active voxel lights as point lights and the keyframe cameras.
  std::optional<MeshColors> observed;
  if (fs::exists(ws.Texture())) {
    try {
      observed = ReadMeshColors(ws.Texture(), mesh);
    } catch (const Error& e) {
      warnings->push_back(Format("observed colour left out of model.glb: ", e.what()));
    }
  }
  const render::GltfExportSummary glb =
      render::ExportGltf(dir / "model.glb", mesh, albedo, observed ? &*observed : nullptr,
                         scene.voxel_lights ? &*scene.voxel_lights : nullptr, views);
  for (const std::string& w : glb.warnings) warnings->push_back(w);
  const bool distant = scene.voxel_lights && scene.voxel_lights->HasDistantLight();
  if (distant) {
    warnings->push_back(
        "the distant light is left out of model.glb (glTF has no environment light); model.xml "
        "holds it as an envmap");
  }
  try {
    for (std::string& w : render::ExportMitsubaXml(dir / "model.xml", scene, views))
      warnings->push_back(std::move(w));
  } catch (const Error& e) {  // cameras Mitsuba cannot express (fx != fy, distortion): none
    warnings->push_back(Format("keyframe cameras left out of model.xml: ", e.what()));
    for (std::string& w : render::ExportMitsubaXml(dir / "model.xml", scene, {}))
      warnings->push_back(std::move(w));
  }
  return Format(colored.vertices.size(), " coloured vertices (", (dir / "model.ply").string(),
                "), ", scene.voxel_lights->ActiveVoxels().size(), " active voxel lights (",
                scene.voxel_lights->ActiveVoxels(0.0).size(),
                " with any power, all exported) as emissive cube faces",
                distant ? " and the distant light as an envmap (model_distant.exr)" : "", " (",
                (dir / "model.xml").string(), "), glTF binary with a ", glb.atlas_width, "x",
                glb.atlas_height, " albedo atlas, ", glb.cameras, " cameras and ", glb.lights,
                " point lights (", (dir / "model.glb").string(), ", ", glb.bytes / 1024,
                " KiB), trajectory (", (dir / "trajectory.txt").string(), ")");
}

template <typename O>
std::string OptionsText(const O& options) {
  return OptionsToJson(options).dump();
}

}  // namespace

void RunChain(const std::string& input, const SourceOptions& source, const ChainOptions& options,
              uint64_t seed, const Workspace& ws, bool redo, std::ostream& log,
              std::vector<StageRow>& rows, const std::string& until) {
  const auto& names = ChainStages();
  if (!until.empty() && std::find(names.begin(), names.end(), until) == names.end()) {
    std::string known;
    for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
    throw Error(Format("--until ", until, ": no such stage (stages: ", known, ")"));
  }
  StageRunner stage(ws, redo, log, rows, until);
  // Each stage's settings: its options (and the seed where it draws random numbers); the source
  // options and the content of the files they name for the stages that read the recording.
  std::string source_settings = OptionsText(source);
  for (const std::string& file : {source.intrinsics, source.associations, source.trajectory}) {
    std::error_code ec;
    if (!file.empty() && fs::is_regular_file(file, ec))
      source_settings += Hash(ContentFingerprint(file));
  }
  const fs::path summary_path = ws.SequenceJson();
  stage.Run("ingest", {summary_path}, {input}, source_settings,
            [&] { return Describe(IngestSequence(input, source, summary_path)); });

  stage.Run("fusion", {ws.Trajectory(), ws.Tsdf(), ws.FusionJson()}, {input},
            source_settings + OptionsText(options.fusion), [&] {
              const FuseSummary s = FuseSequence(input, source, options.fusion, ws);
              std::string result =
                  Format(s.fused, "/", s.frames, " frames fused (", s.lost, " lost, ", s.degenerate,
                         " degenerate, ", s.blank, " blank), ", s.blocks, " blocks (", s.megabytes,
                         " MB), ", s.keyframes, " keyframes");
              if (s.held_out > 0) result += Format(", ", s.held_out, " held out");
              if (s.live) result += Format(", ", s.skipped, " camera frames skipped");
              if (s.ate) result += Format(", ATE ", 100.0 * s.ate->rmse, " cm");
              return result;
            });

  stage.Run("meshing", {ws.Mesh()}, {ws.Tsdf()}, OptionsText(options.meshing), [&] {
    const TsdfVolume volume = ReadTsdfVolume(ws.Tsdf());
    const auto r = meshing::ExtractMesh(volume, options.meshing);
    if (r.mesh.empty())
      throw Error(Format(ws.Tsdf().string(), ": the volume holds no surface; no mesh written"));
    WritePly(ws.Mesh(), r.mesh, {true, PlyColors::kObserved});
    return Format(r.stats.vertices, " vertices, ", r.stats.triangles, " triangles (",
                  ws.Mesh().string(), ")");
  });

  stage.Run("texturing", {ws.Texture(), ws.TexturePly()}, {ws.Mesh(), ws.Keyframes()},
            OptionsText(options.texturing) + source.camera_response, [&] {
              SourceOptions keyframes;
              keyframes.camera_response = source.camera_response;
              return ToString(TextureWorkspace({}, keyframes, options.texturing, ws));
            });

  stage.Run("albedo", {ws.Albedo(), ws.AlbedoPly()}, {ws.Mesh(), ws.Texture()},
            OptionsText(options.albedo),
            [&] { return ToString(AlbedoWorkspace({}, options.albedo, ws)); });

  stage.Run("lights", {ws.Lights()}, {ws.Mesh(), ws.Albedo(), ws.Keyframes()},
            Hash(OptionsText(options.lights), seed, options.preview.lights_spp), [&] {
              LightsInputs in;
              in.render_spp = options.preview.lights_spp;
              const LightsSummary s = LightsWorkspace(in, options.lights, seed, ws);
              Warn(s.warnings);
              return ToString(s);
            });

  stage.Run("refine", {ws.RefinedMesh()},
            {ws.Mesh(), ws.ModelAlbedo(), ws.Lights(), ws.Keyframes()},
            Hash(OptionsText(options.refine), seed, options.preview.refine_spp), [&] {
              RefineInputs in;
              in.render_spp = options.preview.refine_spp;
              const RefineSummary s = RefineWorkspace(in, options.refine, seed, ws);
              Warn(s.warnings);
              return ToString(s);
            });

  const fs::path exported = ws.ExportDir();
  stage.Run("export",
            {exported / "model.xml", exported / "model.glb", exported / "model.ply",
             exported / "trajectory.txt"},
            {ws.RefinedMesh(), ws.ModelAlbedo(), ws.Texture(), ws.Lights(), ws.Trajectory(),
             ws.Keyframes()},
            "", [&] {
              std::vector<std::string> warnings;
              std::string result = ExportModel(ws, &warnings);
              Warn(warnings);
              return result;
            });

  // Judge the model: against the ground truth when the input carries one (genscene-synth, the
  // demo), and on the frames fusion held out when it held some out.
  const bool synthetic = fs::exists(fs::path(input) / "scene.json");
  const bool held_out = fs::exists(ws.HeldOut() / "rgb.txt");
  if (synthetic || held_out) {
    const fs::path judged = ws.EvaluationJson(), holdout = ws.HeldOutJson();
    std::vector<fs::path> outputs, inputs = {ws.RefinedMesh(), ws.ModelAlbedo(), ws.Lights()};
    if (synthetic) outputs.push_back(judged), inputs.push_back(input);
    if (held_out)
      outputs.push_back(holdout), inputs.push_back(ws.HeldOut()), inputs.push_back(ws.Texture());
    stage.Run(
        "evaluate", outputs, inputs,
        Hash(OptionsText(options.evaluate), OptionsText(options.lights), seed), [&] {
          std::string result;
          // The true scene, loaded once for both judges.
          std::optional<render::Scene> truth;
          if (synthetic) truth = render::LoadScene(fs::path(input) / "scene.json").scene;
          if (synthetic) {
            const DemoEvaluation e =
                EvaluateAgainstTruth(ws, input, *truth, options.lights, options.evaluate, seed);
            result = Format(e.views.size(), " novel views against the ground truth: relative RMSE ",
                            e.relative_rmse, " (noise taken out, ", options.evaluate.block, "x",
                            options.evaluate.block, " pixel tiles) (", judged.string(), ")");
          }
          if (held_out) {
            const HeldOutEvaluation h =
                EvaluateHeldOut(ws, options.lights, options.evaluate.model_spp, seed,
                                truth ? &*truth : nullptr, options.evaluate.truth_spp);
            result += Format(result.empty() ? "" : "; ", h.frames.size(),
                             " held-out frames: model relative RMSE ", h.model.rmse,
                             " (render noise ", h.noise, "), SSIM ", h.model.ssim,
                             "; unlit texture ", h.texture.rmse, ", SSIM ", h.texture.ssim,
                             "; albedo under ambient ", h.ambient.rmse, ", SSIM ", h.ambient.ssim);
            if (h.truth) {
              result +=
                  Format("; against the true scene at those poses: model ", h.truth->model.rmse,
                         ", unlit texture ", h.truth->texture.rmse, ", albedo under ambient ",
                         h.truth->ambient.rmse, ", the frames themselves ", h.truth->frame.rmse);
            }
            result += Format(" (", holdout.string(), ")");
            if (h.model.rmse > std::min(h.texture.rmse, h.ambient.rmse)) {
              spdlog::warn(
                  "on the held-out frames the model's renders are further from the real images "
                  "(relative RMSE {:.3f}) "
                  "than the {} ({:.3f})",
                  h.model.rmse,
                  h.texture.rmse < h.ambient.rmse ? "unlit observed-colour texture"
                                                  : "albedo under ambient light",
                  std::min(h.texture.rmse, h.ambient.rmse));
            }
          }
          return result;
        });
  }
}

void PreviewOptions::Validate() const {
  RequireRange("lights_spp", lights_spp, 2, 1 << 16);
  RequireRange("refine_spp", refine_spp, 0, 1 << 16);
}

void EvaluationOptions::Validate() const {
  RequireRange("views", views, 1, 1000);
  RequireRange("truth_spp", truth_spp, 2, 1 << 16);
  RequireRange("model_spp", model_spp, 2, 1 << 16);
  RequireRange("block", block, 1, 64);
}

DemoEvaluation EvaluateAgainstTruth(const Workspace& ws, const fs::path& input,
                                    const render::Scene& truth,
                                    const inverse::LightEstimationOptions& lights,
                                    const EvaluationOptions& eval, uint64_t seed) {
  const int views = eval.views, truth_spp = eval.truth_spp, model_spp = eval.model_spp;
  using namespace inverse;
  using namespace render;
  const fs::path dir = ws.EvaluationDir();
  fs::create_directories(dir);
  const std::vector<PosedImage> all = ReadPosedImages(input);
  if (all.empty()) throw Error(Format(input.string(), ": no frames to take novel views from"));

  std::vector<std::string> warnings;
  const Scene model = LoadModel(ws, ws.RefinedMesh(), &warnings);
  const PathTracer truth_tracer(truth), model_tracer(model);

  DemoEvaluation out;
  nlohmann::ordered_json list = nlohmann::ordered_json::array();
  for (int k = 0; k < views; ++k) {
    // Frames between the keyframes (every 5th frame from the first is a keyframe in the demo).
    const size_t index = std::min(all.size() - 1, (2 * k + 1) * all.size() / (2 * views));
    PosedImage reference{all[index].view, {}};
    RenderOptions paths;
    paths.spp = truth_spp;
    const RenderHalves truth_render =
        RenderInHalves(truth_tracer, reference.view, paths, seed + 1000 + k,
                       (seed + 1000 + k) ^ 0x9E3779B97F4A7C15ull);
    reference.image = truth_render.mean;
    const double noise_rms = truth_render.NoiseRms();
    ImageRgb render;
    const ViewError e = CompareRender(model_tracer, reference, lights, model_spp, seed + 2000 + k,
                                      noise_rms, &render, eval.block);
    char name[32];
    std::snprintf(name, sizeof(name), "novel_%02d", k);
    WritePng(dir / (std::string(name) + "_truth.png"), reference.image);
    WritePng(dir / (std::string(name) + "_model.png"), render);
    out.views.push_back(e);
    out.relative_rmse += e.rmse_bias / views;
    list.push_back({{"frame", index},
                    {"pixels", e.pixels},
                    {"relative_rmse", e.rmse},
                    {"noise", e.noise},
                    {"relative_rmse_bias", e.rmse_bias}});
  }
  nlohmann::ordered_json report;
  report["truth_spp"] = truth_spp;
  report["model_spp"] = model_spp;
  report["block"] = eval.block;
  report["relative_rmse"] = out.relative_rmse;
  report["views"] = list;
  WriteTextFileAtomically(dir / "evaluation.json", report.dump(1) + "\n");
  return out;
}

void WriteSummaryJson(const Workspace& ws, const std::string& input, uint64_t seed,
                      const std::vector<StageRow>& rows) {
  const fs::path path = ws.SummaryJson();
  nlohmann::ordered_json previous;
  if (fs::exists(path)) {
    try {
      previous = nlohmann::ordered_json::parse(ReadTextFile(path));
    } catch (const std::exception&) {  // rewritten below
    }
  }
  nlohmann::ordered_json stages = nlohmann::ordered_json::array();
  for (const StageRow& r : rows) {
    nlohmann::ordered_json row = {
        {"stage", r.stage},      {"seconds", r.seconds}, {"peak_megabytes", r.peak_megabytes},
        {"skipped", r.skipped},  {"failed", r.failed},   {"result", r.result},
        {"warnings", r.warnings}};
    // A skipped stage keeps the figures of the run that made its outputs, marked skipped.
    if (r.skipped && previous.contains("stages")) {
      for (const auto& old : previous["stages"]) {
        if (old.value("stage", "") == r.stage) {
          row = old;
          row["skipped"] = true;
        }
      }
    }
    stages.push_back(row);
  }
  nlohmann::ordered_json summary = {{"input", input}, {"seed", seed}, {"stages", stages}};
  WriteTextFileAtomically(path, summary.dump(1) + "\n");
}

std::string SummaryTable(const std::vector<StageRow>& rows) {
  std::ostringstream o;
  char line[96];
  std::snprintf(line, sizeof(line), "%-10s %9s %9s  %s\n", "stage", "seconds", "peak MB", "result");
  o << line;
  double total = 0.0;
  for (const StageRow& r : rows) {
    std::snprintf(line, sizeof(line), "%-10s %9.2f %9.0f  ", r.stage.c_str(), r.seconds,
                  r.peak_megabytes);
    o << line << r.result << "\n";
    total += r.seconds;
  }
  std::snprintf(line, sizeof(line), "%-10s %9.2f\n", "total", total);
  o << line;
  // Each distinct warning once, under the first stage that gave it (ingest and fusion read the
  // same source and warn alike).
  std::set<std::string> seen;
  std::ostringstream list;
  for (const StageRow& r : rows) {
    for (const std::string& w : r.warnings) {
      if (seen.insert(w).second) list << "  " << r.stage << ": " << w << "\n";
    }
  }
  if (!seen.empty())
    o << "\n"
      << seen.size() << (seen.size() == 1 ? " warning" : " warnings") << ":\n"
      << list.str();
  return o.str();
}

}  // namespace genscene::apps
