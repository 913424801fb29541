#include "apps/lights.h"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "apps/scene_inputs.h"
#include "core/check.h"
#include "core/frame_source.h"
#include "core/image_io.h"
#include "core/light_set.h"
#include "core/mesh_colors.h"
#include "core/options_json.h"
#include "core/ply_io.h"
#include "render/formats/mitsuba_xml.h"
#include "render/formats/scene_io.h"

namespace genscene::apps {

namespace {

namespace fs = std::filesystem;
using namespace genscene::inverse;
using namespace genscene::render;

std::string Stamp(const char* prefix, size_t index) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%s_%02zu", prefix, index);
  return buffer;
}

}  // namespace

LightsSummary LightsWorkspace(const LightsInputs& in, const LightEstimationOptions& options,
                              uint64_t seed, const Workspace& ws) {
  options.Validate();
  LightsSummary out;
  // The lights start from the clustering's albedo (albedo.mcol), not from an earlier joint one.
  const fs::path albedo_path =
      !in.albedo.empty() ? in.albedo : (fs::exists(ws.Albedo()) ? ws.Albedo() : fs::path());
  const Scene scene = LoadGeometry({in.scene, in.mesh, albedo_path}, ws, &out.warnings);
  const std::vector<PosedImage> keyframes =
      ReadPosedImages(in.views.empty() ? ws.Keyframes() : in.views);
  const std::vector<PosedImage> novel =
      in.novel.empty() ? std::vector<PosedImage>() : ReadPosedImages(in.novel);
  // Joint albedo needs the observed colour per texel (texture.mcol) of the same mesh.
  std::error_code ec;
  fs::remove(ws.JointAlbedo(), ec);
  fs::remove(ws.JointAlbedoPly(), ec);
  std::optional<MeshColors> clusters, observed;
  JointAlbedoInputs joint;
  if (options.albedo_iterations > 0 && in.scene.empty() && albedo_path.extension() == ".mcol") {
    if (!fs::exists(ws.Texture())) {
      out.warnings.push_back(Format("joint albedo skipped: ", ws.Texture().string(),
                                    " (the observed colour per texel) is missing"));
    } else {
      try {
        clusters = ReadMeshColors(albedo_path, scene.meshes[0].mesh);
        observed = ReadMeshColors(ws.Texture(), scene.meshes[0].mesh);
        if (observed->SampleCount() != clusters->SampleCount())
          throw Error(Format(ws.Texture().string(), ": ", observed->SampleCount(), " texels where ",
                             albedo_path.string(), " has ", clusters->SampleCount()));
        joint.observed = &*observed;
        joint.clusters = &*clusters;
        joint.view_counts = observed->labels();
      } catch (const Error& e) {
        out.warnings.push_back(Format("joint albedo skipped: ", e.what()));
        clusters.reset();
        observed.reset();
      }
    }
  }
  out.estimate = EstimateLights(scene, keyframes, options, seed, clusters ? &joint : nullptr);
  for (const std::string& note : out.estimate.notes) out.warnings.push_back(note);
  // With estimated exposures, the model is judged against each view divided by its gain (the
  // ambient baseline too): the gains are part of the camera model.
  std::vector<PosedImage> divided = keyframes;
  for (size_t v = 0; v < out.estimate.exposure_gains.size() && v < divided.size(); ++v) {
    const Eigen::Vector3f inverse = out.estimate.exposure_gains[v].cwiseInverse().cast<float>();
    for (Eigen::Vector3f& p : divided[v].image.pixels()) p = p.cwiseProduct(inverse);
  }
  const std::vector<PosedImage>& train = divided;

  Scene lit = WithoutLights(scene);
  lit.voxel_lights = out.estimate.lights;
  if (out.estimate.albedo) {  // the model's albedo from here on
    lit.meshes[0].albedo = SurfaceAlbedo::FromMeshColors(*out.estimate.albedo);
    WriteMeshColors(ws.JointAlbedo(), *out.estimate.albedo);
    WritePly(ws.JointAlbedoPly(), out.estimate.albedo->ToSubdividedMesh(lit.meshes[0].mesh));
  }
  const PathTracer tracer(lit);
  const fs::path dir = ws.LightsDir();
  fs::create_directories(dir);
  for (const auto& [views, prefix, errors] :
       {std::tuple{&train, "train", &out.train}, std::tuple{&novel, "novel", &out.novel}}) {
    for (size_t i = 0; i < views->size(); ++i) {
      ImageRgb render;
      errors->push_back(
          CompareRender(tracer, (*views)[i], options, in.render_spp, seed + i, 0.0, &render));
      WriteExr(dir / (Stamp(prefix, i) + ".exr"), render);
      WritePng(dir / (Stamp(prefix, i) + ".png"), render);
    }
  }
  // The baseline: the albedo under a constant ambient light, on the same pixels. It has no render
  // noise, so the renders' error with their noise taken out is what it is compared with.
  out.ambient = FitAmbientBaseline(tracer, train, options);
  for (const ViewError& e : out.train) out.train_rmse += e.rmse_bias / out.train.size();
  if (!out.train.empty() && out.train_rmse > out.ambient.mean_rmse) {
    out.warnings.push_back(
        Format("the voxel lights fit the training views worse than a constant ambient light "
               "(relative RMSE ",
               out.train_rmse, " without render noise, against ", out.ambient.mean_rmse,
               " for ambient radiance (", out.ambient.radiance.transpose(),
               ")): the light model does not describe these images"));
  }
  try {
    std::vector<PosedView> views;
    for (const PosedImage& v : train) views.push_back(v.view);
    for (std::string& w : ExportMitsubaXml(dir / "scene.xml", lit, views))
      out.warnings.push_back(std::move(w));
  } catch (const Error& e) {
    out.warnings.push_back(Format("Mitsuba export skipped: ", e.what()));
  }

  // lights.json last: its presence means the stage is complete.
  nlohmann::ordered_json estimate;
  estimate["options"] = nlohmann::ordered_json::parse(OptionsToJson(options).dump());
  estimate["seed"] = seed;
  estimate["pixels"] = out.estimate.pixels;
  estimate["active_voxels"] = out.estimate.active_voxels;
  if (out.estimate.lights.distant) estimate["distant_share"] = out.estimate.distant_share;
  estimate["train_rmse_cache"] = out.estimate.train_rmse;
  estimate["seconds"] = out.estimate.seconds;
  nlohmann::ordered_json rounds = nlohmann::ordered_json::array();
  for (const LightRound& r : out.estimate.rounds) {
    rounds.push_back({{"round", r.round},
                      {"level", r.level},
                      {"candidates", r.candidates},
                      {"nonzeros", r.nonzeros},
                      {"rays", r.rays},
                      {"trace_seconds", r.trace_seconds},
                      {"gram_seconds", r.gram_seconds},
                      {"solve_seconds", r.solve_seconds},
                      {"iterations", r.solve.iterations},
                      {"cost", r.solve.cost},
                      {"data", r.solve.data},
                      {"active_voxels", r.active_voxels},
                      {"power_change", r.power_change}});
  }
  estimate["rounds"] = rounds;
  if (!out.estimate.exposure_gains.empty()) {
    nlohmann::ordered_json views = nlohmann::ordered_json::array();
    for (size_t v = 0; v < out.estimate.exposure_gains.size(); ++v) {
      const Eigen::Vector3d& g = out.estimate.exposure_gains[v];
      views.push_back(
          {{"timestamp", keyframes[v].view.timestamp}, {"gain", {g.x(), g.y(), g.z()}}});
    }
    estimate["exposure"] = {
        {"mode", options.exposure},
        {"gauge", options.exposure == "gain" ? "geometric mean of the gains over the views = 1"
                                             : "geometric mean over the views = 1 per channel"},
        {"views", views}};
  }
  if (!out.estimate.albedo_steps.empty()) {
    nlohmann::ordered_json steps = nlohmann::ordered_json::array();
    for (const JointAlbedoStep& st : out.estimate.albedo_steps) {
      steps.push_back({{"cost", st.cost},
                       {"data", st.data},
                       {"texels_updated", st.texels_updated},
                       {"scale", st.scale},
                       {"check_before", st.check_before},
                       {"check", st.check},
                       {"kept", st.kept}});
    }
    estimate["joint_albedo"] = {
        {"initial_cost", out.estimate.rounds.empty() ? 0.0 : out.estimate.rounds.back().solve.cost},
        {"steps", steps},
        {"shading_probes", out.estimate.albedo_probes},
        {"final_scale", out.estimate.albedo_final_scale},
        {"seconds", out.estimate.albedo_seconds},
        {"gauge",
         "the clustering's: its global scale and its colour split (the lights start white)"},
        {"albedo", out.estimate.albedo ? ws.JointAlbedo().filename().string() : ""}};
  }
  estimate["ambient_baseline"] = {
      {"radiance", {out.ambient.radiance.x(), out.ambient.radiance.y(), out.ambient.radiance.z()}},
      {"train_relative_rmse", out.ambient.mean_rmse}};
  for (const auto& [key, errors] :
       {std::pair{"train_views", &out.train}, std::pair{"novel_views", &out.novel}}) {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const ViewError& e : *errors) {
      list.push_back({{"pixels", e.pixels},
                      {"relative_rmse", e.rmse},
                      {"noise", e.noise},
                      {"relative_rmse_bias", e.rmse_bias}});
    }
    estimate[key] = list;
  }
  WriteLightsJson(ws.Lights(), out.estimate.lights, estimate.dump());
  return out;
}

