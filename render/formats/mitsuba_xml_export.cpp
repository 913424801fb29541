// Mitsuba 3 XML export (ExportMitsubaXml in mitsuba_xml.h; the import is in mitsuba_xml.cpp, its
// element helpers in mitsuba_xml_elements.cpp).
#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <functional>
#include <iomanip>
#include <map>
#include <numeric>
#include <set>
#include <sstream>
#include <tuple>

#include "core/check.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/parallel.h"
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

// ------------------------------------------------------------------------------------------------
// Sensors.

// The camera a perspective sensor expresses for fx, fy: square pixels of focal length f (its fov)
// seen through the scale diag(sx, sy, 1) of the camera's local axes in to_world (mitsuba_xml.h),
// with sx^2 = 1 + e and sy^2 = 1 - e. The entries of M M^T - I of such a to_world M are at most
// |e|, and Mitsuba refuses any beyond kCameraScaleTolerance: |e| stays below it, with a margin for
// Mitsuba's float arithmetic. A view more anisotropic than that gets the largest anisotropy
// allowed, with the same sqrt(fx fy).
struct SensorCamera {
  double f = 0.0;
  double sx = 1.0, sy = 1.0;
  double fx = 0.0, fy = 0.0;  // what the sensor expresses
};

SensorCamera MitsubaCamera(double fx, double fy) {
  constexpr double kLargest = 0.99 * mitsuba_detail::kCameraScaleTolerance;
  const double rho = fx / fy;
  const double wanted = (1.0 - rho * rho) / (1.0 + rho * rho);  // fx / fy = sy / sx
  const double e = std::clamp(wanted, -kLargest, kLargest);
  SensorCamera c;
  c.sx = std::sqrt(1.0 + e);
  c.sy = std::sqrt(1.0 - e);
  c.fx = fx;
  c.fy = fy;
  if (e != wanted) {
    const double mean = std::sqrt(fx * fy), half_ratio = std::sqrt(c.sy / c.sx);
    c.fx = mean * half_ratio;
    c.fy = mean / half_ratio;
  }
  c.f = c.fx * c.sx;
  return c;
}

void WriteFilm(std::ostream& xml, const CameraIntrinsics& k, const RenderSettings& s) {
  if (s.samples_per_pixel) {
    xml << "    <sampler type=\"independent\"><integer name=\"sample_count\" value=\""
        << *s.samples_per_pixel << "\"/></sampler>\n";
  }
  xml << "    <film type=\"hdrfilm\">\n"
      << "      <integer name=\"width\" value=\"" << k.width << "\"/>\n"
      << "      <integer name=\"height\" value=\"" << k.height << "\"/>\n"
      << "      <string name=\"pixel_format\" value=\"rgb\"/>\n";
  if (!s.pixel_filter || s.pixel_filter->kind == PixelFilter::Kind::kBox)  // our renderer's default
    xml << "      <rfilter type=\"box\"/>\n";
  if (s.pixel_filter && s.pixel_filter->kind == PixelFilter::Kind::kGaussian) {
    xml << "      <rfilter type=\"gaussian\"><float name=\"stddev\" value=\""
        << Num(s.pixel_filter->stddev) << "\"/></rfilter>\n";
  }
  xml << "    </film>\n";
}

void WriteSensor(std::ostream& xml, const PosedView& view, const RenderSettings& s,
                 const std::string& where, std::vector<std::string>* warnings) {
  const CameraIntrinsics& k = view.intrinsics;
  k.Validate(where);
  for (double d : k.distortion) {
    if (d != 0.0)
      throw Error(
          Format(where, ": lens distortion cannot be expressed in Mitsuba's perspective camera"));
  }
  const SensorCamera c = MitsubaCamera(k.fx, k.fy);
  if (c.fx != k.fx || c.fy != k.fy) {
    const double shift =
        std::max(std::abs(c.fx / k.fx - 1.0) * std::max(k.cx + 0.5, k.width - 0.5 - k.cx),
                 std::abs(c.fy / k.fy - 1.0) * std::max(k.cy + 0.5, k.height - 0.5 - k.cy));
    warnings->push_back(Format(where, ": fx / fy = ", k.fx / k.fy,
                               " is beyond what Mitsuba's perspective sensor expresses (it refuses "
                               "scale in the camera's to_world beyond 1e-3); written as fx ",
                               c.fx, ", fy ", c.fy,
                               " (the same sqrt(fx fy)): pixels move by up to ", shift, " px"));
  }
  // The inverse of the import conversion (see mitsuba_xml.h).
  const double ppo_x = (0.5 * (k.width - 1) - k.cx) / k.width,
               ppo_y = (0.5 * (k.height - 1) - k.cy) / k.height;
  const Matrix4d to_world =
      view.world_from_camera.matrix() * Eigen::Vector4d(-c.sx, -c.sy, 1, 1).asDiagonal();
  xml << "  <sensor type=\"perspective\">\n"
      << "    <float name=\"fov\" value=\"" << Num(Degrees(2.0 * std::atan(k.width / (2.0 * c.f))))
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
  WriteFilm(xml, k, s);
  xml << "  </sensor>\n";
}

