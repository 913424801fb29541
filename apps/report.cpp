#include "apps/report.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "apps/fuse.h"
#include "apps/plot.h"
#include "apps/report_html.h"
#include "apps/scene_inputs.h"
#include "core/check.h"
#include "core/file_util.h"
#include "core/mesh_distance.h"
#include "core/ply_io.h"
#include "core/trajectory.h"
#include "core/trajectory_metrics.h"
#include "core/tsdf_volume.h"
#include "inverse/lights/light_estimation.h"
#include "meshing/marching_cubes.h"
#include "render/path_tracer.h"

namespace genscene::apps {

namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

std::optional<Json> ReadJson(const fs::path& path) {
  if (!fs::exists(path)) return std::nullopt;
  try {
    return Json::parse(ReadTextFile(path));
  } catch (const std::exception& e) {
    throw Error(Format(path.string(), ": not valid JSON (", e.what(), ")"));
  }
}

std::string Fixed(double v, int digits = 3) {
  char text[48];
  std::snprintf(text, sizeof(text), "%.*f", digits, v);
  return text;
}

// Copies `from` into the report's img/ folder; returns the Markdown link target (relative).
std::string CopyImage(const fs::path& from, const fs::path& report_dir, const std::string& name) {
  fs::create_directories(report_dir / "img");
  fs::copy_file(from, report_dir / "img" / name, fs::copy_options::overwrite_existing);
  return "img/" + name;
}

// A Markdown row of images with captions.
std::string ImageRow(const std::vector<std::pair<std::string, std::string>>& images) {
  std::ostringstream o;
  o << "|";
  for (const auto& [caption, link] : images) o << " " << caption << " |";
  o << "\n|";
  for (size_t i = 0; i < images.size(); ++i) o << "---|";
  o << "\n|";
  for (const auto& [caption, link] : images) o << " ![" << caption << "](" << link << ") |";
  o << "\n\n";
  return o.str();
}

void Summary(const Workspace& ws, std::ostream& md) {
  const auto summary = ReadJson(ws.SummaryJson());
  if (!summary) return;
  md << "## Summary\n\nInput: `" << (*summary)["input"].get<std::string>() << "`, seed "
     << (*summary)["seed"].get<uint64_t>()
     << ".\n\n| stage | seconds | peak MB | result |\n|---|---:|---:|---|\n";
  for (const Json& row : (*summary)["stages"]) {
    md << "| " << row["stage"].get<std::string>() << " | " << Fixed(row["seconds"].get<double>(), 2)
       << " | " << Fixed(row["peak_megabytes"].get<double>(), 0) << " | "
       << row["result"].get<std::string>() << " |\n";
  }
  md << "\n";
}

// The input folder of the run (for its ground truth), from summary.json or the demo's input/.
std::optional<fs::path> InputFolder(const Workspace& ws) {
  if (const auto summary = ReadJson(ws.SummaryJson())) {
    const fs::path input = (*summary)["input"].get<std::string>();
    if (fs::is_directory(input)) return input;
  }
  if (fs::is_directory(ws.Input())) return ws.Input();
  return std::nullopt;
}

// The frames where tracking did more than follow the camera: loops closed (against which frame,
// how far the poses moved), lost, degenerate and blank frames, frames started again from
// features, relocalisations (against which keyframe). At most kListed frames per row, then how
// many more.
void TrackingEvents(const Json& frames, std::ostream& md) {
  constexpr size_t kListed = 20;
  const std::vector<std::string> order = {"loop closed", "relocalised", "started from features",
                                          "lost",        "degenerate",  "blank"};
  std::map<std::string, std::vector<std::string>> events;
  for (const Json& f : frames) {
    const std::string at = std::to_string(f["index"].get<long>());
    const std::string status = f["status"].get<std::string>();
    const Json& against = f.contains("relocalised_against_t") ? f["relocalised_against_t"] : Json();
    if (against.is_number()) {
      events["relocalised"].push_back(at + " (keyframe t = " + Fixed(against.get<double>(), 3) +
                                      ")");
    } else if (f.value("feature_start", false)) {
      events["started from features"].push_back(at);
    }
    if (status == "lost" || status == "degenerate" || status == "blank")
      events[status].push_back(at);
    if (f.contains("loop_closure")) {
      const Json& loop = f["loop_closure"];
      std::string what = at + " (frame t = " + Fixed(loop["against_t"].get<double>(), 3) +
                         ", poses moved up to " +
                         Fixed(100.0 * loop["largest_move_m"].get<double>(), 2) + " cm";
      const long again = loop.value("reintegrated_frames", 0L);
      if (again > 0) what += ", " + std::to_string(again) + " frames integrated again";
      events["loop closed"].push_back(what + ")");
    }
  }
  if (events.empty()) {
    md << "Every frame was tracked from the one before it.\n\n";
    return;
  }
  md << "| tracking | frames |\n|---|---|\n";
  for (const std::string& kind : order) {
    const auto it = events.find(kind);
    if (it == events.end()) continue;
    md << "| " << kind << " | ";
    for (size_t i = 0; i < std::min(it->second.size(), kListed); ++i)
      md << (i ? ", " : "") << it->second[i];
    if (it->second.size() > kListed) md << " and " << it->second.size() - kListed << " more";
    md << " |\n";
  }
  md << "\n";
}

void Tracking(const Workspace& ws, const fs::path& dir, std::ostream& md) {
  const auto fusion = ReadJson(ws.FusionJson());
  if (!fusion) return;
  md << "## Tracking and fusion\n\n";
  PlotSeries total{"all (with loop closure)", {}, {}}, track{"track (ICP)", {}, {}};
  for (const Json& f : (*fusion)["frames"]) {
    const double i = f["index"].get<double>();
    total.x.push_back(i);
    total.y.push_back(f["ms_preprocess"].get<double>() + f["ms_track"].get<double>() +
                      f["ms_integrate"].get<double>() + f["ms_raycast"].get<double>() +
                      f.value("ms_loop", 0.0));
    track.x.push_back(i);
    track.y.push_back(f["ms_track"].get<double>());
  }
  WritePlot(dir / "tracking_time.png", {"Per-frame time", "frame", "ms"}, {total, track});
  double mean = 0.0;
  for (double v : total.y) mean += v / std::max<size_t>(1, total.y.size());
  md << total.x.size() << " frames, " << Fixed(mean, 1) << " ms per frame on average ("
     << Fixed(1000.0 / mean, 1) << " fps).\n\n![per-frame time](tracking_time.png)\n\n";
  TrackingEvents((*fusion)["frames"], md);

  const auto input = InputFolder(ws);
  if (!input || !fs::exists(*input / "groundtruth.txt") || !fs::exists(ws.Trajectory())) return;
  const Trajectory estimated = ReadTumTrajectory(ws.Trajectory()),
                   truth = ReadTumTrajectory(*input / "groundtruth.txt");
  AteResult ate;
  try {
    ate = ComputeAte(estimated, truth);
  } catch (const Error& e) {
    md << "No trajectory error: " << e.what() << ".\n\n";
    return;
  }
  PlotSeries error{"position error after alignment", {}, {}};
  for (size_t i = 0; i < estimated.size(); ++i) {
    const auto& p = estimated.poses()[i];
    const auto gt = truth.Nearest(p.timestamp, 0.02);
    if (!gt) continue;
    error.x.push_back(static_cast<double>(i));
    error.y.push_back(100.0 * ((ate.alignment * p.world_from_camera).translation() -
                               gt->world_from_camera.translation())
                                  .norm());
  }
  WritePlot(dir / "tracking_error.png",
            {"Per-frame position error against the ground truth", "frame", "cm"}, {error});
  md << "Absolute trajectory error (TUM, " << ate.pairs << " poses): RMSE **"
     << Fixed(100.0 * ate.rmse, 3) << " cm**, max " << Fixed(100.0 * ate.max, 3)
     << " cm.\n\n![per-frame error](tracking_error.png)\n\n";
}

// Surface error of the workspace's meshes against the input's ground-truth mesh (synthetic
// inputs: mesh_gt.ply), and with `sweep`, fusion + meshing again at other voxel sizes.
void Surface(const Workspace& ws, const fs::path& dir, const ReportOptions& options,
             std::ostream& md) {
  const auto input = InputFolder(ws);
  if (!input || !fs::exists(*input / "mesh_gt.ply") || !fs::exists(ws.Mesh())) return;
  const TriangleMesh truth = ReadPly(*input / "mesh_gt.ply");
  md << "## Surface error against the ground-truth mesh\n\nDistance to `mesh_gt.ply` (cut off "
        "at 10 cm) of every vertex, and over the surface (points on every face, weighted by its "
        "area; a decimated mesh has few vertices where it is flat, many at its borders):\n\n"
     << "| mesh | vertices | mean mm | RMS mm | max mm | surface mean mm | surface RMS mm "
        "|\n|---|---:|---:|---:|---:|---:|---:|\n";
  for (const fs::path& path : {ws.Mesh(), ws.RefinedMesh()}) {
    if (!fs::exists(path)) continue;
    const SurfaceError e = MeasureSurfaceError(ReadPly(path), truth);
    md << "| " << path.filename().string() << " | " << e.points << " | "
       << Fixed(1000.0 * e.mean, 2) << " | " << Fixed(1000.0 * e.rms, 2) << " | "
       << Fixed(1000.0 * e.max, 1) << " | " << Fixed(1000.0 * e.area_mean, 2) << " | "
       << Fixed(1000.0 * e.area_rms, 2) << " |\n";
  }
  md << "\n";
  if (!options.sweep) return;
  const auto summary = ReadJson(ws.SummaryJson());
  if (!summary) return;
  const std::string source = (*summary)["input"].get<std::string>();
  PlotSeries error{"RMS surface error (mm)", {}, {}}, seconds{"fusion + meshing (s)", {}, {}};
  md << "### Voxel size sweep\n\n| voxel size m | vertices | RMS mm | fusion s | meshing s "
        "|\n|---:|---:|---:|---:|---:|\n";
  const fs::path scratch = dir / "sweep_workspace";
  for (double voxel : {0.04, 0.02, 0.01, 0.005}) {
    std::fprintf(stderr, "report: sweep: voxel size %g m\n", voxel);
    fs::remove_all(scratch);
    const Workspace tmp(scratch);
    fusion::FusionOptions fo;
    fo.voxel_size = voxel;
    fo.truncation = std::max(fo.truncation, 4.0 * voxel);
    const auto start = std::chrono::steady_clock::now();
    FuseSequence(source, SourceOptions(), fo, tmp);
    const double fused =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const auto meshed_at = std::chrono::steady_clock::now();
    const auto mesh =
        meshing::ExtractMesh(ReadTsdfVolume(tmp.Tsdf()), meshing::MeshingOptions()).mesh;
    const double meshed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - meshed_at).count();
    const SurfaceError e = MeasureSurfaceError(mesh, truth);
    error.x.push_back(voxel), error.y.push_back(1000.0 * e.rms);
    seconds.x.push_back(voxel), seconds.y.push_back(fused + meshed);
    md << "| " << voxel << " | " << mesh.vertices.size() << " | " << Fixed(1000.0 * e.rms, 2)
       << " | " << Fixed(fused, 2) << " | " << Fixed(meshed, 2) << " |\n";
  }
  fs::remove_all(scratch);
  WritePlot(dir / "surface_voxel_size.png",
            {"Surface error and time against the voxel size", "voxel size (m)", "mm / s", true},
            {error, seconds});
  md << "\n![surface error against voxel size](surface_voxel_size.png)\n\n";
}

