#include "core/mesh.h"

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

}  // namespace genscene
