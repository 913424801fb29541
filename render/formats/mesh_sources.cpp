#include "render/formats/mesh_sources.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "core/check.h"
#include "core/file_util.h"
#include "core/light_set.h"

namespace genscene::render {

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Matrix4d;
using Eigen::Vector3d;
using Eigen::Vector3f;

namespace {

bool IsDegenerate(const Vector3f& a, const Vector3f& b, const Vector3f& c) {
  const float scale =
      std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
  return !((b - a).cross(c - a).norm() > 1e-7f * scale);
}

}  // namespace

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
            c[static_cast<size_t>(k)] = ParseInt32(t[i].substr(start, slash - start), where);
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

}  // namespace genscene::render