void Texturing(const Workspace& ws, std::ostream& md) {
  const auto texture = ReadJson(ws.TextureJson());
  const auto albedo = ReadJson(ws.AlbedoJson());
  if (!texture && !albedo) return;
  md << "## Texturing and albedo\n\n";
  if (texture && texture->contains("summary"))
    md << "Texturing: " << (*texture)["summary"].dump() << "\n\n";
  if (albedo && albedo->contains("clusters")) {
    md << "| albedo cluster | linear RGB | texels |\n|---|---|---:|\n";
    for (const Json& c : (*albedo)["clusters"]) {
      const auto& a = c["albedo"];
      md << "| " << c["id"].get<int>() << " | (" << Fixed(a[0].get<double>()) << ", "
         << Fixed(a[1].get<double>()) << ", " << Fixed(a[2].get<double>()) << ") | "
         << c["texels"].get<long long>() << " |\n";
    }
    md << "\n";
  }
}

void Lights(const Workspace& ws, const fs::path& dir, const ReportOptions& options, uint64_t seed,
            std::ostream& md) {
  const auto lights = ReadJson(ws.Lights());
  if (!lights) return;
  const Json& e = (*lights)["estimate"];
  md << "## Light estimation\n\n"
     << e["pixels"].get<long long>() << " sampled pixels, " << e["active_voxels"].get<int>()
     << " active voxels, " << Fixed(e["seconds"].get<double>(), 2) << " s.\n\n";
  if (e.contains("distant_share") && (*lights)["voxel_lights"].contains("distant")) {
    const Json& d = (*lights)["voxel_lights"]["distant"];
    md << "Distant light (beyond the scan): " << Fixed(100.0 * e["distant_share"].get<double>(), 1)
       << " % of the light at the sampled pixels; intensity (" << d["intensity"][0].get<double>()
       << ", " << d["intensity"][1].get<double>() << ", " << d["intensity"][2].get<double>()
       << "), lobes +x -x +y -y +z -z:";
    for (const Json& w : d["weights"]) md << " " << Fixed(w.get<double>(), 2);
    md << ".\n\n";
  }
  md << "| round | cache non-zeros | rays | trace s | solve s | cost | active voxels "
        "|\n|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const Json& r : e["rounds"]) {
    md << "| " << r["round"].get<int>() << " | " << r["nonzeros"].get<long long>() << " | "
       << r["rays"].get<long long>() << " | " << Fixed(r["trace_seconds"].get<double>(), 2) << " | "
       << Fixed(r["solve_seconds"].get<double>(), 2) << " | " << r["cost"].get<double>() << " | "
       << r["active_voxels"].get<int>() << " |\n";
  }
  md << "\n";
  if (e.contains("joint_albedo")) {
    const Json& j = e["joint_albedo"];
    md << "Joint albedo (per-texel albedo alternated with the lights, "
       << j["albedo"].get<std::string>()
       << "; light cost before: " << j["initial_cost"].get<double>() << ", "
       << Fixed(j["seconds"].get<double>(), 2)
       << " s; a step is kept when the cost and the second half of the paths' residual fall):\n\n"
          "| step | cost | check residual before | after | albedo scale | kept |\n"
          "|---:|---:|---:|---:|---:|---|\n";
    int step = 0;
    for (const Json& st : j["steps"]) {
      md << "| " << step++ << " | " << st["cost"].get<double>() << " | "
         << Fixed(st["check_before"].get<double>(), 4) << " | "
         << Fixed(st["check"].get<double>(), 4) << " | " << Fixed(st["scale"].get<double>())
         << " | " << (st["kept"].get<bool>() ? "yes" : "no") << " |\n";
    }
    md << "\n";
  }
  std::vector<std::pair<std::string, std::string>> row;
  const auto keyframes = ReadDataLines(ws.Keyframes() / "rgb.txt");
  for (size_t i = 0; i < e["train_views"].size() && i < 4; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "train_%02zu.png", i);
    const fs::path render = ws.LightsDir() / name;
    if (!fs::exists(render)) continue;
    if (i < keyframes.size()) {
      const auto fields = SplitWhitespace(keyframes[i].text);
      if (fields.size() >= 2 && fs::exists(ws.Keyframes() / fields[1])) {
        row.push_back({Format("keyframe ", i),
                       CopyImage(ws.Keyframes() / fields[1], dir, Format("keyframe_", i, ".png"))});
      }
    }
    row.push_back({Format("render ", i, " (RMSE ",
                          Fixed(e["train_views"][i]["relative_rmse_bias"].get<double>()), ")"),
                   CopyImage(render, dir, name)});
  }
  if (!row.empty())
    md << "Keyframes and the model rendered with the estimated lights (relative RMSE with the "
          "render noise taken out):\n\n"
       << ImageRow(row);

  if (!options.sweep) return;
  // Fig. 3: light error against the penalty weight, and the time it takes.
  std::vector<std::string> warnings;
  const render::Scene scene = LoadGeometry({{}, ws.Mesh(), ws.ModelAlbedo()}, ws, &warnings);
  const std::vector<PosedImage> views = ReadPosedImages(ws.Keyframes());
  inverse::LightEstimationOptions base;
  // The estimate's own grid and refinement (lights.json's dims are the refined grid's).
  const Json used = e.contains("options") ? e["options"] : Json::object();
  base.grid = used.contains("grid") ? used["grid"].get<int>()
                                    : (*lights)["voxel_lights"]["dims"][0].get<int>();
  if (used.contains("refine_levels")) base.refine_levels = used["refine_levels"].get<int>();
  base.pixels_per_view =
      static_cast<int>(e["pixels"].get<long long>() / std::max<size_t>(1, views.size()));
  PlotSeries error{"relative RMSE (training views)", {}, {}}, seconds{"seconds", {}, {}},
      active{"active voxels", {}, {}};
  md << "### Penalty weight sweep (the paper's Fig. 3)\n\n| penalty weight | relative RMSE | "
        "active voxels | seconds |\n|---:|---:|---:|---:|\n";
  for (double weight : {1e-5, 1e-4, 1e-3, 1e-2, 1e-1}) {
    inverse::LightEstimationOptions o = base;
    o.penalty_weight = weight;
    std::fprintf(stderr, "report: sweep: penalty weight %g\n", weight);
    const inverse::LightEstimate estimate = inverse::EstimateLights(scene, views, o, seed);
    render::Scene lit = inverse::WithoutLights(scene);
    lit.voxel_lights = estimate.lights;
    const render::PathTracer tracer(lit);
    double rmse = 0.0;
    for (size_t i = 0; i < views.size(); ++i) {
      rmse += inverse::CompareRender(tracer, views[i], o, options.sweep_spp, seed + i).rmse_bias /
              views.size();
    }
    error.x.push_back(weight), error.y.push_back(rmse);
    seconds.x.push_back(weight), seconds.y.push_back(estimate.seconds);
    active.x.push_back(weight), active.y.push_back(estimate.active_voxels);
    md << "| " << weight << " | " << Fixed(rmse) << " | " << estimate.active_voxels << " | "
       << Fixed(estimate.seconds, 2) << " |\n";
  }
  WritePlot(dir / "lights_penalty_error.png",
            {"Light error against the penalty weight", "penalty weight", "relative RMSE", true},
            {error});
  WritePlot(
      dir / "lights_penalty_cost.png",
      {"Active voxels and time against the penalty weight", "penalty weight", "count / s", true},
      {active, seconds});
  md << "\n![error](lights_penalty_error.png) ![active voxels and "
        "time](lights_penalty_cost.png)\n\n";
}