// The settings' integrator and max_depth, and hide_emitters; nothing for Mitsuba's default.
void WriteIntegrator(std::ostream& xml, const RenderSettings& s, bool hide_emitters) {
  if (!s.integrator && !hide_emitters) return;
  const std::string type = s.integrator.value_or("path");
  xml << "  <integrator type=\"" << Escape(type) << "\">";
  if (s.max_depth && type == "path")
    xml << "<integer name=\"max_depth\" value=\"" << *s.max_depth << "\"/>";
  if (hide_emitters) xml << "<boolean name=\"hide_emitters\" value=\"true\"/>";
  xml << "</integrator>\n";
}

// ------------------------------------------------------------------------------------------------
// Shapes.

// A binary little-endian PLY with the mesh's normals and its vertex or face colours, when it has
// them, as float red/green/blue: Mitsuba 3's PLY loader makes those the vertex_color /
// face_color attribute with the values as they are (linear; integer colours it sRGB-decodes).
void WriteShapePly(const fs::path& path, const TriangleMesh& mesh) {
  const std::string rgb = "property float red\nproperty float green\nproperty float blue\n";
  std::string data =
      "ply\nformat binary_little_endian 1.0\n"
      "comment genscene: linear float colours (Mitsuba 3: vertex_color / face_color)\n";
  data += Format("element vertex ", mesh.vertices.size(),
                 "\nproperty float x\nproperty float y\nproperty float z\n");
  if (!mesh.normals.empty()) data += "property float nx\nproperty float ny\nproperty float nz\n";
  if (!mesh.vertex_colors.empty()) data += rgb;
  data += Format("element face ", mesh.faces.size(), "\nproperty list uchar int vertex_indices\n");
  if (!mesh.face_colors.empty()) data += rgb;
  data += "end_header\n";
  const auto put = [&data](const auto& v) {
    data.append(reinterpret_cast<const char*>(v.data()), sizeof(v[0]) * 3);
  };
  for (size_t v = 0; v < mesh.vertices.size(); ++v) {
    put(mesh.vertices[v]);
    if (!mesh.normals.empty()) put(mesh.normals[v]);
    if (!mesh.vertex_colors.empty()) put(mesh.vertex_colors[v]);
  }
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    data += '\3';
    put(mesh.faces[f]);
    if (!mesh.face_colors.empty()) put(mesh.face_colors[f]);
  }
  WriteTextFileAtomically(path, data);
}

// Albedo fields, baked into the vertex colours of a subdivided mesh. Face f is cut along its
// lattice of resolution R (R^2 triangles with corners at the barycentric points (i/R, j/R)), R the
// smallest power of two at which the colours interpolated between the lattice points match the
// field within kBakeTolerance at the centroids of the 2R lattice's triangles and at every point of
// the face's check lattice: resolution 256 (the finest of Mesh Colors), or the finest that keeps
// the check within kCheckBudget field evaluations on a large mesh. A Mesh Colors field is linear
// on the triangles of its face's lattice, so with the check at that lattice or finer the bake is
// exact (features the check lattice is too coarse to see can be missed). A lattice point on a
// vertex or an edge is one vertex for all the faces around it, placed from the edge's lower-index
// end, so faces of equal R meet without cracks (between different R the finer face's extra edge
// points lie on the coarser face's edge up to rounding, as in MeshColors::ToSubdividedMesh).
constexpr float kBakeTolerance = 1e-4f;  // albedo units, any channel
constexpr int kMaxBakeResolution = 256;  // MeshColors::kMaxResolution
constexpr size_t kMaxBakedTriangles = size_t{1} << 22;
constexpr size_t kCheckBudget = size_t{1} << 27;  // field evaluations, about 2 s

