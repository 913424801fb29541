// Mesh sources shared by the scene loaders (conventions of ../shared/MITSUBA-XML.md §7): the
// Wavefront OBJ reader, Mitsuba's analytic shapes as meshes, transforms and Mitsuba's vertex
// normals.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <vector>

#include "core/mesh.h"

namespace genscene::render {

// A Wavefront OBJ as Mitsuba reads it: `v`, `vt`, `vn`, `f` (corners v, v/vt, v//vn, v/vt/vn,
// 1-based, positive); polygons fan-triangulated about their first corner; one vertex per distinct
// (v, vt, vn) triple in order of first use (unused `v` lines are not part of the mesh); vertex
// normals from `vn` when every corner has one. Other line types are ignored. Throws Error naming
// the file and line (bad number, non-finite value, index out of range, mixed corner forms).
TriangleMesh ReadObj(const std::filesystem::path& path);

// Mitsuba's `rectangle`: the square [-1, 1]^2 at z = 0, front (counter-clockwise side) +z.
TriangleMesh RectangleMesh();
// Mitsuba's `cube`: [-1, 1]^3 as 24 vertices / 12 triangles, fronts outward, one normal per face.
TriangleMesh CubeMesh();
// The unit sphere mapped by `to_world` (rotation, uniform scale, translation; anything else is an
// Error) as a geodesic icosphere of 20 * 4^level triangles, fronts outward, with exact radial
// vertex normals.
TriangleMesh SphereMesh(const Eigen::Matrix4d& to_world, int level);

// Applies an affine `to_world` to the positions and (inverse-transpose, renormalised) normals.
void TransformMesh(const Eigen::Matrix4d& to_world, TriangleMesh* mesh);
// Vertex normals as Mitsuba computes them: the sum of adjacent face normals weighted by the
// corner angle (Thuermer & Wuethrich 1998), normalised; zero-area faces do not contribute.
std::vector<Eigen::Vector3f> AngleWeightedNormals(const TriangleMesh& mesh);
int CountDegenerateFaces(const TriangleMesh& mesh);

}  // namespace genscene::render
