// Mitsuba 3 XML export (ExportMitsubaXml in mitsuba_xml.h; the import is in mitsuba_xml.cpp, its
// element helpers in mitsuba_xml_elements.cpp).
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>

#include "core/check.h"
#include "core/file_util.h"
#include "core/ply_io.h"
#include "render/formats/mitsuba_xml.h"
#include "render/formats/mitsuba_xml_internal.h"

namespace genscene::render {

namespace {

using mitsuba_detail::Affine;
using mitsuba_detail::Degrees;
namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Matrix4d;
using Eigen::Vector3d;
using Eigen::Vector3f;

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    out += c == '&'   ? "&amp;"
           : c == '<' ? "&lt;"
           : c == '>' ? "&gt;"
           : c == '"' ? "&quot;"
                      : std::string(1, c);
  }
  return out;
}

// Shortest text that reads back to the same value (doubles, and floats as floats).
template <typename T>
std::string Num(T v) {
  char text[64];
  return std::string(text, std::to_chars(text, text + sizeof(text), v).ptr);
}
std::string Rgb(const Vector3f& c) {
  return Num(c.x()) + ", " + Num(c.y()) + ", " + Num(c.z());
}
std::string RowMajor(const Matrix4d& m) {
  std::string out;
  for (int i = 0; i < 16; ++i) out += (i ? " " : "") + Num(m(i / 4, i % 4));
  return out;
}

void WriteSensor(std::ostream& xml, const PosedView& view, const RenderSettings& s,
                 const std::string& where) {
  const CameraIntrinsics& k = view.intrinsics;
  k.Validate(where);
  if (std::abs(k.fx - k.fy) > 1e-9 * k.fx) {
    throw Error(Format(where, ": fx ", k.fx, " != fy ", k.fy,
                       "; Mitsuba's perspective camera has square pixels"));
  }
  for (double d : k.distortion) {
    if (d != 0.0)
      throw Error(
          Format(where, ": lens distortion cannot be expressed in Mitsuba's perspective camera"));
  }
  // The inverse of the import conversion (see mitsuba_xml.h).
  const double ppo_x = (0.5 * (k.width - 1) - k.cx) / k.width,
               ppo_y = (0.5 * (k.height - 1) - k.cy) / k.height;
  const Matrix4d to_world =
      view.world_from_camera.matrix() * Eigen::Vector4d(-1, -1, 1, 1).asDiagonal();
  xml << "  <sensor type=\"perspective\">\n"
      << "    <float name=\"fov\" value=\"" << Num(Degrees(2.0 * std::atan(k.width / (2.0 * k.fx))))
      << "\"/>\n"
      << "    <string name=\"fov_axis\" value=\"x\"/>\n";
  if (ppo_x != 0.0)
    xml << "    <float name=\"principal_point_offset_x\" value=\"" << Num(ppo_x) << "\"/>\n";
  if (ppo_y != 0.0)
    xml << "    <float name=\"principal_point_offset_y\" value=\"" << Num(ppo_y) << "\"/>\n";
  if (s.near_clip) xml << "    <float name=\"near_clip\" value=\"" << Num(*s.near_clip) << "\"/>\n";
  if (s.far_clip) xml << "    <float name=\"far_clip\" value=\"" << Num(*s.far_clip) << "\"/>\n";
  xml << "    <transform name=\"to_world\"><matrix value=\"" << RowMajor(to_world)
      << "\"/></transform>\n";
  if (s.samples_per_pixel) {
    xml << "    <sampler type=\"independent\"><integer name=\"sample_count\" value=\""
        << *s.samples_per_pixel << "\"/></sampler>\n";
  }
  xml << "    <film type=\"hdrfilm\">\n"
      << "      <integer name=\"width\" value=\"" << k.width << "\"/>\n"
      << "      <integer name=\"height\" value=\"" << k.height << "\"/>\n"
      << "      <string name=\"pixel_format\" value=\"rgb\"/>\n";
  if (s.pixel_filter && s.pixel_filter->kind == PixelFilter::Kind::kBox)
    xml << "      <rfilter type=\"box\"/>\n";
  if (s.pixel_filter && s.pixel_filter->kind == PixelFilter::Kind::kGaussian) {
    xml << "      <rfilter type=\"gaussian\"><float name=\"stddev\" value=\""
        << Num(s.pixel_filter->stddev) << "\"/></rfilter>\n";
  }
  xml << "    </film>\n  </sensor>\n";
}

