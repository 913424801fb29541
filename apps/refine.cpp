#include "apps/refine.h"

#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "core/check.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/light_set.h"
#include "core/options_json.h"
#include "core/ply_io.h"

namespace genscene::apps {

namespace {

namespace fs = std::filesystem;
using namespace genscene::inverse;
using namespace genscene::render;

// The indices of the meshes to refine, in scene order: those named, or every non-emitter.
std::vector<int> ChooseMeshes(const Scene& scene, const std::vector<std::string>& names,
                              std::vector<std::string>* chosen) {
  std::vector<int> refined;
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    const SceneMesh& mesh = scene.meshes[m];
    if (mesh.IsEmitter()) continue;
    const bool named = std::find(names.begin(), names.end(), mesh.name) != names.end();
    if (names.empty() || named) {
      refined.push_back(static_cast<int>(m));
      chosen->push_back(mesh.name);
    }
  }
  for (const std::string& name : names) {
    if (std::find(chosen->begin(), chosen->end(), name) == chosen->end()) {
      std::string known;
      for (const SceneMesh& m : scene.meshes) known += (known.empty() ? "" : ", ") + m.name;
      throw Error(Format("--refine ", name,
                         ": no such non-emitting mesh in the scene (meshes: ", known, ")"));
    }
  }
  return refined;
}

// The meshes as one mesh (vertices in order), with the vertex colours of the meshes when every one
// has them; with `keep_normals` and every mesh carrying vertex normals, those, else area-weighted
// ones.
TriangleMesh JoinMeshes(const std::vector<TriangleMesh>& meshes, bool keep_normals) {
  TriangleMesh out;
  bool colored = true, with_normals = keep_normals;
  for (const TriangleMesh& mesh : meshes) {
    colored = colored && mesh.vertex_colors.size() == mesh.vertices.size();
    with_normals = with_normals && mesh.normals.size() == mesh.vertices.size();
  }
  for (const TriangleMesh& mesh : meshes) {
    const int offset = static_cast<int>(out.vertices.size());
    out.vertices.insert(out.vertices.end(), mesh.vertices.begin(), mesh.vertices.end());
    if (colored)
      out.vertex_colors.insert(out.vertex_colors.end(), mesh.vertex_colors.begin(),
                               mesh.vertex_colors.end());
    if (with_normals)
      out.normals.insert(out.normals.end(), mesh.normals.begin(), mesh.normals.end());
    for (const Eigen::Vector3i& f : mesh.faces)
      out.faces.push_back(f + Eigen::Vector3i::Constant(offset));
  }
  if (!with_normals) out.ComputeVertexNormals();
  return out;
}

// The true positions of the refined vertices from a PLY, (x, y, z) each; throws Error when the
// count is not `vertices`.
Eigen::VectorXd ReadTruth(const fs::path& path, int vertices) {
  const TriangleMesh t = ReadPly(path);
  if (static_cast<int>(t.vertices.size()) != vertices) {
    throw Error(Format(path.string(), ": ", t.vertices.size(),
                       " vertices, but the refined meshes have ", vertices));
  }
  Eigen::VectorXd truth(3 * t.vertices.size());
  for (size_t v = 0; v < t.vertices.size(); ++v)
    truth.segment<3>(3 * v) = t.vertices[v].cast<double>();
  return truth;
}

// The fit gate: why the workspace's lights (lights.json, as the light stage judged them) are too
// poor for refinement, or nothing. They are when they fit the training views worse than a constant
// ambient light, both without render noise.
std::optional<std::string> LightsTooPoorToRefine(const fs::path& lights) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(ReadTextFile(lights));
  } catch (const std::exception&) {
    return std::nullopt;  // ReadLightsJson has read it: only the estimate's figures are missing
  }
  if (!j.contains("estimate") || !j["estimate"].is_object()) return std::nullopt;
  const auto& e = j["estimate"];
  if (!e.contains("train_views") || !e.contains("ambient_baseline") || e["train_views"].empty())
    return std::nullopt;
  double fit = 0.0;
  for (const auto& v : e["train_views"]) fit += v.value("relative_rmse_bias", 0.0);
  fit /= static_cast<double>(e["train_views"].size());
  const double ambient = e["ambient_baseline"].value("train_relative_rmse", 0.0);
  if (!(ambient > 0.0) || fit <= ambient) return std::nullopt;
  return Format(
      "the lights fit the training views worse than a constant ambient light (relative "
      "RMSE ",
      fit, " against ", ambient,
      " without render noise): renders that do not describe the images carry no "
      "geometric information");
}