void Refinement(const Workspace& ws, const fs::path& dir, std::ostream& md) {
  const auto report = ReadJson(ws.RefineReport());
  if (!report) return;
  if (report->contains("skipped")) {
    md << "## Vertex refinement\n\nSkipped, the unrefined mesh kept: "
       << (*report)["skipped"].get<std::string>() << ".\n\n";
    return;
  }
  md << "## Vertex refinement\n\n"
     << (*report)["vertices"].get<int>() << " vertices, " << (*report)["pixels"].get<int>()
     << " pixels, " << (*report)["flipped_faces"].get<int>() << " flipped faces.\n\n";
  PlotSeries image{"image RMSE / RMS of the reference", {}, {}};
  std::vector<std::pair<std::string, std::string>> row;
  double seconds = 0.0;
  for (const Json& it : (*report)["iterations"]) {
    const int i = it["iteration"].get<int>();
    image.x.push_back(i);
    image.y.push_back(it["image_rmse"].get<double>());
    seconds += it["seconds"].get<double>();
    char name[32];
    std::snprintf(name, sizeof(name), "iter_%02d_shading.png", i);
    if (fs::exists(ws.RefineDir() / name))
      row.push_back({Format("iteration ", i), CopyImage(ws.RefineDir() / name, dir, name)});
  }
  WritePlot(dir / "refine_error.png", {"Image error per iteration", "iteration", "relative RMSE"},
            {image});
  md << Fixed(seconds, 1)
     << " s in all.\n\n![image error per iteration](refine_error.png)\n\nShading after each "
        "iteration (every albedo grey, the paper's Fig. 4):\n\n"
     << ImageRow(row);
}