class FieldBaker {
 public:
  explicit FieldBaker(const SceneMesh& m) : m_(m) {}
  TriangleMesh Bake(std::vector<std::string>* warnings);

 private:
  Vector3f Field(int f, int r, int i, int j) const {
    return m_.albedo.Eval(m_.mesh, f, static_cast<float>(static_cast<double>(i) / r),
                          static_cast<float>(static_cast<double>(j) / r));
  }
  // The largest difference between the field and its interpolation on face f's lattice r, at
  // the probes.
  float LatticeError(int f, int r) const;
  // The field at the points of face f's lattice c, row by row.
  std::vector<Vector3f> Sample(int f, int c) const;
  // The resolution of face f (see above) and the largest difference found there.
  std::pair<int, float> Resolution(int f, int check) const;
  // The output vertex of lattice point (i, j) of face f's lattice r.
  int Point(int f, int r, int i, int j);

  const SceneMesh& m_;
  TriangleMesh out_;
  std::map<std::array<int, 5>, int> points_;
  float shared_error_ = 0.0f;  // faces that disagree on the colour of a shared lattice point
};

float FieldBaker::LatticeError(int f, int r) const {
  const auto index = [r](int i, int j) { return static_cast<size_t>(j * (2 * r + 3 - j) / 2 + i); };
  std::vector<Vector3f> corner(static_cast<size_t>((r + 1) * (r + 2) / 2));
  for (int j = 0; j <= r; ++j)
    for (int i = 0; i + j <= r; ++i) corner[index(i, j)] = Field(f, r, i, j);
  float worst = 0.0f;
  // The probes: the centroids of each lattice triangle's four children, as weights of its corners
  // in sixths (points of the face's lattice 6r).
  static constexpr int kWeights[4][3] = {{4, 1, 1}, {1, 4, 1}, {1, 1, 4}, {2, 2, 2}};
  const auto probe = [&](const std::array<std::array<int, 2>, 3>& t) {
    for (const auto& w : kWeights) {
      Vector3f interpolated = Vector3f::Zero();
      int i6 = 0, j6 = 0;
      for (int k = 0; k < 3; ++k) {
        interpolated += w[k] / 6.0f * corner[index(t[k][0], t[k][1])];
        i6 += w[k] * t[k][0];
        j6 += w[k] * t[k][1];
      }
      worst = std::max(worst, (Field(f, 6 * r, i6, j6) - interpolated).cwiseAbs().maxCoeff());
    }
  };
  for (int j = 0; j < r; ++j) {
    for (int i = 0; i + j < r; ++i) {
      probe({{{i, j}, {i + 1, j}, {i, j + 1}}});
      if (i + j + 2 <= r) probe({{{i + 1, j}, {i + 1, j + 1}, {i, j + 1}}});
    }
  }
  return worst;
}

std::vector<Vector3f> FieldBaker::Sample(int f, int c) const {
  std::vector<Vector3f> values;
  values.reserve(static_cast<size_t>((c + 1) * (c + 2) / 2));
  for (int j = 0; j <= c; ++j)
    for (int i = 0; i + j <= c; ++i) values.push_back(Field(f, c, i, j));
  return values;
}

// The largest difference between `values` (at the points of lattice c, row by row) and their
// interpolation from the points of lattice r, r dividing c.
float Difference(const std::vector<Vector3f>& values, int c, int r) {
  const auto at = [&values, c](int i, int j) -> const Vector3f& {
    return values[static_cast<size_t>(j * (2 * c + 3 - j) / 2 + i)];
  };
  const int s = c / r;
  float worst = 0.0f;
  for (int jj = 0; jj <= c; ++jj) {
    for (int ii = 0; ii + jj <= c; ++ii) {
      const int i = ii / s * s, j = jj / s * s, x = ii - i, y = jj - j;
      if (x == 0 && y == 0) continue;  // a point of lattice r itself
      const Vector3f interpolated =
          x + y <= s
              ? ((s - x - y) * at(i, j) + x * at(i + s, j) + y * at(i, j + s)) / s
              : ((s - y) * at(i + s, j) + (x + y - s) * at(i + s, j + s) + (s - x) * at(i, j + s)) /
                    s;
      worst = std::max(worst, (at(ii, jj) - interpolated).cwiseAbs().maxCoeff());
    }
  }
  return worst;
}

