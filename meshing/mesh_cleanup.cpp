#include "meshing/mesh_cleanup.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModHausdorffT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>
#include <numeric>

#include "core/check.h"
#include "core/disjoint_sets.h"

namespace genscene::meshing {

namespace {

// Keeps the faces with keep[f] and the vertices they use, in their original order.
void KeepFaces(TriangleMesh* mesh, const std::vector<bool>& keep) {
  std::vector<int> new_index(mesh->vertices.size(), -1);
  std::vector<Eigen::Vector3i> faces;
  for (size_t f = 0; f < mesh->faces.size(); ++f) {
    if (!keep[f]) continue;
    faces.push_back(mesh->faces[f]);
    for (int j = 0; j < 3; ++j) new_index[mesh->faces[f][j]] = 0;
  }
  TriangleMesh out;
  for (size_t v = 0; v < mesh->vertices.size(); ++v) {
    if (new_index[v] < 0) continue;
    new_index[v] = static_cast<int>(out.vertices.size());
    out.vertices.push_back(mesh->vertices[v]);
    if (!mesh->normals.empty()) out.normals.push_back(mesh->normals[v]);
    if (!mesh->vertex_colors.empty()) out.vertex_colors.push_back(mesh->vertex_colors[v]);
  }
  for (size_t f = 0; f < mesh->faces.size(); ++f) {
    if (keep[f] && !mesh->face_colors.empty()) out.face_colors.push_back(mesh->face_colors[f]);
  }
  for (Eigen::Vector3i& face : faces) {
    for (int j = 0; j < 3; ++j) face[j] = new_index[face[j]];
  }
  out.faces = std::move(faces);
  *mesh = std::move(out);
}

struct DecimationTraits : public OpenMesh::DefaultTraits {
  typedef OpenMesh::Vec3d Point;
  typedef OpenMesh::Vec3d Normal;
};
using OmMesh = OpenMesh::TriMesh_ArrayKernelT<DecimationTraits>;

}  // namespace

ComponentRemoval RemoveSmallComponents(TriangleMesh* mesh, int min_triangles) {
  GS_CHECK_GE(min_triangles, 0);
  DisjointSets sets(mesh->vertices.size());
  for (const Eigen::Vector3i& face : mesh->faces) {
    sets.Union(face[0], face[1]);
    sets.Union(face[0], face[2]);
  }
  std::vector<size_t> triangles(mesh->vertices.size(), 0);
  for (const Eigen::Vector3i& face : mesh->faces) ++triangles[sets.Find(face[0])];
  ComponentRemoval removal;
  std::vector<bool> keep(mesh->faces.size());
  for (size_t f = 0; f < mesh->faces.size(); ++f) {
    keep[f] = triangles[sets.Find(mesh->faces[f][0])] >= static_cast<size_t>(min_triangles);
    removal.triangles += !keep[f];
  }
  for (size_t v = 0; v < triangles.size(); ++v) {
    removal.components += triangles[v] > 0 && triangles[v] < static_cast<size_t>(min_triangles);
  }
  if (removal.triangles > 0) KeepFaces(mesh, keep);
  return removal;
}

void Decimate(TriangleMesh* mesh, double max_error) {
  GS_CHECK_GT(max_error, 0.0);
  GS_CHECK(mesh->face_colors.empty());  // marching cubes output has none; collapses would mix them
  if (mesh->faces.empty()) return;
  // Build the halfedge mesh; `source` remembers each OpenMesh vertex's input index.
  OmMesh om;
  OpenMesh::VPropHandleT<int> source;
  om.add_property(source);
  std::vector<OmMesh::VertexHandle> handle(mesh->vertices.size());
  for (size_t v = 0; v < mesh->vertices.size(); ++v) {
    const Eigen::Vector3f& p = mesh->vertices[v];
    handle[v] = om.add_vertex(OmMesh::Point(p.x(), p.y(), p.z()));
    om.property(source, handle[v]) = static_cast<int>(v);
  }
  std::vector<OmMesh::VertexHandle> split;
  for (const Eigen::Vector3i& face : mesh->faces) {
    std::vector<OmMesh::VertexHandle> corners = {handle[face[0]], handle[face[1]], handle[face[2]]};
    if (om.add_face(corners).is_valid()) continue;
    // A non-manifold vertex: give this face its own copies (merged again below).
    for (int j = 0; j < 3; ++j) {
      split.push_back(corners[j]);
      corners[j] = om.add_vertex(om.point(corners[j]));
      om.property(source, corners[j]) = face[j];
      split.push_back(corners[j]);
    }
    GS_CHECK(om.add_face(corners).is_valid());
  }
  // Split vertices and their neighbours never move, so that merging the copies again cannot
  // produce a face with a repeated vertex.
  om.request_vertex_status();
  for (const OmMesh::VertexHandle v : split) {
    om.status(v).set_locked(true);
    for (const auto& w : om.vv_range(v)) om.status(w).set_locked(true);
  }

  // Quadric error orders the collapses; Hausdorff and normal flipping veto them. The latter
  // needs face normals (computed here, so that OpenMesh does not announce it on stderr).
  om.request_face_normals();
  om.update_face_normals();
  OpenMesh::Decimater::DecimaterT<OmMesh> decimater(om);
  OpenMesh::Decimater::ModQuadricT<OmMesh>::Handle quadric;
  OpenMesh::Decimater::ModHausdorffT<OmMesh>::Handle hausdorff;
  OpenMesh::Decimater::ModNormalFlippingT<OmMesh>::Handle flipping;
  decimater.add(quadric);
  decimater.add(hausdorff);
  decimater.add(flipping);
  // The quadric also vetoes: a vertex may not move further than max_error from the planes of
  // the faces it absorbed (this limits how far the new faces' interiors stray, which the
  // Hausdorff module, measuring from the removed points only, does not).
  decimater.module(quadric).set_max_err(max_error * max_error, /*binary=*/false);
  decimater.module(hausdorff).set_tolerance(max_error);
  GS_CHECK(decimater.initialize());
  decimater.decimate();
  om.garbage_collection();

  // Back to shared vertices: OpenMesh vertices with the same input index are one vertex again.
  std::vector<int> new_index(mesh->vertices.size(), -1);
  TriangleMesh out;
  for (const auto& v : om.vertices()) {
    const int s = om.property(source, v);
    if (new_index[s] >= 0 || om.is_isolated(v)) continue;
    new_index[s] = static_cast<int>(out.vertices.size());
    out.vertices.push_back(mesh->vertices[s]);
    if (!mesh->normals.empty()) out.normals.push_back(mesh->normals[s]);
    if (!mesh->vertex_colors.empty()) out.vertex_colors.push_back(mesh->vertex_colors[s]);
  }
  for (const auto& f : om.faces()) {
    Eigen::Vector3i face;
    int j = 0;
    for (const auto& v : om.fv_range(f)) face[j++] = new_index[om.property(source, v)];
    out.faces.push_back(face);
  }
  *mesh = std::move(out);
}

}  // namespace genscene::meshing