std::string ToString(const LightsSummary& s) {
  std::ostringstream o;
  const LightEstimate& e = s.estimate;
  o << e.pixels << " pixels, " << e.rounds.size() << " rounds, " << e.active_voxels
    << " active voxels of " << e.lights.VoxelCount() << ", " << Format(e.seconds) << " s";
  if (e.lights.distant) {
    char line[96];
    std::snprintf(line, sizeof(line), "; distant light: %.1f %% of the light at the pixels",
                  100.0 * e.distant_share);
    o << line;
  }
  for (const auto& [name, errors] :
       {std::pair{"training", &s.train}, std::pair{"novel", &s.novel}}) {
    if (errors->empty()) continue;
    double rmse = 0.0, bias = 0.0;
    for (const ViewError& v : *errors)
      rmse += v.rmse / errors->size(), bias += v.rmse_bias / errors->size();
    char line[160];
    std::snprintf(line, sizeof(line), "; %s views: relative RMSE %.3f (%.3f without render noise)",
                  name, rmse, bias);
    o << line;
  }
  if (!s.train.empty()) o << "; ambient baseline " << Format(s.ambient.mean_rmse);
  if (!e.albedo_steps.empty()) {
    int kept = 0;
    for (const JointAlbedoStep& st : e.albedo_steps) kept += st.kept ? 1 : 0;
    char line[200];
    std::snprintf(line, sizeof(line),
                  "; joint albedo: %d of %zu steps kept, %zu shading probes, light cost %.4g -> "
                  "%.4g",
                  kept, e.albedo_steps.size(), e.albedo_probes,
                  e.rounds.empty() ? 0.0 : e.rounds.back().solve.cost,
                  kept > 0 ? e.albedo_steps[static_cast<size_t>(kept - 1)].cost
                           : (e.rounds.empty() ? 0.0 : e.rounds.back().solve.cost));
    o << line;
  }
  if (!e.exposure_gains.empty()) {
    Eigen::Vector3d lo = e.exposure_gains.front(), hi = lo;
    for (const Eigen::Vector3d& g : e.exposure_gains) lo = lo.cwiseMin(g), hi = hi.cwiseMax(g);
    char line[200];
    std::snprintf(line, sizeof(line),
                  "; exposure gains over %zu views: R %.3f-%.3f, G %.3f-%.3f, B %.3f-%.3f",
                  e.exposure_gains.size(), lo.x(), hi.x(), lo.y(), hi.y(), lo.z(), hi.z());
    o << line;
  }
  return o.str();
}

}  // namespace genscene::apps
