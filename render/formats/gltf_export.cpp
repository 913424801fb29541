#include "render/formats/gltf_export.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/check.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/mesh_colors_atlas.h"

namespace genscene::render {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

constexpr uint32_t kGlbMagic = 0x46546C67;   // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;   // "BIN\0"
constexpr int kFloat = 5126, kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr int kLinear = 9729, kLinearMipmapLinear = 9987, kClampToEdge = 33071;

// The JSON document and the BIN chunk as they grow.
struct Glb {
  Json gltf = Json::object();
  std::string bin;

  // Appends `bytes` at a 4-byte aligned offset as a new buffer view; returns its index.
  int AddView(const void* data, size_t bytes, int target) {
    bin.resize((bin.size() + 3) / 4 * 4, '\0');
    Json view = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}};
    if (target != 0) view["target"] = target;
    bin.append(static_cast<const char*>(data), bytes);
    gltf["bufferViews"].push_back(std::move(view));
    return static_cast<int>(gltf["bufferViews"].size()) - 1;
  }
  int AddAccessor(int view, int component_type, size_t count, const char* type) {
    gltf["accessors"].push_back({{"bufferView", view},
                                 {"componentType", component_type},
                                 {"count", count},
                                 {"type", type}});
    return static_cast<int>(gltf["accessors"].size()) - 1;
  }
  int Add(const char* key, Json value) {
    gltf[key].push_back(std::move(value));
    return static_cast<int>(gltf[key].size()) - 1;
  }
};

Json Vec(const Eigen::Vector3f& v) {
  return Json::array({v.x(), v.y(), v.z()});
}

// A unit normal for corner k of face f: the mesh's vertex normal, or the face normal when that is
// zero or not finite.
Eigen::Vector3f CornerNormal(const TriangleMesh& mesh, int f, int k) {
  Eigen::Vector3f n = mesh.normals[mesh.faces[f][k]];
  if (!n.allFinite() || n.norm() < 1e-12f) n = mesh.FaceNormalScaled(f);
  const float length = n.norm();
  return length > 1e-20f && std::isfinite(length) ? Eigen::Vector3f(n / length)
                                                  : Eigen::Vector3f::UnitZ();
}

// The mesh as one primitive with one vertex per face corner; returns the primitive (without
// material), adding its buffer views and accessors.
Json AddPrimitive(Glb& glb, const TriangleMesh& mesh, const AtlasLayout& layout) {
  const size_t corners = 3 * mesh.faces.size();
  std::vector<Eigen::Vector3f> positions(corners), normals;
  std::vector<Eigen::Vector2f> uvs = layout.CornerUvs();
  std::vector<uint32_t> indices(corners);
  const bool has_normals = !mesh.normals.empty();
  if (has_normals) normals.resize(corners);
  Eigen::Vector3f lo = Eigen::Vector3f::Zero(), hi = Eigen::Vector3f::Zero();
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const size_t c = 3 * f + k;
      positions[c] = mesh.vertices[mesh.faces[f][k]];
      if (has_normals) normals[c] = CornerNormal(mesh, static_cast<int>(f), k);
      indices[c] = static_cast<uint32_t>(c);
      lo = c == 0 ? positions[c] : Eigen::Vector3f(lo.cwiseMin(positions[c]));
      hi = c == 0 ? positions[c] : Eigen::Vector3f(hi.cwiseMax(positions[c]));
    }
  }
  Json attributes = Json::object();
  int view = glb.AddView(positions.data(), corners * sizeof(Eigen::Vector3f), kArrayBuffer);
  const int position = glb.AddAccessor(view, kFloat, corners, "VEC3");
  glb.gltf["accessors"][position]["min"] = Vec(lo);
  glb.gltf["accessors"][position]["max"] = Vec(hi);
  attributes["POSITION"] = position;
  if (has_normals) {
    view = glb.AddView(normals.data(), corners * sizeof(Eigen::Vector3f), kArrayBuffer);
    attributes["NORMAL"] = glb.AddAccessor(view, kFloat, corners, "VEC3");
  }
  view = glb.AddView(uvs.data(), corners * sizeof(Eigen::Vector2f), kArrayBuffer);
  attributes["TEXCOORD_0"] = glb.AddAccessor(view, kFloat, corners, "VEC2");
  view = glb.AddView(indices.data(), corners * sizeof(uint32_t), kElementArrayBuffer);
  const int index = glb.AddAccessor(view, kUnsignedInt, corners, "SCALAR");
  return {{"attributes", attributes}, {"indices", index}, {"mode", 4}};
}