// <shape type=...> with its geometry properties (`body`), a diffuse BSDF and an area emitter.
void WriteShape(std::ostream& xml, const std::string& type, const std::string& id,
                const std::string& body, const Vector3f& albedo, const Vector3f& emission) {
  xml << "  <shape type=\"" << type << "\" id=\"" << Escape(id) << "\">\n"
      << body << "    <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"" << Rgb(albedo)
      << "\"/></bsdf>\n";
  if (emission.maxCoeff() > 0.0f) {
    xml << "    <emitter type=\"area\"><rgb name=\"radiance\" value=\"" << Rgb(emission)
        << "\"/></emitter>\n";
  }
  xml << "  </shape>\n";
}

// The albedo of each face, grouped by value in order of first appearance.
std::vector<std::pair<Vector3f, std::vector<int>>> AlbedoGroups(
    const SceneMesh& m, std::vector<std::string>* warnings) {
  std::vector<std::pair<Vector3f, std::vector<int>>> groups;
  std::map<std::array<float, 3>, size_t> index;
  const bool exact = m.albedo.kind == SurfaceAlbedo::Kind::kConstant ||
                     m.albedo.kind == SurfaceAlbedo::Kind::kPerFace;
  if (!exact) {
    warnings->push_back(
        Format("mesh '", m.name,
               "': per-vertex albedo / albedo field exported as one value "
               "per face (the centroid's): plain Mitsuba diffuse cannot vary within a face"));
  }
  for (int f = 0; f < static_cast<int>(m.mesh.faces.size()); ++f) {
    const Vector3f a = m.albedo.Eval(m.mesh, f, 1.0f / 3.0f, 1.0f / 3.0f);
    auto [it, added] = index.emplace(std::array<float, 3>{a.x(), a.y(), a.z()}, groups.size());
    if (added) groups.push_back({a, {}});
    groups[it->second].second.push_back(f);
  }
  return groups;
}

TriangleMesh Submesh(const TriangleMesh& mesh, const std::vector<int>& faces) {
  std::vector<int> new_index(mesh.vertices.size(), -1);
  for (int f : faces)
    for (int k = 0; k < 3; ++k)
      new_index[static_cast<size_t>(mesh.faces[static_cast<size_t>(f)][k])] = 0;
  TriangleMesh out;
  for (size_t v = 0; v < mesh.vertices.size(); ++v) {
    if (new_index[v] < 0) continue;
    new_index[v] = static_cast<int>(out.vertices.size());
    out.vertices.push_back(mesh.vertices[v]);
    if (!mesh.normals.empty()) out.normals.push_back(mesh.normals[v]);
  }
  for (int f : faces) {
    const Eigen::Vector3i& t = mesh.faces[static_cast<size_t>(f)];
    out.faces.emplace_back(new_index[static_cast<size_t>(t[0])],
                           new_index[static_cast<size_t>(t[1])],
                           new_index[static_cast<size_t>(t[2])]);
  }
  return out;
}

}  // namespace

