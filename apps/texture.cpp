#include "apps/texture.h"

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/file_util.h"
#include "core/mesh_colors.h"
#include "core/options_json.h"
#include "core/ply_io.h"

namespace genscene::apps {

namespace {

using json = nlohmann::json;

TriangleMesh LoadMesh(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) {
    throw Error(Format(path.string(),
                       ": missing (run genscene-mesh on this workspace first, or give --mesh)"));
  }
  TriangleMesh mesh = ReadPly(path);
  if (mesh.faces.empty())
    throw Error(Format(path.string(), ": the mesh has no faces, nothing to texture"));
  return mesh;
}

}  // namespace

TextureSummary TextureWorkspace(const TextureInputs& inputs, const SourceOptions& source,
                                const texturing::TexturingOptions& options, const Workspace& ws) {
  options.Validate();
  const std::filesystem::path mesh_path = inputs.mesh.empty() ? ws.Mesh() : inputs.mesh;
  const std::filesystem::path views = inputs.views.empty() ? ws.Keyframes() : inputs.views;
  const TriangleMesh mesh = LoadMesh(mesh_path);
  if (!std::filesystem::is_directory(views)) {
    throw Error(Format(views.string(),
                       ": no keyframes folder (run genscene-fuse first, or give --views DIR)"));
  }
  auto frames_source = OpenFrameSource(views.string(), source);
  const std::vector<RgbdFrame> keyframes = ReadAllFrames(*frames_source);
  for (const RgbdFrame& f : keyframes) {
    if (!f.world_from_camera) {
      throw Error(
          Format(views.string(), ": frame ", f.color_path, " has no pose (groundtruth.txt)"));
    }
  }
  const texturing::TexturingResult result = texturing::TextureMesh(mesh, keyframes, options);

  WriteMeshColors(ws.Texture(), result.texture);
  WritePly(ws.TexturePly(), result.texture.ToSubdividedMesh(mesh), {true, PlyColors::kObserved});

  TextureSummary summary;
  summary.stats = result.stats;
  summary.faces = mesh.faces.size();
  for (int r : result.texture.face_resolutions())
    summary.max_resolution_used = std::max(summary.max_resolution_used, r);
  summary.mean_views_per_texel =
      result.stats.observed > 0
          ? static_cast<double>(result.stats.samples_used) / result.stats.observed
          : 0.0;
  const auto& s = result.stats;
  WriteTextFileAtomically(ws.TextureJson(),
                          json({{"summary",
                                 {{"mesh", mesh_path.string()},
                                  {"keyframes", views.string()},
                                  {"faces", mesh.faces.size()},
                                  {"texels", s.texels},
                                  {"observed", s.observed},
                                  {"filled", s.filled},
                                  {"unreached", s.unreached},
                                  {"isolated", s.isolated},
                                  {"samples_used", s.samples_used},
                                  {"samples_rejected", s.samples_rejected},
                                  {"keyframes", s.keyframes},
                                  {"keyframes_seeing_mesh", s.keyframes_seeing_mesh},
                                  {"seconds_visibility", s.seconds_visibility},
                                  {"seconds_backproject", s.seconds_backproject}}},
                                {"options", OptionsToJson(options)}})
                                  .dump(1) +
                              "\n");
  return summary;
}

std::string ToString(const TextureSummary& t) {
  const auto& s = t.stats;
  const double total = s.seconds_visibility + s.seconds_backproject;
  return Format(s.texels, " texels on ", t.faces, " faces (resolution up to ",
                t.max_resolution_used, "), ", s.observed, " observed by ", s.keyframes_seeing_mesh,
                "/", s.keyframes, " keyframes (", t.mean_views_per_texel, " views per texel, ",
                s.samples_rejected, " outlier samples dropped), ", s.filled,
                " filled from neighbours",
                s.unreached ? Format(", ", s.unreached, " unreached") : "",
                s.isolated ? Format(", ", s.isolated, " isolated vertices") : "", "; ",
                total > 0.0 ? static_cast<double>(s.texels) / total / 1e6 : 0.0, " M texels/s");
}

AlbedoSummary AlbedoWorkspace(const std::filesystem::path& mesh_path_in,
                              const texturing::AlbedoOptions& options, const Workspace& ws) {
  options.Validate();
  const std::filesystem::path mesh_path = mesh_path_in.empty() ? ws.Mesh() : mesh_path_in;
  const TriangleMesh mesh = LoadMesh(mesh_path);
  if (!std::filesystem::exists(ws.Texture())) {
    throw Error(
        Format(ws.Texture().string(), ": missing (run genscene-texture on this workspace first)"));
  }
  const MeshColors texture = ReadMeshColors(ws.Texture(), mesh);
  const texturing::AlbedoResult result =
      texturing::EstimateAlbedo(texture, texture.labels(), options);

  json clusters = json::array();
  for (const texturing::AlbedoCluster& c : result.clusters) {
    clusters.push_back(
        {{"id", c.id},
         {"albedo", {c.albedo.x(), c.albedo.y(), c.albedo.z()}},
         {"chromaticity", {c.chromaticity.x(), c.chromaticity.y(), c.chromaticity.z()}},
         {"texels", c.texels},
         {"observed_texels", c.observed_texels},
         {"pieces", c.pieces},
         {"dark", c.dark}});
  }
  const auto& s = result.stats;
  const std::string report =
      json({{"summary",
             {{"clusters", result.clusters.size()},
              {"chroma_classes", s.chroma_classes},
              {"pieces", s.pieces},
              {"boundary_edges", s.boundary_edges},
              {"shading_jump_rms", s.shading_jump_rms},
              {"white_balance", {s.white_balance.x(), s.white_balance.y(), s.white_balance.z()}}}},
            {"clusters", clusters},
            {"options", OptionsToJson(options)}})
          .dump(1) +
      "\n";
  WriteMeshColors(ws.Albedo(), result.albedo);
  WritePly(ws.AlbedoPly(), result.albedo.ToSubdividedMesh(mesh));
  WriteTextFileAtomically(ws.AlbedoJson(), report);
  return {result.stats, result.clusters};
}

std::string ToString(const AlbedoSummary& a) {
  std::string out = Format(a.clusters.size(), " clusters from ", a.stats.chroma_classes,
                           " chromaticity classes, ", a.stats.pieces, " pieces, shading jump RMS ",
                           a.stats.shading_jump_rms);
  if (a.stats.white_balance != Eigen::Vector3f::Ones()) {
    const Eigen::Vector3f& w = a.stats.white_balance;
    out += Format(", white balance x(", w.x(), ", ", w.y(), ", ", w.z(), ")");
  }
  for (size_t c = 0; c < std::min<size_t>(a.clusters.size(), 6); ++c) {
    const auto& k = a.clusters[c];
    out += Format("; #", k.id, " (", k.albedo.x(), ", ", k.albedo.y(), ", ", k.albedo.z(), ") x",
                  k.texels);
  }
  if (a.clusters.size() > 6) out += "; ...";
  return out;
}

}  // namespace genscene::apps