// The atlas of `colors` as an embedded PNG texture; returns the texture index.
int AddAtlasTexture(Glb& glb, const AtlasLayout& layout, const MeshColors& colors,
                    const std::string& name, const fs::path& path) {
  const AtlasImage image = BakeAtlas(layout, colors);
  std::vector<uint8_t> png;
  try {
    png = EncodePng(image.width, image.height, image.srgb8);
  } catch (const Error& e) {
    throw Error(Format(path.string(), ": the ", name, " atlas: ", e.what()));
  }
  const int view = glb.AddView(png.data(), png.size(), 0);
  const int source =
      glb.Add("images", {{"name", name}, {"bufferView", view}, {"mimeType", "image/png"}});
  return glb.Add("textures", {{"sampler", 0}, {"source", source}, {"name", name}});
}

Json Material(const std::string& name, int texture) {
  return {{"name", name},
          {"pbrMetallicRoughness",
           {{"baseColorTexture", {{"index", texture}, {"texCoord", 0}}},
            {"metallicFactor", 0.0},
            {"roughnessFactor", 1.0}}}};
}

// One perspective camera and its node per view; returns the node indices.
std::vector<int> AddCameras(Glb& glb, const std::vector<PosedView>& views, double znear,
                            std::vector<std::string>* warnings) {
  std::vector<int> nodes;
  int anisotropic = 0, off_centre = 0, distorted = 0;
  for (size_t v = 0; v < views.size(); ++v) {
    const CameraIntrinsics& k = views[v].intrinsics;
    anisotropic += std::abs(k.fx - k.fy) > 1e-6 * k.fy;
    off_centre +=
        std::abs(k.cx - 0.5 * (k.width - 1)) > 0.5 || std::abs(k.cy - 0.5 * (k.height - 1)) > 0.5;
    distorted +=
        std::any_of(k.distortion.begin(), k.distortion.end(), [](double d) { return d != 0.0; });
    Json camera = {{"type", "perspective"},
                   {"name", Format("keyframe_", v)},
                   {"perspective",
                    {{"yfov", 2.0 * std::atan(0.5 * k.height / k.fy)},
                     {"aspectRatio", static_cast<double>(k.width) / k.height},
                     {"znear", znear}}},
                   {"extras",
                    {{"fx", k.fx},
                     {"fy", k.fy},
                     {"cx", k.cx},
                     {"cy", k.cy},
                     {"width", k.width},
                     {"height", k.height},
                     {"timestamp", views[v].timestamp}}}};
    const int index = glb.Add("cameras", std::move(camera));
    // OpenCV camera (x right, y down, z forward) to glTF camera (x right, y up, looking down -z).
    const Eigen::Matrix3d rotation =
        views[v].world_from_camera.linear() * Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
    const Eigen::Quaterniond q = Eigen::Quaterniond(rotation).normalized();
    const Eigen::Vector3d t = views[v].world_from_camera.translation();
    nodes.push_back(glb.Add("nodes", {{"name", Format("keyframe_", v)},
                                      {"camera", index},
                                      {"translation", {t.x(), t.y(), t.z()}},
                                      {"rotation", {q.x(), q.y(), q.z(), q.w()}}}));
  }
  if (anisotropic > 0) {
    warnings->push_back(Format("glTF: ", anisotropic,
                               " camera(s) with fx != fy keep fy only (the "
                               "horizontal field of view follows the aspect ratio)"));
  }
  if (off_centre > 0) {
    warnings->push_back(Format("glTF: ", off_centre,
                               " camera(s) with an off-centre principal "
                               "point are exported centred"));
  }
  if (distorted > 0) {
    warnings->push_back(
        Format("glTF: ", distorted, " camera(s) with lens distortion exported without it"));
  }
  return nodes;
}

