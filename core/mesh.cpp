#include "core/mesh.h"

#include <cmath>
#include <map>

#include "core/check.h"

namespace genscene {

void TriangleMesh::Validate(const std::string& source) const {
  const size_t nv = vertices.size();
  auto check_size = [&](size_t size, size_t expected, const char* what, const char* per) {
    if (size != 0 && size != expected) {
      throw Error(Format(source, ": ", size, " ", what, " for ", expected, " ", per));
    }
  };
  check_size(normals.size(), nv, "normals", "vertices");
  check_size(vertex_colors.size(), nv, "vertex colours", "vertices");
  check_size(face_colors.size(), faces.size(), "face colours", "faces");
  for (size_t i = 0; i < nv; ++i) {
    if (!vertices[i].allFinite()) throw Error(Format(source, ": vertex ", i, " is not finite"));
  }
  for (size_t i = 0; i < normals.size(); ++i) {
    if (!normals[i].allFinite()) throw Error(Format(source, ": normal ", i, " is not finite"));
  }
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int index = faces[f][k];
      if (index < 0 || static_cast<size_t>(index) >= nv) {
        throw Error(Format(source, ": face ", f, " uses vertex ", index, " but the mesh has ", nv,
                           " vertices"));
      }
    }
  }
}

Eigen::AlignedBox3f TriangleMesh::Bounds() const {
  Eigen::AlignedBox3f box;
  for (const auto& v : vertices) box.extend(v);
  return box;
}

Eigen::Vector3f TriangleMesh::FaceNormalScaled(size_t f) const {
  const Eigen::Vector3i& t = faces[f];
  return (vertices[t[1]] - vertices[t[0]]).cross(vertices[t[2]] - vertices[t[0]]);
}

void TriangleMesh::ComputeVertexNormals() {
  normals.assign(vertices.size(), Eigen::Vector3f::Zero());
  // |n_f| = 2 area, so summing unnormalised face normals weights each face by its area.
  for (size_t f = 0; f < faces.size(); ++f) {
    const Eigen::Vector3f n = FaceNormalScaled(f);
    for (int k = 0; k < 3; ++k) normals[faces[f][k]] += n;
  }
  for (auto& n : normals) {
    const float length = n.norm();
    if (length > 0.0f) n /= length;
  }
}

UnitIcosphere MakeUnitIcosphere(int level) {
  GS_CHECK(level >= 0 && level <= 10);
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  UnitIcosphere s;
  auto& v = s.vertices;
  v = {{-1, g, 0},  {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
       {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
  for (Eigen::Vector3d& p : v) p.normalize();
  s.faces = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
             {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (Eigen::Vector3i& f : s.faces) {  // fronts outward, whatever the list's winding
    if ((v[f[1]] - v[f[0]]).cross(v[f[2]] - v[f[0]]).dot(v[f[0]]) < 0.0) std::swap(f[1], f[2]);
  }
  for (int l = 0; l < level; ++l) {
    // Each edge's midpoint, pushed onto the sphere, is made once and shared by both faces.
    std::map<std::pair<int, int>, int> midpoints;
    const auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoints.find(key);
      if (it != midpoints.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      return midpoints[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<Eigen::Vector3i> next;
    for (const Eigen::Vector3i& f : s.faces) {
      const int ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
      next.insert(next.end(), {{f[0], ab, ca}, {ab, f[1], bc}, {ca, bc, f[2]}, {ab, bc, ca}});
    }
    s.faces = std::move(next);
  }
  return s;
}

}  // namespace genscene
