#include "apps/lights.h"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/check.h"
#include "core/frame_source.h"
#include "core/image_io.h"
#include "core/light_set.h"
#include "core/mesh_colors.h"
#include "core/options_json.h"
#include "core/ply_io.h"
#include "inverse/mitsuba_xml.h"
#include "inverse/scene_io.h"

namespace genscene::apps {

namespace {

namespace fs = std::filesystem;
using namespace genscene::inverse;

// Albedo from Mesh Colors (linear lookup), clamped to [0, 1].
class MeshColorsAlbedo : public AlbedoField {
 public:
  explicit MeshColorsAlbedo(MeshColors colors) : colors_(std::move(colors)) {}
  Eigen::Vector3f Eval(int face, float b1, float b2) const override {
    return colors_.Linear(face, b1, b2).cwiseMax(0.0f).cwiseMin(1.0f);
  }

 private:
  MeshColors colors_;
};

Scene LoadGeometry(const LightsInputs& in, const Workspace& ws, std::vector<std::string>* warnings) {
  if (!in.scene.empty()) {
    LoadedScene loaded = LoadScene(in.scene);
    for (std::string& w : loaded.warnings) warnings->push_back(std::move(w));
    return loaded.scene;
  }
  const fs::path mesh_path = in.mesh.empty() ? ws.Mesh() : in.mesh;
  if (!fs::exists(mesh_path)) throw Error(Format(mesh_path.string(), ": no such mesh (run genscene-mesh, or give --mesh)"));
  SceneMesh m;
  m.name = mesh_path.stem().string();
  m.mesh = ReadPly(mesh_path);
  const fs::path albedo = !in.albedo.empty() ? in.albedo : (fs::exists(ws.Albedo()) ? ws.Albedo() : fs::path());
  if (!albedo.empty()) {
    m.albedo.kind = SurfaceAlbedo::Kind::kField;
    m.albedo.field = std::make_shared<MeshColorsAlbedo>(ReadMeshColors(albedo, m.mesh));
  } else {
    m.albedo = SurfaceAlbedo::FromMesh(m.mesh, Eigen::Vector3f::Constant(0.5f));
    if (m.mesh.face_colors.empty() && m.mesh.vertex_colors.empty()) {
      warnings->push_back(Format(mesh_path.string(), ": no albedo given and no colours in the PLY; assuming grey 0.5"));
    }
  }
  Scene scene;
  scene.meshes.push_back(std::move(m));
  return scene;
}

std::vector<TrainingView> ReadViews(const fs::path& folder) {
  if (!fs::is_directory(folder)) throw Error(Format(folder.string(), ": no such view set folder"));
  std::vector<TrainingView> views;
  auto source = OpenFrameSource(folder.string(), SourceOptions());
  while (auto frame = source->Next()) {
    if (!frame->world_from_camera) {
      throw Error(Format(frame->color_path.empty() ? folder.string() : frame->color_path, ": the image has no pose"));
    }
    if (frame->color.empty()) throw Error(Format(folder.string(), ": a frame has no colour image"));
    views.push_back({View{frame->intrinsics, *frame->world_from_camera, frame->timestamp}, frame->color});
  }
  if (views.empty()) throw Error(Format(folder.string(), ": no images"));
  return views;
}

std::string Stamp(const char* prefix, size_t index) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%s_%02zu", prefix, index);
  return buffer;
}

}  // namespace

LightsSummary LightsWorkspace(const LightsInputs& in, const LightEstimationOptions& options, uint64_t seed,
                              const Workspace& ws) {
  options.Validate();
  LightsSummary out;
  const Scene scene = LoadGeometry(in, ws, &out.warnings);
  const std::vector<TrainingView> train = ReadViews(in.views.empty() ? ws.Keyframes() : in.views);
  const std::vector<TrainingView> novel = in.novel.empty() ? std::vector<TrainingView>() : ReadViews(in.novel);
  out.estimate = EstimateLights(scene, train, options, seed);

  Scene lit = WithoutLights(scene);
  lit.voxel_lights = out.estimate.lights;
  const PathTracer tracer(lit);
  const fs::path dir = ws.root() / "lights";
  fs::create_directories(dir);
  for (const auto& [views, prefix, errors] : {std::tuple{&train, "train", &out.train}, std::tuple{&novel, "novel", &out.novel}}) {
    for (size_t i = 0; i < views->size(); ++i) {
      ImageRgb render;
      errors->push_back(CompareRender(tracer, (*views)[i], options, in.render_spp, seed + i, 0.0, &render));
      WriteExr(dir / (Stamp(prefix, i) + ".exr"), render);
      WritePng(dir / (Stamp(prefix, i) + ".png"), render);
    }
  }
  try {
    std::vector<View> views;
    for (const TrainingView& v : train) views.push_back(v.view);
    for (std::string& w : ExportMitsubaXml(dir / "scene.xml", lit, views)) out.warnings.push_back(std::move(w));
  } catch (const Error& e) {
    out.warnings.push_back(Format("Mitsuba export skipped: ", e.what()));
  }

  // lights.json last: its presence means the stage is complete.
  nlohmann::ordered_json estimate;
  estimate["options"] = nlohmann::ordered_json::parse(OptionsToJson(options).dump());
  estimate["seed"] = seed;
  estimate["pixels"] = out.estimate.pixels;
  estimate["active_voxels"] = out.estimate.active_voxels;
  estimate["train_rmse_cache"] = out.estimate.train_rmse;
  estimate["seconds"] = out.estimate.seconds;
  nlohmann::ordered_json rounds = nlohmann::ordered_json::array();
  for (const LightRound& r : out.estimate.rounds) {
    rounds.push_back({{"round", r.round}, {"nonzeros", r.nonzeros}, {"rays", r.rays},
                      {"trace_seconds", r.trace_seconds}, {"gram_seconds", r.gram_seconds},
                      {"solve_seconds", r.solve_seconds}, {"iterations", r.solve.iterations},
                      {"cost", r.solve.cost}, {"active_voxels", r.active_voxels}, {"power_change", r.power_change}});
  }
  estimate["rounds"] = rounds;
  for (const auto& [key, errors] : {std::pair{"train_views", &out.train}, std::pair{"novel_views", &out.novel}}) {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const ViewError& e : *errors) {
      list.push_back({{"pixels", e.pixels}, {"relative_rmse", e.rmse}, {"noise", e.noise}, {"relative_rmse_bias", e.rmse_bias}});
    }
    estimate[key] = list;
  }
  WriteLightsJson(ws.Lights(), out.estimate.lights, estimate.dump());
  return out;
}

std::string ToString(const LightsSummary& s) {
  std::ostringstream o;
  const LightEstimate& e = s.estimate;
  o << e.pixels << " pixels, " << e.rounds.size() << " rounds, " << e.active_voxels << " active voxels of "
    << e.lights.VoxelCount() << ", " << Format(e.seconds) << " s";
  for (const auto& [name, errors] : {std::pair{"training", &s.train}, std::pair{"novel", &s.novel}}) {
    if (errors->empty()) continue;
    double rmse = 0.0, bias = 0.0;
    for (const ViewError& v : *errors) rmse += v.rmse / errors->size(), bias += v.rmse_bias / errors->size();
    char line[160];
    std::snprintf(line, sizeof(line), "; %s views: relative RMSE %.3f (%.3f without render noise)", name, rmse, bias);
    o << line;
  }
  return o.str();
}

}  // namespace genscene::apps