std::pair<int, float> FieldBaker::Resolution(int f, int check) const {
  const std::vector<Vector3f> values = check > 1 ? Sample(f, check) : std::vector<Vector3f>();
  for (int r = 1;; r *= 2) {
    float e = LatticeError(f, r);
    if (e <= kBakeTolerance && r < check) e = std::max(e, Difference(values, check, r));
    if (e <= kBakeTolerance || r == kMaxBakeResolution) return {r, e};
  }
}

int FieldBaker::Point(int f, int r, int i, int j) {
  const Eigen::Vector3i& v = m_.mesh.faces[static_cast<size_t>(f)];
  const int w[3] = {r - i - j, i, j};
  std::array<int, 5> key = {2, f, i, j, 0};  // inside the face
  for (int k = 0; k < 3; ++k) {
    if (w[k] == r) key = {0, v[k], 0, 0, 0};                        // on vertex k
    if (w[k] == 0 && w[(k + 1) % 3] != r && w[(k + 2) % 3] != r) {  // on the edge opposite k
      const int a = v[(k + 1) % 3], b = v[(k + 2) % 3];
      const int w_high = a > b ? w[(k + 1) % 3] : w[(k + 2) % 3], g = std::gcd(w_high, r);
      key = {1, std::min(a, b), std::max(a, b), w_high / g, r / g};
    }
  }
  const Vector3f colour = Field(f, r, i, j);
  const auto [it, added] = points_.emplace(key, static_cast<int>(out_.vertices.size()));
  if (!added) {
    const Vector3f& stored = out_.vertex_colors[static_cast<size_t>(it->second)];
    shared_error_ = std::max(shared_error_, (stored - colour).cwiseAbs().maxCoeff());
    return it->second;
  }
  const auto blend = [&](const std::vector<Vector3f>& a) -> Vector3f {
    if (key[0] == 0) return a[static_cast<size_t>(key[1])];
    if (key[0] == 1) {
      const double t = static_cast<double>(key[3]) / key[4];
      const Vector3d low = a[static_cast<size_t>(key[1])].cast<double>();
      return (low + t * (a[static_cast<size_t>(key[2])].cast<double>() - low)).cast<float>();
    }
    Vector3d sum = Vector3d::Zero();
    for (int k = 0; k < 3; ++k) sum += w[k] * a[static_cast<size_t>(v[k])].cast<double>();
    return (sum / r).cast<float>();
  };
  out_.vertices.push_back(blend(m_.mesh.vertices));
  if (m_.smooth_shading) out_.normals.push_back(blend(m_.mesh.normals).normalized());
  out_.vertex_colors.push_back(colour);
  return it->second;
}

TriangleMesh FieldBaker::Bake(std::vector<std::string>* warnings) {
  const int faces = static_cast<int>(m_.mesh.faces.size());
  std::vector<int> resolution(static_cast<size_t>(faces), 1);
  std::vector<float> error(static_cast<size_t>(faces), 0.0f);
  int check = kMaxBakeResolution;
  while (check > 1 &&
         static_cast<size_t>(faces) * static_cast<size_t>((check + 1) * (check + 2) / 2) >
             kCheckBudget)
    check /= 2;
  ParallelFor(
      0, static_cast<size_t>(faces),
      [&](size_t f) { std::tie(resolution[f], error[f]) = Resolution(static_cast<int>(f), check); },
      16);
  size_t triangles = 0;
  for (int r : resolution) triangles += static_cast<size_t>(r) * static_cast<size_t>(r);
  int coarsened = 0;  // over the triangle budget: the finest faces are halved until it fits
  for (int finest = faces ? *std::max_element(resolution.begin(), resolution.end()) : 1;
       triangles > kMaxBakedTriangles && finest > 1; finest /= 2) {
    for (int f = 0; f < faces; ++f) {
      int& r = resolution[static_cast<size_t>(f)];
      if (r != finest) continue;
      r /= 2;
      triangles -= 3 * static_cast<size_t>(r) * static_cast<size_t>(r);
      error[static_cast<size_t>(f)] = LatticeError(f, r);
      ++coarsened;
    }
  }
  for (int f = 0; f < faces; ++f) {
    const int r = resolution[static_cast<size_t>(f)];
    for (int j = 0; j < r; ++j) {
      for (int i = 0; i + j < r; ++i) {
        out_.faces.emplace_back(Point(f, r, i, j), Point(f, r, i + 1, j), Point(f, r, i, j + 1));
        if (i + j + 2 <= r) {
          out_.faces.emplace_back(Point(f, r, i + 1, j), Point(f, r, i + 1, j + 1),
                                  Point(f, r, i, j + 1));
        }
      }
    }
  }
  float worst = shared_error_;
  for (float e : error) worst = std::max(worst, e);
  if (worst > kBakeTolerance) {
    warnings->push_back(
        Format("mesh '", m_.name, "': albedo field baked into ", out_.faces.size(),
               " triangles with vertex colours, which differ from the field by up to ", worst,
               coarsened ? Format(" (", coarsened, " faces coarsened to stay within ",
                                  kMaxBakedTriangles, " triangles)")
                         : std::string()));
  }
  return std::move(out_);
}

