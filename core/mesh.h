// Indexed triangle mesh with shared vertices: the hand-over type between meshing, texturing and
// the inverse stages. Colours are LINEAR RGB in [0, 1].
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace genscene {

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;       // world frame, meters
  std::vector<Eigen::Vector3f> normals;        // empty, or one unit normal per vertex
  std::vector<Eigen::Vector3f> vertex_colors;  // empty, or one linear RGB per vertex
  std::vector<Eigen::Vector3i> faces;  // vertex indices, counter-clockwise seen from the front
  std::vector<Eigen::Vector3f> face_colors;  // empty, or one linear RGB per face (e.g. albedo)

  bool empty() const { return faces.empty(); }

  // Throws Error naming `source` when an index is out of range, a per-element array has the wrong
  // length, or a position/normal/colour is not finite.
  void Validate(const std::string& source) const;

  Eigen::AlignedBox3f Bounds() const;

  // Face normal (unnormalised, length = 2 x area) of face f.
  Eigen::Vector3f FaceNormalScaled(size_t f) const;

  // Vertex normals as the area-weighted average of incident face normals (the paper's definition,
  // section IV). Vertices without faces get (0, 0, 0).
  void ComputeVertexNormals();
};

// The unit sphere as a geodesic icosphere: the icosahedron subdivided `level` times (20 * 4^level
// triangles), vertices on the sphere in double precision, faces counter-clockwise seen from
// outside.
struct UnitIcosphere {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
};
UnitIcosphere MakeUnitIcosphere(int level);

}  // namespace genscene
