// Scene files: our JSON format, the cbox-cycles loader, LoadScene, and the mesh sources the
// loaders share (OBJ, Mitsuba's primitives, normals). The formats are documented in scene_io.h.
#include "inverse/scene_io.h"

#include <algorithm>
#include <limits>
#include <array>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/check.h"
#include "core/file_util.h"
#include "core/json_util.h"
#include "core/ply_io.h"
#include "core/se3.h"
#include "inverse/mitsuba_xml.h"

namespace genscene::inverse {

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

View ParseCamera(const json& j, const std::string& where) {
  CheckKeys(j, {"intrinsics", "pose"}, where);
  if (!j.contains("intrinsics") || !j["intrinsics"].is_string() || !j.contains("pose") ||
      !j["pose"].is_string()) {
    throw Error(Format(where, ": needs \"intrinsics\" and \"pose\" strings"));
  }
  View view;
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

json CameraToJson(const View& view) {
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
  if (j.contains("name") && !j["name"].is_string()) throw Error(Format(where, ".name: expected a string, got ", j["name"].dump()));
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

// ------------------------------------------------------------------------------------------------
// Geometry helpers.

bool IsDegenerate(const Vector3f& a, const Vector3f& b, const Vector3f& c) {
  const float scale =
      std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
  return !((b - a).cross(c - a).norm() > 1e-7f * scale);
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

void SaveSceneJson(const fs::path& path, const Scene& scene, const std::vector<View>& views,
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
    for (const View& v : views) cameras.push_back(CameraToJson(v));
    j["cameras"] = cameras;
  }
  const json render = RenderToJson(settings);
  if (!render.empty()) j["render"] = render;
  WriteTextFileAtomically(path, j.dump(2) + "\n");
}

namespace {

Scene LoadCyclesSceneUnguarded(const fs::path& folder) {
  const fs::path geometry = folder / "geometry";
  const TriangleMesh all = ReadPly(geometry / "scene.ply");
  const std::string ply = (geometry / "scene.ply").string();
  if (all.face_colors.empty()) throw Error(Format(ply, ": no per-face albedo (albedo_r/g/b)"));
  Scene scene;
  const fs::path objects_file = geometry / "objects.json";
  const json objects = ParseJsonFile(objects_file);
  size_t covered = 0;
  for (const json& o :
       JsonArray(objects.value("objects", json()), objects_file.string() + ": objects")) {
    const std::string where = Format(objects_file.string(), ": object ", o.value("name", "?"));
    const Eigen::Vector2d fr = JsonVector<2>(o.value("face_range", json()), where + ".face_range");
    const Eigen::Vector2d vr =
        JsonVector<2>(o.value("vertex_range", json()), where + ".vertex_range");
    const int f0 = static_cast<int>(fr[0]), f1 = static_cast<int>(fr[1]);
    const int v0 = static_cast<int>(vr[0]), v1 = static_cast<int>(vr[1]);
    if (f0 < 0 || f1 < f0 || f1 > static_cast<int>(all.faces.size()) || v0 < 0 || v1 < v0 ||
        v1 > static_cast<int>(all.vertices.size())) {
      throw Error(
          Format(where, ": ranges [", f0, ", ", f1, ") / [", v0, ", ", v1, ") exceed ", ply));
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
    const Vector3f listed =
        JsonVector<3>(o.value("albedo_rgb", json()), where + ".albedo_rgb").cast<float>();
    const bool constant = std::all_of(albedo.begin(), albedo.end(),
                                      [&](const Vector3f& a) { return a == albedo[0]; });
    if (constant && !albedo.empty()) {
      if ((albedo[0] - listed).cwiseAbs().maxCoeff() > 1e-6f) {
        throw Error(Format(where, ": albedo_rgb (", listed.transpose(),
                           ") differs from the PLY's (", albedo[0].transpose(), ")"));
      }
      m.albedo = SurfaceAlbedo::Constant(albedo[0]);
    } else {
      m.albedo.kind = SurfaceAlbedo::Kind::kPerFace;
      m.albedo.values = albedo;
    }
    covered += static_cast<size_t>(f1 - f0);
    scene.meshes.push_back(std::move(m));
  }
  if (covered != all.faces.size()) {
    throw Error(Format(objects_file.string(), ": objects cover ", covered, " of the ",
                       all.faces.size(), " faces of ", ply));
  }
  const fs::path emitters_file = geometry / "emitters.json";
  const json emitters = ParseJsonFile(emitters_file);
  for (const json& e :
       JsonArray(emitters.value("emitters", json()), emitters_file.string() + ": emitters")) {
    const std::string where = Format(emitters_file.string(), ": emitter ", e.value("name", "?"));
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
    scene.meshes.push_back(std::move(m));
  }
  scene.Validate();
  return scene;
}

}  // namespace

Scene LoadCyclesScene(const fs::path& folder) {
  return GuardJson(folder, [&] { return LoadCyclesSceneUnguarded(folder); });
}

// ------------------------------------------------------------------------------------------------
// Mesh sources.

TriangleMesh ReadObj(const fs::path& path) {
  const std::string name = path.string();
  if (!fs::is_regular_file(path)) throw Error(Format(name, ": file not found"));
  const std::string text = ReadTextFile(path);
  std::vector<Vector3f> positions, normals;
  size_t texcoords = 0;
  struct Polygon {
    std::vector<std::array<int, 3>> corners;  // 1-based v, vt, vn; 0 = absent
    int line;
  };
  std::vector<Polygon> polygons;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    const std::string where = Format(name, ":", number);
    const std::vector<std::string> t = SplitWhitespace(line);
    if (t.empty()) continue;
    const auto vec3 = [&]() -> Vector3f {
      if (t.size() < 4) throw Error(Format(where, ": '", t[0], "' needs 3 numbers"));
      const Vector3d v(ParseDouble(t[1], where), ParseDouble(t[2], where),
                       ParseDouble(t[3], where));
      if (!v.allFinite()) throw Error(Format(where, ": '", line, "' is not finite"));
      return v.cast<float>();
    };
    if (t[0] == "v") {
      positions.push_back(vec3());
    } else if (t[0] == "vn") {
      normals.push_back(vec3());
    } else if (t[0] == "vt") {
      ++texcoords;
    } else if (t[0] == "f") {
      if (t.size() < 4) throw Error(Format(where, ": a face needs at least 3 corners"));
      Polygon p{{}, number};
      for (size_t i = 1; i < t.size(); ++i) {
        std::array<int, 3> c{0, 0, 0};
        size_t start = 0;
        for (int k = 0; k < 3 && start <= t[i].size(); ++k) {
          const size_t slash = std::min(t[i].find('/', start), t[i].size());
          if (slash > start)
            c[static_cast<size_t>(k)] =
                ParseInt32(t[i].substr(start, slash - start), where);
          start = slash + 1;
        }
        if (c[0] < 1 || c[1] < 0 || c[2] < 0)
          throw Error(Format(where, ": corner '", t[i], "' (only positive 1-based indices)"));
        p.corners.push_back(c);
      }
      polygons.push_back(std::move(p));
    }
  }
  TriangleMesh mesh;
  std::map<std::array<int, 3>, int> vertex_of;
  bool with_normals = false;
  for (const Polygon& p : polygons) {
    std::vector<int> ids;
    for (const auto& c : p.corners) {
      if (c[0] > static_cast<int>(positions.size()) || c[1] > static_cast<int>(texcoords) ||
          c[2] > static_cast<int>(normals.size())) {
        throw Error(Format(name, ":", p.line, ": index out of range (", positions.size(), " v, ",
                           texcoords, " vt, ", normals.size(), " vn)"));
      }
      if (&p == &polygons.front() && &c == &p.corners.front()) with_normals = c[2] > 0;
      if ((c[2] > 0) != with_normals)
        throw Error(Format(name, ":", p.line, ": some corners have normals and some not"));
      auto [it, added] = vertex_of.emplace(c, static_cast<int>(mesh.vertices.size()));
      if (added) {
        mesh.vertices.push_back(positions[static_cast<size_t>(c[0] - 1)]);
        if (with_normals)
          mesh.normals.push_back(normals[static_cast<size_t>(c[2] - 1)].normalized());
      }
      ids.push_back(it->second);
    }
    for (size_t k = 1; k + 1 < ids.size(); ++k) mesh.faces.emplace_back(ids[0], ids[k], ids[k + 1]);
  }
  mesh.Validate(name);
  return mesh;
}

TriangleMesh RectangleMesh() {
  TriangleMesh m;
  m.vertices = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

TriangleMesh CubeMesh() {
  TriangleMesh m;
  for (int k = 0; k < 6; ++k) {
    const Vector3d n = VoxelLightGrid::Directions()[static_cast<size_t>(k)];
    const Vector3d t1 = VoxelLightGrid::Directions()[static_cast<size_t>((k / 2 * 2 + 2) % 6)];
    const Vector3d t2 = n.cross(t1);  // t1 x t2 = n: the corners below are counter-clockwise from n
    const int base = static_cast<int>(m.vertices.size());
    for (const auto& [a, b] :
         {std::pair{-1, -1}, std::pair{1, -1}, std::pair{1, 1}, std::pair{-1, 1}}) {
      m.vertices.push_back((n + a * t1 + b * t2).cast<float>());
    }
    m.faces.insert(m.faces.end(), {{base, base + 1, base + 2}, {base, base + 2, base + 3}});
  }
  return m;
}

TriangleMesh SphereMesh(const Matrix4d& to_world, int level) {
  const Matrix3d linear = to_world.topLeftCorner<3, 3>();
  const double scale = std::cbrt(std::abs(linear.determinant()));
  if (!(scale > 0.0) ||
      !(linear.transpose() * linear).isApprox(scale * scale * Matrix3d::Identity(), 1e-5)) {
    throw Error(
        "a sphere's to_world may only rotate, scale uniformly and translate (Mitsuba would "
        "ignore the rest and render a sphere anyway)");
  }
  UnitIcosphere sphere = MakeUnitIcosphere(level);
  std::vector<Eigen::Vector3i>& faces = sphere.faces;
  TriangleMesh m;
  for (const Vector3d& u : sphere.vertices) {
    m.vertices.push_back((linear * u + to_world.topRightCorner<3, 1>()).cast<float>());
    m.normals.push_back((linear * u).normalized().cast<float>());  // outward, even when mirrored
  }
  if (linear.determinant() < 0.0) {
    for (Eigen::Vector3i& f : faces) std::swap(f[1], f[2]);
  }
  m.faces = std::move(faces);
  return m;
}

void TransformMesh(const Matrix4d& to_world, TriangleMesh* mesh) {
  const Matrix3d linear = to_world.topLeftCorner<3, 3>();
  const Matrix3d normal_matrix = linear.inverse().transpose();
  for (Vector3f& v : mesh->vertices) {
    v = (linear * v.cast<double>() + to_world.topRightCorner<3, 1>()).cast<float>();
  }
  for (Vector3f& n : mesh->normals)
    n = (normal_matrix * n.cast<double>()).normalized().cast<float>();
}

std::vector<Vector3f> AngleWeightedNormals(const TriangleMesh& mesh) {
  std::vector<Vector3d> sum(mesh.vertices.size(), Vector3d::Zero());
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Vector3f& a = mesh.vertices[f[0]];
    const Vector3f& b = mesh.vertices[f[1]];
    const Vector3f& c = mesh.vertices[f[2]];
    if (IsDegenerate(a, b, c)) continue;
    const Vector3d n = (b - a).cross(c - a).cast<double>().normalized();
    for (int k = 0; k < 3; ++k) {
      const Vector3d p = mesh.vertices[f[k]].cast<double>();
      const Vector3d e1 = (mesh.vertices[f[(k + 1) % 3]].cast<double>() - p).normalized();
      const Vector3d e2 = (mesh.vertices[f[(k + 2) % 3]].cast<double>() - p).normalized();
      sum[static_cast<size_t>(f[k])] += n * std::acos(std::clamp(e1.dot(e2), -1.0, 1.0));
    }
  }
  std::vector<Vector3f> normals;
  for (const Vector3d& s : sum)
    normals.push_back(s.norm() > 0.0 ? Vector3f(s.normalized().cast<float>()) : Vector3f::Zero());
  return normals;
}

int CountDegenerateFaces(const TriangleMesh& mesh) {
  int count = 0;
  for (const Eigen::Vector3i& f : mesh.faces) {
    count += IsDegenerate(mesh.vertices[f[0]], mesh.vertices[f[1]], mesh.vertices[f[2]]) ? 1 : 0;
  }
  return count;
}

}  // namespace genscene::inverse