// report.json: the options, the refined meshes, the held-out comparison and the iterations.
nlohmann::ordered_json Report(const RefineSummary& out, const RefineOptions& options,
                              uint64_t seed) {
  nlohmann::ordered_json report;
  report["options"] = nlohmann::ordered_json::parse(OptionsToJson(options).dump());
  report["seed"] = seed;
  report["refined_meshes"] = out.refined;
  if (!out.skipped.empty()) report["skipped"] = out.skipped;
  report["vertices"] = out.vertices;
  report["pixels"] = out.result.pixels;
  report["flipped_faces"] = out.flipped_faces;
  report["held_out"] = {{"pixels", out.held_out.pixels},
                        {"image_rmse_unrefined", out.held_out.rmse_a},
                        {"image_rmse_refined", out.held_out.rmse_b},
                        {"improvement_z", out.held_out.improvement_z},
                        {"kept_unrefined", out.kept_unrefined}};
  nlohmann::ordered_json iterations = nlohmann::ordered_json::array();
  for (size_t i = 0; i < out.result.history.size(); ++i) {
    const RefineIteration& it = out.result.history[i];
    nlohmann::ordered_json j = {{"iteration", it.iteration},
                                {"cost", it.cost},
                                {"image_rmse", it.data_rmse},
                                {"step_rms_m", it.step_rms},
                                {"accepted", it.accepted},
                                {"rejected", it.rejected},
                                {"held_vertices", it.held},
                                {"damping", it.damping},
                                {"seconds", it.seconds},
                                {"jacobian_nonzeros_per_pixel", it.jacobian_nonzeros_per_pixel},
                                {"rays", it.rays.total()}};
    if (i < out.vertex_rms.size())
      j["vertex_rms_m"] = out.vertex_rms[i], j["vertex_max_m"] = out.vertex_max[i];
    iterations.push_back(j);
  }
  report["iterations"] = iterations;
  return report;
}

}  // namespace