// One point light per active voxel under a node "voxel_lights"; returns that node (-1: none).
int AddLights(Glb& glb, const VoxelLightGrid& grid, int* count) {
  const std::vector<int> active = grid.ActiveVoxels();
  *count = static_cast<int>(active.size());
  if (active.empty()) return -1;
  Json lights = Json::array(), children = Json::array();
  for (int voxel : active) {
    const std::array<float, 6>& w = grid.weights[voxel];
    float weight_sum = 0.0f;
    for (float lambda : w) weight_sum += lambda;
    const Eigen::Vector3f intensity = grid.intensity[voxel] * (weight_sum / 4.0f);
    const float peak = intensity.maxCoeff();
    const Eigen::Vector3f color =
        peak > 0.0f ? Eigen::Vector3f(intensity / peak) : Eigen::Vector3f::Ones();
    lights.push_back({{"name", Format("voxel_", voxel)},
                      {"type", "point"},
                      {"color", Vec(color)},
                      {"intensity", peak},
                      {"extras",
                       {{"voxel", voxel},
                        {"intensity_L", Vec(grid.intensity[voxel])},
                        {"weights", Json::array({w[0], w[1], w[2], w[3], w[4], w[5]})}}}});
    const Eigen::Vector3d c = grid.VoxelCenter(voxel);
    Json node = {{"name", Format("voxel_", voxel)},
                 {"translation", {c.x(), c.y(), c.z()}},
                 {"extensions", {{"KHR_lights_punctual", {{"light", lights.size() - 1}}}}}};
    children.push_back(glb.Add("nodes", std::move(node)));
  }
  glb.gltf["extensions"]["KHR_lights_punctual"]["lights"] = std::move(lights);
  glb.gltf["extensionsUsed"].push_back("KHR_lights_punctual");
  return glb.Add("nodes", {{"name", "voxel_lights"}, {"children", std::move(children)}});
}

void PutU32(std::string& out, uint32_t value) {
  const char bytes[4] = {static_cast<char>(value), static_cast<char>(value >> 8),
                         static_cast<char>(value >> 16), static_cast<char>(value >> 24)};
  out.append(bytes, 4);
}

// The GLB container of `json` and `bin`, written atomically; returns its size in bytes.
size_t WriteGlb(const fs::path& path, const std::string& json, const std::string& bin) {
  std::string json_chunk = json, bin_chunk = bin;
  json_chunk.resize((json_chunk.size() + 3) / 4 * 4, ' ');
  bin_chunk.resize((bin_chunk.size() + 3) / 4 * 4, '\0');
  const size_t total = 12 + 8 + json_chunk.size() + (bin_chunk.empty() ? 0 : 8 + bin_chunk.size());
  if (total > 0xffffffffull) {
    throw Error(Format(path.string(), ": the model needs ", total,
                       " bytes, more than a .glb can hold (4 GiB)"));
  }
  std::string out;
  out.reserve(total);
  PutU32(out, kGlbMagic);
  PutU32(out, 2);
  PutU32(out, static_cast<uint32_t>(total));
  PutU32(out, static_cast<uint32_t>(json_chunk.size()));
  PutU32(out, kChunkJson);
  out += json_chunk;
  if (!bin_chunk.empty()) {
    PutU32(out, static_cast<uint32_t>(bin_chunk.size()));
    PutU32(out, kChunkBin);
    out += bin_chunk;
  }
  WriteFileAtomically(path, [&](const fs::path& tmp) {
    std::ofstream file(tmp, std::ios::binary);
    file.write(out.data(), static_cast<std::streamsize>(out.size()));
    file.close();
    if (!file) throw Error(Format(path.string(), ": cannot write the glTF file"));
  });
  return total;
}

