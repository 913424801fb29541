// Scene files: our JSON format, the cbox-cycles loader and LoadScene (the mesh sources the loaders
// share are in mesh_sources.cpp). The formats are documented in scene_io.h.
#include "render/formats/scene_io.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/check.h"
#include "core/file_util.h"
#include "core/json_util.h"
#include "core/ply_io.h"
#include "core/se3.h"
#include "render/formats/mesh_sources.h"
#include "render/formats/mitsuba_xml.h"

namespace genscene::render {

namespace {

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Matrix4d;
using Eigen::Vector3d;
using Eigen::Vector3f;
using json = nlohmann::ordered_json;  // keeps the documented key order when writing

using namespace json_util;  // NOLINT: CheckKeys, JsonNumber, JsonVector, ... (core/json_util.h)

std::string Digits17(const std::vector<double>& values) {
  std::ostringstream out;
  out << std::setprecision(17);
  for (size_t i = 0; i < values.size(); ++i) out << (i ? " " : "") << values[i];
  return out.str();
}

// "fx fy cx cy width height [k1 k2 p1 p2 k3]", as intrinsics.txt.
CameraIntrinsics ParseIntrinsicsLine(const std::string& line, const std::string& where) {
  const std::vector<std::string> t = SplitWhitespace(line);
  if (t.size() != 6 && t.size() != 11)
    throw Error(Format(where, ": expected 6 or 11 values, got '", line, "'"));
  CameraIntrinsics k;
  k.fx = ParseDouble(t[0], where);
  k.fy = ParseDouble(t[1], where);
  k.cx = ParseDouble(t[2], where);
  k.cy = ParseDouble(t[3], where);
  k.width = ParseInt32(t[4], where);
  k.height = ParseInt32(t[5], where);
  for (size_t i = 6; i < t.size(); ++i) k.distortion[i - 6] = ParseDouble(t[i], where);
  k.Validate(where);
  return k;
}

PosedView ParseCamera(const json& j, const std::string& where) {
  CheckKeys(j, {"intrinsics", "pose"}, where);
  if (!j.contains("intrinsics") || !j["intrinsics"].is_string() || !j.contains("pose") ||
      !j["pose"].is_string()) {
    throw Error(Format(where, ": needs \"intrinsics\" and \"pose\" strings"));
  }
  PosedView view;
  view.intrinsics = ParseIntrinsicsLine(j["intrinsics"].get<std::string>(), where + ".intrinsics");
  const std::vector<std::string> t = SplitWhitespace(j["pose"].get<std::string>());
  if (t.size() != 8) throw Error(Format(where, ".pose: expected 'timestamp tx ty tz qx qy qz qw'"));
  std::array<double, 8> v{};
  for (size_t i = 0; i < 8; ++i) v[i] = ParseDouble(t[i], where + ".pose");
  view.timestamp = v[0];
  try {
    view.world_from_camera = PoseFromTranslationQuaternion(
        Vector3d(v[1], v[2], v[3]), Eigen::Quaterniond(v[7], v[4], v[5], v[6]));
  } catch (const Error& e) {
    throw Error(Format(where, ".pose: ", e.what()));
  }
  return view;
}

json CameraToJson(const PosedView& view) {
  const CameraIntrinsics& k = view.intrinsics;
  std::vector<double> line = {
      k.fx, k.fy, k.cx, k.cy, static_cast<double>(k.width), static_cast<double>(k.height)};
  if (std::any_of(k.distortion.begin(), k.distortion.end(), [](double d) { return d != 0.0; })) {
    line.insert(line.end(), k.distortion.begin(), k.distortion.end());
  }
  Vector3d t;
  Eigen::Quaterniond q;
  ToTranslationQuaternion(view.world_from_camera, &t, &q);
  return {{"intrinsics", Digits17(line)},
          {"pose", Digits17({view.timestamp, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()})}};
}

RenderSettings ParseRender(const json& j, const std::string& where) {
  CheckKeys(j,
            {"integrator", "max_depth", "samples_per_pixel", "pixel_filter", "gaussian_stddev",
             "near_clip", "far_clip"},
            where);
  RenderSettings s;
  const auto integer = [&](const char* key) -> std::optional<int> {
    if (!j.contains(key)) return std::nullopt;
    return JsonInt(j[key], Format(where, ".", key));
  };
  const auto number = [&](const char* key) -> std::optional<double> {
    if (!j.contains(key)) return std::nullopt;
    return JsonNumber(j[key], Format(where, ".", key));
  };
  if (j.contains("integrator")) {
    s.integrator = j["integrator"].is_string() ? j["integrator"].get<std::string>() : "";
    if (s.integrator != "path" && s.integrator != "direct") {
      throw Error(Format(where, ".integrator: expected \"path\" or \"direct\", got ",
                         j["integrator"].dump()));
    }
  }
  s.max_depth = integer("max_depth");
  s.samples_per_pixel = integer("samples_per_pixel");
  if (j.contains("pixel_filter")) {
    const std::string f = j["pixel_filter"].is_string() ? j["pixel_filter"].get<std::string>() : "";
    if (f != "box" && f != "gaussian")
      throw Error(Format(where, ".pixel_filter: expected \"box\" or \"gaussian\""));
    s.pixel_filter =
        PixelFilter{f == "box" ? PixelFilter::Kind::kBox : PixelFilter::Kind::kGaussian,
                    number("gaussian_stddev").value_or(0.5)};
  } else if (j.contains("gaussian_stddev")) {
    throw Error(Format(where, ".gaussian_stddev: needs \"pixel_filter\": \"gaussian\""));
  }
  s.near_clip = number("near_clip");
  s.far_clip = number("far_clip");
  return s;
}

json RenderToJson(const RenderSettings& s) {
  json j = json::object();
  if (s.integrator) j["integrator"] = *s.integrator;
  if (s.max_depth) j["max_depth"] = *s.max_depth;
  if (s.samples_per_pixel) j["samples_per_pixel"] = *s.samples_per_pixel;
  if (s.pixel_filter) {
    const bool box = s.pixel_filter->kind == PixelFilter::Kind::kBox;
    j["pixel_filter"] = box ? "box" : "gaussian";
    if (!box) j["gaussian_stddev"] = s.pixel_filter->stddev;
  }
  if (s.near_clip) j["near_clip"] = *s.near_clip;
  if (s.far_clip) j["far_clip"] = *s.far_clip;
  return j;
}

SceneMesh ParseMesh(const json& j, const fs::path& file, const std::string& where, size_t index) {
  CheckKeys(j, {"name", "ply", "albedo", "emission", "smooth"}, where);
  if (!j.contains("ply") || !j["ply"].is_string())
    throw Error(Format(where, ": needs a \"ply\" path"));
  SceneMesh m;
  if (j.contains("name") && !j["name"].is_string())
    throw Error(Format(where, ".name: expected a string, got ", j["name"].dump()));
  m.name = j.contains("name") ? j["name"].get<std::string>() : Format("mesh", index);
  m.mesh = ReadPly(ResolveRelativeTo(file, j["ply"].get<std::string>()));
  if (!j.contains("albedo")) {
    m.albedo = SurfaceAlbedo::Constant(Vector3f::Constant(0.5f));
  } else if (j["albedo"] == "from_ply") {
    if (m.mesh.face_colors.empty() && m.mesh.vertex_colors.empty()) {
      throw Error(Format(where, ".albedo: \"from_ply\" but ", j["ply"].get<std::string>(),
                         " has no colours"));
    }
    m.albedo = SurfaceAlbedo::FromMesh(m.mesh, Vector3f::Constant(0.5f));
  } else {
    m.albedo = SurfaceAlbedo::Constant(JsonVector<3>(j["albedo"], where + ".albedo").cast<float>());
  }
  if (j.contains("emission"))
    m.emission = JsonVector<3>(j["emission"], where + ".emission").cast<float>();
  if (j.contains("smooth")) {
    if (!j["smooth"].is_boolean()) throw Error(Format(where, ".smooth: expected true or false"));
    m.smooth_shading = j["smooth"].get<bool>();
    if (m.smooth_shading && m.mesh.normals.empty()) {
      throw Error(Format(where, ".smooth: the PLY has no vertex normals (nx, ny, nz)"));
    }
  }
  return m;
}

LoadedScene LoadSceneJsonUnguarded(const fs::path& path) {
  const std::string name = path.string();
  const json j = ParseJsonFile(path);
  CheckKeys(j, {"genscene_scene", "meshes", "point_lights", "voxel_lights", "cameras", "render"},
            name);
  if (!j.contains("genscene_scene") || j["genscene_scene"] != 1) {
    throw Error(Format(name, ": \"genscene_scene\": 1 (the format version) is missing or not 1"));
  }
  LoadedScene out;
  if (j.contains("meshes")) {
    for (const json& m : JsonArray(j["meshes"], name + ": meshes")) {
      const size_t i = out.scene.meshes.size();
      out.scene.meshes.push_back(ParseMesh(m, path, Format(name, ": meshes[", i, "]"), i));
    }
  }
  if (j.contains("point_lights")) {
    for (const json& p : JsonArray(j["point_lights"], name + ": point_lights")) {
      const std::string where = Format(name, ": point_lights[", out.scene.point_lights.size(), "]");
      CheckKeys(p, {"position", "intensity"}, where);
      if (!p.contains("position") || !p.contains("intensity"))
        throw Error(Format(where, ": needs position and intensity"));
      PointLight light;
      light.position = JsonVector<3>(p["position"], where + ".position");
      light.intensity = JsonVector<3>(p["intensity"], where + ".intensity").cast<float>();
      out.scene.point_lights.push_back(light);
    }
  }
  if (j.contains("voxel_lights"))
    out.scene.voxel_lights = VoxelLightGridFromJson(j["voxel_lights"], name + ": voxel_lights");
  if (j.contains("cameras")) {
    for (const json& c : JsonArray(j["cameras"], name + ": cameras")) {
      out.views.push_back(ParseCamera(c, Format(name, ": cameras[", out.views.size(), "]")));
    }
  }
  if (j.contains("render")) out.settings = ParseRender(j["render"], name + ": render");
  out.scene.Validate();
  return out;
}

// nlohmann's own exceptions (a value of the wrong JSON type) become Errors naming the file.
template <typename F>
auto GuardJson(const fs::path& path, F&& f) {
  try {
    return f();
  } catch (const json::exception& e) {
    throw Error(Format(path.string(), ": ", e.what()));
  }
}

std::string FileSafe(const std::string& name) {
  std::string out;
  for (char c : name)
    out += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
  return out.substr(0, 64);
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Public entry points.

LoadedScene LoadScene(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  if (ext == ".xml") return ImportMitsubaXml(path);
  if (ext == ".json") return GuardJson(path, [&] { return LoadSceneJsonUnguarded(path); });
  throw Error(Format(path.string(), ": unknown scene format '", ext, "' (expected .xml or .json)"));
}

void SaveSceneJson(const fs::path& path, const Scene& scene, const std::vector<PosedView>& views,
                   const RenderSettings& settings) {
  scene.Validate();
  const std::string folder = path.stem().string() + "_meshes";
  json j = {{"genscene_scene", 1}};
  json meshes = json::array();
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const SceneMesh& m = scene.meshes[i];
    std::ostringstream file;
    file << folder << "/" << std::setw(3) << std::setfill('0') << i << "_" << FileSafe(m.name)
         << ".ply";
    json e = {{"name", m.name}, {"ply", file.str()}};
    TriangleMesh mesh = m.mesh;
    switch (m.albedo.kind) {
      case SurfaceAlbedo::Kind::kConstant:
        e["albedo"] = FloatsToJson(m.albedo.constant);
        break;
      case SurfaceAlbedo::Kind::kPerFace:
        mesh.face_colors = m.albedo.values;
        e["albedo"] = "from_ply";
        break;
      case SurfaceAlbedo::Kind::kPerVertex:
        mesh.vertex_colors = m.albedo.values;
        mesh.face_colors.clear();  // "from_ply" prefers face colours
        e["albedo"] = "from_ply";
        break;
      case SurfaceAlbedo::Kind::kField:
        throw Error(Format(path.string(), ": mesh '", m.name,
                           "' has an albedo field, which the scene "
                           "JSON cannot store; bake it per vertex or per face first"));
    }
    if (m.emission != Vector3f::Zero()) e["emission"] = FloatsToJson(m.emission);
    if (m.smooth_shading) e["smooth"] = true;
    WritePly(path.parent_path() / file.str(), mesh);
    meshes.push_back(e);
  }
  j["meshes"] = meshes;
  json lights = json::array();
  for (const PointLight& p : scene.point_lights) {
    lights.push_back({{"position", ToJson(p.position)}, {"intensity", FloatsToJson(p.intensity)}});
  }
  j["point_lights"] = lights;
  if (scene.voxel_lights) j["voxel_lights"] = VoxelLightGridToJson(*scene.voxel_lights);
  if (!views.empty()) {
    json cameras = json::array();
    for (const PosedView& v : views) cameras.push_back(CameraToJson(v));
    j["cameras"] = cameras;
  }
  const json render = RenderToJson(settings);
  if (!render.empty()) j["render"] = render;
  WriteTextFileAtomically(path, j.dump(2) + "\n");
}

namespace {

// A per-face albedo that is one colour must be the object's albedo_rgb: a constant albedo then.
SurfaceAlbedo CyclesObjectAlbedo(std::vector<Vector3f> albedo, const json& o,
                                 const std::string& where) {
  const Vector3f listed =
      JsonVector<3>(o.value("albedo_rgb", json()), where + ".albedo_rgb").cast<float>();
  const bool constant =
      std::all_of(albedo.begin(), albedo.end(), [&](const Vector3f& a) { return a == albedo[0]; });
  if (constant && !albedo.empty()) {
    if ((albedo[0] - listed).cwiseAbs().maxCoeff() > 1e-6f) {
      throw Error(Format(where, ": albedo_rgb (", listed.transpose(), ") differs from the PLY's (",
                         albedo[0].transpose(), ")"));
    }
    return SurfaceAlbedo::Constant(albedo[0]);
  }
  SurfaceAlbedo out;
  out.kind = SurfaceAlbedo::Kind::kPerFace;
  out.values = std::move(albedo);
  return out;
}

// One entry of objects.json: faces [f0, f1) and vertices [v0, v1) of the shared PLY `all`
// (`ply` names it). Adds the number of faces it takes to *covered.
SceneMesh CyclesObject(const json& o, const TriangleMesh& all, const std::string& ply,
                       const std::string& where, size_t* covered) {
  const Eigen::Vector2d fr = JsonVector<2>(o.value("face_range", json()), where + ".face_range");
  const Eigen::Vector2d vr =
      JsonVector<2>(o.value("vertex_range", json()), where + ".vertex_range");
  const int f0 = static_cast<int>(fr[0]), f1 = static_cast<int>(fr[1]);
  const int v0 = static_cast<int>(vr[0]), v1 = static_cast<int>(vr[1]);
  if (f0 < 0 || f1 < f0 || f1 > static_cast<int>(all.faces.size()) || v0 < 0 || v1 < v0 ||
      v1 > static_cast<int>(all.vertices.size())) {
    throw Error(Format(where, ": ranges [", f0, ", ", f1, ") / [", v0, ", ", v1, ") exceed ", ply));
  }
  SceneMesh m;
  m.name = o.value("name", "object");
  m.smooth_shading = o.value("smooth_shaded", false);
  m.mesh.vertices.assign(all.vertices.begin() + v0, all.vertices.begin() + v1);
  if (m.smooth_shading) {
    if (all.normals.empty())
      throw Error(Format(where, ": smooth, but ", ply, " has no vertex normals"));
    m.mesh.normals.assign(all.normals.begin() + v0, all.normals.begin() + v1);
  }
  std::vector<Vector3f> albedo(all.face_colors.begin() + f0, all.face_colors.begin() + f1);
  for (int f = f0; f < f1; ++f) {
    const Eigen::Vector3i local = all.faces[static_cast<size_t>(f)].array() - v0;
    if (local.minCoeff() < 0 || local.maxCoeff() >= v1 - v0) {
      throw Error(Format(where, ": face ", f, " uses a vertex outside its vertex_range"));
    }
    m.mesh.faces.push_back(local);
  }
  m.albedo = CyclesObjectAlbedo(std::move(albedo), o, where);
  *covered += static_cast<size_t>(f1 - f0);
  return m;
}

// geometry/scene.ply split into the objects of geometry/objects.json, which must cover its faces.
void AddCyclesObjects(const fs::path& geometry, Scene* scene) {
  const TriangleMesh all = ReadPly(geometry / "scene.ply");
  const std::string ply = (geometry / "scene.ply").string();
  if (all.face_colors.empty()) throw Error(Format(ply, ": no per-face albedo (albedo_r/g/b)"));
  const fs::path objects_file = geometry / "objects.json";
  const json objects = ParseJsonFile(objects_file);
  size_t covered = 0;
  for (const json& o :
       JsonArray(objects.value("objects", json()), objects_file.string() + ": objects")) {
    const std::string where = Format(objects_file.string(), ": object ", o.value("name", "?"));
    scene->meshes.push_back(CyclesObject(o, all, ply, where, &covered));
  }
  if (covered != all.faces.size()) {
    throw Error(Format(objects_file.string(), ": objects cover ", covered, " of the ",
                       all.faces.size(), " faces of ", ply));
  }
}

// One entry of emitters.json: one-sided quads (two triangles each) with a constant radiance.
SceneMesh CyclesEmitter(const json& e, const std::string& where) {
  if (!e.value("one_sided", false))
    throw Error(Format(where, ": only one-sided emitters are supported"));
  SceneMesh m;
  m.name = e.value("name", "emitter");
  m.albedo = SurfaceAlbedo::Constant(Vector3f::Zero());
  m.emission =
      JsonVector<3>(e.value("radiance_rgb", json()), where + ".radiance_rgb").cast<float>();
  for (const json& f : JsonArray(e.value("faces", json()), where + ".faces")) {
    const json corners = JsonArray(f.value("corners", json()), where + ".corners");
    if (corners.size() != 4) throw Error(Format(where, ": a face needs 4 corners"));
    const int base = static_cast<int>(m.mesh.vertices.size());
    for (const json& c : corners)
      m.mesh.vertices.push_back(JsonVector<3>(c, where + ".corners").cast<float>());
    m.mesh.faces.push_back({base, base + 1, base + 2});
    m.mesh.faces.push_back({base, base + 2, base + 3});
    // Counter-clockwise seen from the emitting side: the winding normal must be `normal`.
    const Vector3d normal = JsonVector<3>(f.value("normal", json()), where + ".normal");
    for (size_t k = m.mesh.faces.size() - 2; k < m.mesh.faces.size(); ++k) {
      if (m.mesh.FaceNormalScaled(k).normalized().cast<double>().dot(normal) < 0.999) {
        throw Error(Format(where, ": corners are not counter-clockwise around normal (",
                           normal.transpose(), ")"));
      }
    }
  }
  return m;
}

Scene LoadCyclesSceneUnguarded(const fs::path& folder) {
  const fs::path geometry = folder / "geometry";
  Scene scene;
  AddCyclesObjects(geometry, &scene);
  const fs::path emitters_file = geometry / "emitters.json";
  const json emitters = ParseJsonFile(emitters_file);
  for (const json& e :
       JsonArray(emitters.value("emitters", json()), emitters_file.string() + ": emitters")) {
    const std::string where = Format(emitters_file.string(), ": emitter ", e.value("name", "?"));
    scene.meshes.push_back(CyclesEmitter(e, where));
  }
  scene.Validate();
  return scene;
}

}  // namespace

Scene LoadCyclesScene(const fs::path& folder) {
  return GuardJson(folder, [&] { return LoadCyclesSceneUnguarded(folder); });
}

}  // namespace genscene::render