// The judge on real frames (apps/holdout.h): the model and both baselines on the held-out frames.
void HeldOut(const Workspace& ws, const fs::path& dir, std::ostream& md) {
  const auto h = ReadJson(ws.HeldOutJson());
  if (!h) return;
  const Json& mean = (*h)["mean"];
  md << "## Held-out frames\n\nThe model rendered at the poses of " << (*h)["frames"].size()
     << " frames kept out of fusion, keyframes, texturing, lights and refinement, against those "
        "frames, over the "
        "pixels the model covers; each prediction with its own per-channel gain (exposure and "
        "white balance). "
        "Relative RMSE in linear RGB, SSIM of the sRGB luminance.\n\n"
     << "| prediction | relative RMSE | SSIM |\n|---|---:|---:|\n"
     << "| full model (" << (*h)["spp"].get<int>() << " spp; render noise "
     << Fixed(mean["noise"].get<double>()) << ") | "
     << Fixed(mean["model"]["relative_rmse"].get<double>()) << " | "
     << Fixed(mean["model"]["ssim"].get<double>()) << " |\n"
     << "| observed-colour texture, unlit | "
     << Fixed(mean["texture_unlit"]["relative_rmse"].get<double>()) << " | "
     << Fixed(mean["texture_unlit"]["ssim"].get<double>()) << " |\n"
     << "| albedo under white ambient light | "
     << Fixed(mean["albedo_ambient"]["relative_rmse"].get<double>()) << " | "
     << Fixed(mean["albedo_ambient"]["ssim"].get<double>()) << " |\n\n";
  const bool truth = mean.contains("against_truth");
  if (truth) {
    const Json& t = mean["against_truth"];
    md << "The same scores against the true scene rendered at those poses ("
       << (*h)["truth_spp"].get<int>()
       << " spp); the held-out frames themselves are the floor a perfect model reaches against the "
          "frames:\n\n"
       << "| prediction | relative RMSE | SSIM |\n|---|---:|---:|\n";
    for (const auto& [key, label] : std::vector<std::pair<std::string, std::string>>{
             {"model", "full model"},
             {"texture_unlit", "observed-colour texture, unlit"},
             {"albedo_ambient", "albedo under white ambient light"},
             {"frame", "the held-out frame"}}) {
      md << "| " << label << " | " << Fixed(t[key]["relative_rmse"].get<double>()) << " | "
         << Fixed(t[key]["ssim"].get<double>()) << " |\n";
    }
    md << "\n";
  }
  for (size_t k = 0; k < (*h)["frames"].size(); ++k) {
    const Json& f = (*h)["frames"][k];
    std::vector<std::pair<std::string, std::string>> row;
    for (const auto& [suffix, label] : std::vector<std::pair<std::string, std::string>>{
             {"real", "real frame"},
             {"model", Format("model (", Fixed(f["model"]["relative_rmse"].get<double>()), ")")},
             {"texture", Format("unlit texture (",
                                Fixed(f["texture_unlit"]["relative_rmse"].get<double>()), ")")},
             {"ambient", Format("albedo, ambient (",
                                Fixed(f["albedo_ambient"]["relative_rmse"].get<double>()), ")")},
             {"error", "model error x4"},
             {"truth", "true scene"}}) {
      if (suffix == "truth" && !truth) continue;
      // The images are named by the frame's index in holdout/ (a frame the model is not in view
      // of has none), older workspaces by the list's.
      char stem[32];
      std::snprintf(stem, sizeof(stem), "holdout_%02zu", k);
      const std::string name =
          (f.contains("images") ? f["images"].get<std::string>() : std::string(stem)) + "_" +
          suffix + ".png";
      row.push_back({label, CopyImage(ws.EvaluationDir() / name, dir, name)});
    }
    md << ImageRow(row);
  }
}