// The mesh of one shape with its albedo as colours: none for constant albedo (the BSDF's rgb), the
// face or vertex colours of per-face and per-vertex albedo, an albedo field baked (FieldBaker).
TriangleMesh ShapeMesh(const SceneMesh& m, std::vector<std::string>* warnings) {
  if (m.albedo.kind == SurfaceAlbedo::Kind::kField) return FieldBaker(m).Bake(warnings);
  TriangleMesh out;
  out.vertices = m.mesh.vertices;
  out.faces = m.mesh.faces;
  if (m.smooth_shading) out.normals = m.mesh.normals;
  if (m.albedo.kind == SurfaceAlbedo::Kind::kPerFace) out.face_colors = m.albedo.values;
  if (m.albedo.kind == SurfaceAlbedo::Kind::kPerVertex) out.vertex_colors = m.albedo.values;
  return out;
}

// <shape type=...> with its geometry properties (`body`), a diffuse BSDF with `reflectance` (the
// property element) and an area emitter when it emits.
void WriteShape(std::ostream& xml, const std::string& type, const std::string& id,
                const std::string& body, const std::string& reflectance, const Vector3f& emission) {
  xml << "  <shape type=\"" << type << "\" id=\"" << Escape(id) << "\">\n"
      << body << "    <bsdf type=\"diffuse\">" << reflectance << "</bsdf>\n";
  if (emission.maxCoeff() > 0.0f) {
    xml << "    <emitter type=\"area\"><rgb name=\"radiance\" value=\"" << Rgb(emission)
        << "\"/></emitter>\n";
  }
  xml << "  </shape>\n";
}

std::string RgbReflectance(const Vector3f& albedo) {
  return "<rgb name=\"reflectance\" value=\"" + Rgb(albedo) + "\"/>";
}

// Each mesh as one PLY in <stem>_meshes/ and one shape.
void WriteMeshes(std::ostream& xml, const fs::path& path, const Scene& scene,
                 const std::function<std::string(const std::string&)>& unique_id,
                 std::vector<std::string>* warnings) {
  const std::string folder = path.stem().string() + "_meshes";
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const SceneMesh& m = scene.meshes[i];
    const TriangleMesh shape = ShapeMesh(m, warnings);
    std::string safe;
    for (char c : m.name) safe += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
    std::ostringstream file;
    file << folder << "/" << std::setw(3) << std::setfill('0') << i << "_" << safe.substr(0, 48)
         << ".ply";
    WriteShapePly(path.parent_path() / file.str(), shape);
    std::string body = "    <string name=\"filename\" value=\"" + Escape(file.str()) + "\"/>\n";
    if (!m.smooth_shading) body += "    <boolean name=\"face_normals\" value=\"true\"/>\n";
    const char* attribute = !shape.vertex_colors.empty() ? "vertex_color"
                            : !shape.face_colors.empty() ? "face_color"
                                                         : nullptr;
    const std::string reflectance =
        attribute ? Format(
                        "<texture type=\"mesh_attribute\" name=\"reflectance\"><string "
                        "name=\"name\" value=\"",
                        attribute, "\"/></texture>")
                  : RgbReflectance(m.albedo.constant);
    WriteShape(xml, "ply", unique_id(m.name), body, reflectance, m.emission);
  }
}

}  // namespace