std::vector<std::string> ExportMitsubaXml(const fs::path& path, const Scene& scene,
                                          const std::vector<PosedView>& views,
                                          const RenderSettings& settings) {
  scene.Validate();
  std::vector<std::string> warnings;
  std::ostringstream xml;
  xml << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      << "<!-- Written by genscene. OpenCV views converted to Mitsuba's "
         "camera frame. -->\n"
      << "<scene version=\"3.0.0\">\n";
  if (settings.integrator) {
    xml << "  <integrator type=\"" << Escape(*settings.integrator) << "\">";
    if (settings.max_depth && *settings.integrator == "path") {
      xml << "<integer name=\"max_depth\" value=\"" << *settings.max_depth << "\"/>";
    }
    xml << "</integrator>\n";
  }
  for (size_t i = 0; i < views.size(); ++i)
    WriteSensor(xml, views[i], settings, Format(path.string(), ": view ", i));

  // Meshes: one PLY per shape in <stem>_meshes/, split by albedo value when it varies per face.
  const std::string folder = path.stem().string() + "_meshes";
  std::set<std::string> ids;
  const auto unique_id = [&](const std::string& wanted) {
    const std::string base = wanted.empty() ? "mesh" : wanted;
    std::string id = base;
    for (int n = 2; !ids.insert(id).second; ++n) id = Format(base, "_", n);
    return id;
  };
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const SceneMesh& m = scene.meshes[i];
    const auto groups = AlbedoGroups(m, &warnings);
    for (size_t g = 0; g < groups.size(); ++g) {
      TriangleMesh piece = groups.size() == 1 ? m.mesh : Submesh(m.mesh, groups[g].second);
      piece.face_colors.clear();
      piece.vertex_colors.clear();
      if (!m.smooth_shading) piece.normals.clear();
      std::string safe;
      for (char c : m.name) safe += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
      std::ostringstream file;
      file << folder << "/" << std::setw(3) << std::setfill('0') << i << "_" << safe.substr(0, 48);
      if (groups.size() > 1) file << "_albedo" << g;
      file << ".ply";
      WritePly(path.parent_path() / file.str(), piece);
      std::string body = "    <string name=\"filename\" value=\"" + Escape(file.str()) + "\"/>\n";
      if (!m.smooth_shading) body += "    <boolean name=\"face_normals\" value=\"true\"/>\n";
      WriteShape(xml, "ply", unique_id(groups.size() > 1 ? Format(m.name, "__albedo", g) : m.name),
                 body, groups[g].first, m.emission);
    }
  }
  for (const PointLight& p : scene.point_lights) {
    xml << "  <emitter type=\"point\">\n    <point name=\"position\" x=\"" << Num(p.position.x())
        << "\" y=\"" << Num(p.position.y()) << "\" z=\"" << Num(p.position.z()) << "\"/>\n"
        << "    <rgb name=\"intensity\" value=\"" << Rgb(p.intensity) << "\"/>\n  </emitter>\n";
  }
  // Voxel lights: each emitting cube face (a square v0 v1 v2 v3, counter-clockwise from its normal)
  // is Mitsuba's rectangle [-1, 1]^2 mapped by the columns [a, b, n, centre], a = (v1 - v0) / 2,
  // b = (v3 - v0) / 2, n = unit(a x b), so that its +z front becomes the face's front.
  if (scene.voxel_lights) {
    for (const SceneMesh& face : VoxelCubeFaces(*scene.voxel_lights)) {
      const auto& v = face.mesh.vertices;
      const Vector3d a = (v[1] - v[0]).cast<double>() / 2.0, b = (v[3] - v[0]).cast<double>() / 2.0;
      Matrix3d linear;
      linear << a, b, a.cross(b).normalized();
      const Matrix4d to_world = Affine(linear, (v[0] + v[2]).cast<double>() / 2.0);
      WriteShape(xml, "rectangle", unique_id(face.name),
                 "    <transform name=\"to_world\"><matrix value=\"" + RowMajor(to_world) +
                     "\"/></transform>\n",
                 face.albedo.constant, face.emission);
    }
  }
  xml << "</scene>\n";
  WriteTextFileAtomically(path, xml.str());
  return warnings;
}

}  // namespace genscene::render