void Evaluation(const Workspace& ws, const fs::path& dir, std::ostream& md) {
  HeldOut(ws, dir, md);
  const auto eval = ReadJson(ws.EvaluationJson());
  if (!eval) return;
  const int block = eval->contains("block") ? (*eval)["block"].get<int>() : 1;
  md << "## Novel views against the ground truth\n\nMean relative RMSE (noise of both renders "
        "taken out, over "
     << block << "x" << block << " pixel tiles): **"
     << Fixed((*eval)["relative_rmse"].get<double>()) << "**.\n\n";
  std::vector<std::pair<std::string, std::string>> row;
  for (size_t k = 0; k < (*eval)["views"].size(); ++k) {
    const Json& v = (*eval)["views"][k];
    char truth[48], model[48];
    std::snprintf(truth, sizeof(truth), "novel_%02zu_truth.png", k);
    std::snprintf(model, sizeof(model), "novel_%02zu_model.png", k);
    row.push_back({Format("truth, frame ", v["frame"].get<int>()),
                   CopyImage(ws.EvaluationDir() / truth, dir, truth)});
    row.push_back({Format("model (", Fixed(v["relative_rmse_bias"].get<double>()), ")"),
                   CopyImage(ws.EvaluationDir() / model, dir, model)});
  }
  md << ImageRow(row);
}

}  // namespace