void CheckInputs(const fs::path& path, const TriangleMesh& mesh, const MeshColors& albedo,
                 const MeshColors* observed, const VoxelLightGrid* lights,
                 const std::vector<PosedView>& views) {
  const std::string where = path.string();
  mesh.Validate(where);
  if (mesh.faces.empty()) throw Error(Format(where, ": the mesh has no faces; nothing to export"));
  const uint64_t fingerprint = MeshFingerprint(mesh);
  if (albedo.mesh_fingerprint() != fingerprint) {
    throw Error(Format(where, ": the albedo Mesh Colors were made for another mesh"));
  }
  if (observed && observed->mesh_fingerprint() != fingerprint) {
    throw Error(Format(where, ": the observed Mesh Colors were made for another mesh"));
  }
  try {
    if (lights) lights->Validate();
    for (size_t v = 0; v < views.size(); ++v) {
      views[v].intrinsics.Validate(Format("camera ", v));
    }
  } catch (const Error& e) {
    throw Error(Format(where, ": ", e.what()));
  }
}

}  // namespace

GltfExportSummary ExportGltf(const fs::path& path, const TriangleMesh& mesh,
                             const MeshColors& albedo, const MeshColors* observed,
                             const VoxelLightGrid* lights, const std::vector<PosedView>& views,
                             const GltfExportOptions& options) {
  CheckInputs(path, mesh, albedo, observed, lights, views);
  GltfExportSummary summary;
  std::vector<int> resolution = albedo.face_resolutions();
  if (observed) {
    for (size_t f = 0; f < resolution.size(); ++f)
      resolution[f] = std::max(resolution[f], observed->FaceResolution(static_cast<int>(f)));
  }
  AtlasOptions atlas_options;
  atlas_options.max_size = options.atlas_max_size;
  atlas_options.gutter = options.atlas_gutter;
  const AtlasLayout layout = MakeAtlasLayout(resolution, atlas_options);
  summary.warnings = layout.warnings;

  Glb glb;
  glb.gltf["asset"] = {{"version", "2.0"}, {"generator", "genscene"}};
  Json primitive = AddPrimitive(glb, mesh, layout);
  glb.Add("samplers", {{"magFilter", kLinear},
                       {"minFilter", kLinearMipmapLinear},
                       {"wrapS", kClampToEdge},
                       {"wrapT", kClampToEdge}});
  primitive["material"] = glb.Add(
      "materials", Material("albedo", AddAtlasTexture(glb, layout, albedo, "albedo", path)));
  if (observed) {
    Json material = Material("observed", AddAtlasTexture(glb, layout, *observed, "observed", path));
    material["extensions"]["KHR_materials_unlit"] = Json::object();
    const int index = glb.Add("materials", std::move(material));
    glb.gltf["extensions"]["KHR_materials_variants"]["variants"] =
        Json::array({{{"name", "albedo"}}, {{"name", "observed"}}});
    primitive["extensions"]["KHR_materials_variants"]["mappings"] =
        Json::array({{{"material", 0}, {"variants", Json::array({0})}},
                     {{"material", index}, {"variants", Json::array({1})}}});
    glb.gltf["extensionsUsed"].push_back("KHR_materials_unlit");
    glb.gltf["extensionsUsed"].push_back("KHR_materials_variants");
    summary.observed = true;
  }
  glb.Add("meshes", {{"name", "model"}, {"primitives", Json::array({std::move(primitive)})}});
  Json scene_nodes = Json::array({glb.Add("nodes", {{"name", "model"}, {"mesh", 0}})});
  for (int node : AddCameras(glb, views, options.znear, &summary.warnings))
    scene_nodes.push_back(node);
  summary.cameras = static_cast<int>(views.size());
  if (lights) {
    const int node = AddLights(glb, *lights, &summary.lights);
    if (node >= 0) scene_nodes.push_back(node);
  }
  glb.gltf["scenes"] = Json::array({{{"name", "genscene model"}, {"nodes", scene_nodes}}});
  glb.gltf["scene"] = 0;
  glb.gltf["buffers"] = Json::array({{{"byteLength", glb.bin.size()}}});
  glb.gltf["extras"] = {{"genscene_atlas",
                         {{"width", layout.width},
                          {"height", layout.height},
                          {"downscale", layout.downscale},
                          {"gutter", options.atlas_gutter}}},
                        {"light_units", "linear radiometric (W/sr), not candela"}};
  summary.atlas_width = layout.width;
  summary.atlas_height = layout.height;
  summary.atlas_downscale = layout.downscale;
  summary.bytes = WriteGlb(path, glb.gltf.dump(), glb.bin);
  return summary;
}

}  // namespace genscene::render