RefineSummary RefineWorkspace(const RefineInputs& in, const RefineOptions& options, uint64_t seed,
                              const Workspace& ws) {
  options.Validate();
  RefineSummary out;
  Scene scene = LoadGeometry(in.geometry, ws, &out.warnings);
  const fs::path lights = !in.lights.empty()                                       ? in.lights
                          : (in.geometry.scene.empty() && fs::exists(ws.Lights())) ? ws.Lights()
                                                                                   : fs::path();
  if (!lights.empty()) scene.voxel_lights = ReadLightsJson(lights);
  const bool lit = scene.voxel_lights || !scene.point_lights.empty() ||
                   std::any_of(scene.meshes.begin(), scene.meshes.end(),
                               [](const SceneMesh& m) { return m.IsEmitter(); });
  if (!lit) {
    throw Error(
        in.geometry.scene.empty()
            ? Format(ws.Lights().string(), ": no lights (run genscene-lights, or give --lights)")
            : Format(in.geometry.scene.string(), ": the scene has no lights (give --lights)"));
  }
  const std::vector<PosedImage> targets =
      ReadPosedImages(in.views.empty() ? ws.Keyframes() : in.views);
  const std::vector<int> refined = ChooseMeshes(scene, in.refine, &out.refined);
  std::vector<TriangleMesh> start_meshes;
  for (int m : refined) start_meshes.push_back(scene.meshes[m].mesh);
  const TriangleMesh start = JoinMeshes(start_meshes, true);

  out.vertices = static_cast<int>(start.vertices.size());
  std::optional<Eigen::VectorXd> truth;  // in the order of the joined refined meshes
  if (!in.truth.empty()) truth = ReadTruth(in.truth, out.vertices);
  const fs::path dir = ws.RefineDir();
  fs::create_directories(dir);
  RenderOptions render = options.paths;
  render.spp = std::max(1, in.render_spp);

  const auto progress = [&](const RefineIteration& it, const DifferentiablePathTracer& at) {
    std::printf(
        "genscene-refine: iteration %d: cost %.6g, image RMSE %.4f, step %.2e m%s (%.1f s)\n",
        it.iteration, it.cost, it.data_rmse, it.step_rms, it.accepted ? "" : ", rejected",
        it.seconds);
    std::fflush(stdout);
    if (truth) {
      const Eigen::VectorXd d = at.Positions() - *truth;
      double max = 0.0;
      for (int v = 0; v < at.VertexCount(); ++v) max = std::max(max, d.segment<3>(3 * v).norm());
      out.vertex_rms.push_back(std::sqrt(d.squaredNorm() / at.VertexCount()));
      out.vertex_max.push_back(max);
    }
    if (in.render_spp > 0) {
      char name[32];
      std::snprintf(name, sizeof(name), "iter_%02d", it.iteration);
      const PosedView& view = targets.front().view;
      WritePng(dir / (std::string(name) + ".png"),
               PathTracer(at.scene()).Render(view, render, 1).radiance);
      WritePng(dir / (std::string(name) + "_shading.png"),
               PathTracer(ShadingOnly(at.scene())).Render(view, render, 1).radiance);
    }
  };
  if (options.fit_gate && lights == ws.Lights()) {
    if (std::optional<std::string> why = LightsTooPoorToRefine(lights)) {
      out.skipped = *why;
      out.kept_unrefined = true;
      out.warnings.push_back(Format("refinement skipped: ", *why,
                                    "; the unrefined mesh is kept as ",
                                    ws.RefinedMesh().filename().string()));
    }
  }
  if (out.skipped.empty()) {
    // The tracer's positions in `progress` are the refined meshes' vertices in scene order, as
    // `refined` and the truth.
    out.result = RefineVertices(scene, refined, targets, options, seed, progress);
    // Judged on pixels it did not fit: never a mesh that explains the images worse than its
    // input.
    out.held_out =
        CompareOnFreshPixels(scene, refined, targets, options, seed ^ 0x6a09e667f3bcc909ull,
                             out.result.initial, out.result.positions);
    if (out.held_out.rmse_b > out.held_out.rmse_a) {
      out.kept_unrefined = true;
      out.warnings.push_back(Format("the refined mesh fits ", out.held_out.pixels,
                                    " held-out pixels worse than the unrefined one "
                                    "(image RMSE ",
                                    out.held_out.rmse_b, " against ", out.held_out.rmse_a,
                                    "): the unrefined mesh is kept as ",
                                    ws.RefinedMesh().filename().string()));
    } else if (out.held_out.improvement_z < options.held_out_z) {
      out.kept_unrefined = true;
      out.warnings.push_back(Format(
          "the refined mesh fits ", out.held_out.pixels,
          " held-out pixels better than the unrefined one only within the noise (image RMSE ",
          out.held_out.rmse_b, " against ", out.held_out.rmse_a, ", ", out.held_out.improvement_z,
          " standard errors, held_out_z ", options.held_out_z, "): the unrefined mesh is kept as ",
          ws.RefinedMesh().filename().string()));
    }
  }
  TriangleMesh final_mesh = out.kept_unrefined ? start : JoinMeshes(out.result.meshes, false);
  // The refined mesh keeps the colours of the mesh it started from.
  if (final_mesh.vertices.size() == start.vertices.size())
    final_mesh.vertex_colors = start.vertex_colors;
  if (final_mesh.faces.size() == start.faces.size()) final_mesh.face_colors = start.face_colors;
  out.flipped_faces = FlippedFaces(start, final_mesh);

  WriteTextFileAtomically(dir / "report.json", Report(out, options, seed).dump(1) + "\n");
  // The mesh last: its presence means the stage is complete.
  // A workspace mesh's colours are what the camera saw; a scene file's PLY colours are albedo.
  WritePly(ws.RefinedMesh(), final_mesh,
           {true, in.geometry.scene.empty() ? PlyColors::kObserved : PlyColors::kAlbedo});
  return out;
}

std::string ToString(const RefineSummary& s) {
  std::ostringstream o;
  if (!s.skipped.empty()) {
    o << s.vertices << " vertices of " << s.refined.size()
      << " mesh(es) kept unrefined: " << s.skipped;
    return o.str();
  }
  const auto& h = s.result.history;
  o << s.vertices << " vertices of " << s.refined.size() << " mesh(es), " << s.result.pixels
    << " pixels, " << (h.size() - 1) << " iterations; image RMSE " << Format(h.front().data_rmse)
    << " -> " << Format(h.back().data_rmse);
  if (!s.vertex_rms.empty()) {
    o << "; vertex RMS error " << Format(s.vertex_rms.front()) << " -> "
      << Format(s.vertex_rms.back()) << " m";
  }
  o << "; " << s.flipped_faces << " flipped faces; held-out pixels: image RMSE "
    << Format(s.held_out.rmse_a) << " unrefined, " << Format(s.held_out.rmse_b) << " refined ("
    << Format(s.held_out.improvement_z) << " standard errors)"
    << (s.kept_unrefined ? " (unrefined mesh kept)" : "");
  return o.str();
}

}  // namespace genscene::apps