std::vector<std::string> ExportMitsubaXml(const fs::path& path, const Scene& scene,
                                          const std::vector<PosedView>& views,
                                          const RenderSettings& settings) {
  scene.Validate();
  std::vector<std::string> warnings;
  const std::vector<SceneMesh> cube_faces =
      scene.voxel_lights ? VoxelCubeFaces(*scene.voxel_lights) : std::vector<SceneMesh>();
  const bool area_lights = std::any_of(scene.meshes.begin(), scene.meshes.end(),
                                       [](const SceneMesh& m) { return m.IsEmitter(); });
  // Voxel lights are never seen by our camera rays; their cubes are hidden with hide_emitters
  // when no other emitter would be hidden with them (point lights are never hit).
  const bool hide = settings.hide_emitters.value_or(false) || (!cube_faces.empty() && !area_lights);
  if (!cube_faces.empty() && !hide) {
    warnings.push_back(
        "the voxel lights' emitting cube faces are visible to the camera: the scene has area "
        "lights too, which hide_emitters would hide as well");
  }
  std::ostringstream xml;
  xml << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      << "<!-- Written by genscene. OpenCV views converted to Mitsuba's "
         "camera frame. -->\n"
      << "<scene version=\"3.0.0\">\n";
  WriteIntegrator(xml, settings, hide);
  for (size_t i = 0; i < views.size(); ++i)
    WriteSensor(xml, views[i], settings, Format(path.string(), ": view ", i), &warnings);

  std::set<std::string> ids;
  const auto unique_id = [&](const std::string& wanted) {
    const std::string base = wanted.empty() ? "mesh" : wanted;
    std::string id = base;
    for (int n = 2; !ids.insert(id).second; ++n) id = Format(base, "_", n);
    return id;
  };
  WriteMeshes(xml, path, scene, unique_id, &warnings);
  for (const PointLight& p : scene.point_lights) {
    xml << "  <emitter type=\"point\">\n    <point name=\"position\" x=\"" << Num(p.position.x())
        << "\" y=\"" << Num(p.position.y()) << "\" z=\"" << Num(p.position.z()) << "\"/>\n"
        << "    <rgb name=\"intensity\" value=\"" << Rgb(p.intensity) << "\"/>\n  </emitter>\n";
  }
  // Voxel lights: each emitting cube face (a square v0 v1 v2 v3, counter-clockwise from its normal)
  // is Mitsuba's rectangle [-1, 1]^2 mapped by the columns [a, b, n, centre], a = (v1 - v0) / 2,
  // b = (v3 - v0) / 2, n = unit(a x b), so that its +z front becomes the face's front.
  for (const SceneMesh& face : cube_faces) {
    const auto& v = face.mesh.vertices;
    const Vector3d a = (v[1] - v[0]).cast<double>() / 2.0, b = (v[3] - v[0]).cast<double>() / 2.0;
    Matrix3d linear;
    linear << a, b, a.cross(b).normalized();
    const Matrix4d to_world = Affine(linear, (v[0] + v[2]).cast<double>() / 2.0);
    WriteShape(xml, "rectangle", unique_id(face.name),
               "    <transform name=\"to_world\"><matrix value=\"" + RowMajor(to_world) +
                   "\"/></transform>\n",
               RgbReflectance(face.albedo.constant), face.emission);
  }
  // The distant light: an envmap beside the XML (EnvmapDirection; world = local frame).
  if (scene.voxel_lights && scene.voxel_lights->HasDistantLight()) {
    const VoxelLightGrid& grid = *scene.voxel_lights;
    ImageRgb env(mitsuba_detail::kEnvmapWidth, mitsuba_detail::kEnvmapHeight);
    for (int j = 0; j < env.height(); ++j) {
      for (int i = 0; i < env.width(); ++i) {
        const Vector3d d = mitsuba_detail::EnvmapDirection(i, j, env.width(), env.height());
        env(i, j) = grid.DistantRadiance(d.cast<float>());
      }
    }
    const fs::path exr = path.parent_path() / (path.stem().string() + "_distant.exr");
    WriteExr(exr, env);
    xml << "  <emitter type=\"envmap\">\n    <string name=\"filename\" value=\""
        << exr.filename().string() << "\"/>\n  </emitter>\n";
  }
  xml << "</scene>\n";
  WriteTextFileAtomically(path, xml.str());
  return warnings;
}

}  // namespace genscene::render