fs::path WriteReport(const Workspace& ws, const ReportOptions& options, uint64_t seed) {
  if (!fs::exists(ws.SummaryJson()) && !fs::exists(ws.FusionJson()) && !fs::exists(ws.Lights())) {
    throw Error(
        Format(ws.root().string(),
               ": no stage outputs to report on (run genscene run or genscene demo first)"));
  }
  const fs::path dir = ws.Report();
  fs::create_directories(dir);
  std::ostringstream md;
  md << "# genscene report\n\nWorkspace `" << ws.root().string() << "`.\n\n";
  Summary(ws, md);
  Tracking(ws, dir, md);
  Surface(ws, dir, options, md);
  Texturing(ws, md);
  Lights(ws, dir, options, seed, md);
  Refinement(ws, dir, md);
  Evaluation(ws, dir, md);
  md << "Not in this report yet: texel error against texel spacing (see bench_texturing, which "
        "measures it on a "
        "scene whose observed colour is its albedo).\n";
  const fs::path path = dir / "report.md";
  WriteTextFileAtomically(path, md.str());
  for (const std::string& w :
       WriteReportHtml(dir, {md.str(), ws.ExportDir() / "model.glb", options.three_dir})) {
    spdlog::warn("{}", w);
  }
  return path;
}

}  // namespace genscene::apps
