#include "meshing/mesh_cleanup.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModHausdorffT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/check.h"
#include "core/disjoint_sets.h"
#include "core/parallel.h"

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

DenoiseStats Denoise(TriangleMesh* mesh, int iterations, double feature_angle_degrees,
                     double max_offset) {
  GS_CHECK_GE(iterations, 0);
  GS_CHECK(feature_angle_degrees > 0.0 && feature_angle_degrees <= 180.0);
  GS_CHECK_GE(max_offset, 0.0);
  DenoiseStats stats;
  const size_t nv = mesh->vertices.size(), nf = mesh->faces.size();
  if (iterations == 0 || nf == 0) return stats;

  // Faces around each vertex (compressed rows, faces in increasing order).
  std::vector<size_t> vertex_start(nv + 1, 0);
  for (const Eigen::Vector3i& face : mesh->faces) {
    for (int j = 0; j < 3; ++j) ++vertex_start[face[j] + 1];
  }
  std::partial_sum(vertex_start.begin(), vertex_start.end(), vertex_start.begin());
  std::vector<int> vertex_faces(vertex_start.back());
  {
    std::vector<size_t> fill(vertex_start.begin(), vertex_start.end() - 1);
    for (size_t f = 0; f < nf; ++f) {
      for (int j = 0; j < 3; ++j) vertex_faces[fill[mesh->faces[f][j]]++] = static_cast<int>(f);
    }
  }
  // Faces sharing a vertex with each face, itself included.
  std::vector<std::vector<int>> neighbours(nf);
  ParallelFor(0, nf, [&](size_t f) {
    std::vector<int>& list = neighbours[f];
    for (int j = 0; j < 3; ++j) {
      const int v = mesh->faces[f][j];
      list.insert(list.end(), vertex_faces.begin() + vertex_start[v],
                  vertex_faces.begin() + vertex_start[v + 1]);
    }
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
  });

  std::vector<Eigen::Vector3d> normal(nf), centroid(nf);
  std::vector<double> area(nf);
  // In double (TriangleMesh::FaceNormalScaled is float): the passes below accumulate in double.
  const auto position = [&](int v) { return mesh->vertices[v].cast<double>(); };
  for (size_t f = 0; f < nf; ++f) {
    const Eigen::Vector3i& face = mesh->faces[f];
    const Eigen::Vector3d scaled =
        (position(face[1]) - position(face[0])).cross(position(face[2]) - position(face[0]));
    area[f] = 0.5 * scaled.norm();
    normal[f] = area[f] > 0.0 ? Eigen::Vector3d(scaled / (2.0 * area[f])) : Eigen::Vector3d::Zero();
    centroid[f] = (position(face[0]) + position(face[1]) + position(face[2])) / 3.0;
  }
  double distance_sum = 0.0;
  size_t pairs = 0;
  for (size_t f = 0; f < nf; ++f) {
    for (const int g : neighbours[f]) {
      if (static_cast<size_t>(g) == f) continue;
      distance_sum += (centroid[f] - centroid[g]).norm();
      ++pairs;
    }
  }
  if (pairs == 0 || distance_sum <= 0.0) return stats;
  const double sigma_c = distance_sum / static_cast<double>(pairs);
  const double sigma_s = 2.0 * std::sin(0.5 * feature_angle_degrees * M_PI / 180.0);
  const double inv_c = 1.0 / (2.0 * sigma_c * sigma_c), inv_s = 1.0 / (2.0 * sigma_s * sigma_s);

  // Normal passes. Faces without area keep a zero normal and weigh nothing.
  std::vector<Eigen::Vector3d> filtered(nf);
  for (int it = 0; it < iterations; ++it) {
    ParallelFor(0, nf, [&](size_t f) {
      if (area[f] <= 0.0) {
        filtered[f] = normal[f];
        return;
      }
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (const int g : neighbours[f]) {
        if (area[g] <= 0.0) continue;
        const double wc = std::exp(-(centroid[f] - centroid[g]).squaredNorm() * inv_c);
        const double ws = std::exp(-(normal[f] - normal[g]).squaredNorm() * inv_s);
        sum += area[g] * wc * ws * normal[g];
      }
      const double norm = sum.norm();
      filtered[f] = norm > 0.0 ? Eigen::Vector3d(sum / norm) : normal[f];
    });
    normal.swap(filtered);
  }

  // Vertex passes toward the planes of the filtered normals through the current centroids.
  const std::vector<Eigen::Vector3f> start = mesh->vertices;
  std::vector<Eigen::Vector3d> x(nv), next(nv);
  for (size_t v = 0; v < nv; ++v) x[v] = start[v].cast<double>();
  for (int it = 0; it < 2 * iterations; ++it) {
    ParallelFor(0, nf, [&](size_t f) {
      const Eigen::Vector3i& face = mesh->faces[f];
      centroid[f] = (x[face[0]] + x[face[1]] + x[face[2]]) / 3.0;
    });
    ParallelFor(0, nv, [&](size_t v) {
      Eigen::Vector3d step = Eigen::Vector3d::Zero();
      int count = 0;
      for (size_t k = vertex_start[v]; k < vertex_start[v + 1]; ++k) {
        const int f = vertex_faces[k];
        if (area[f] <= 0.0) continue;
        step += normal[f] * normal[f].dot(centroid[f] - x[v]);
        ++count;
      }
      Eigen::Vector3d p = count > 0 ? Eigen::Vector3d(x[v] + step / count) : x[v];
      const Eigen::Vector3d offset = p - start[v].cast<double>();
      const double length = offset.norm();
      if (length > max_offset) p = start[v].cast<double>() + offset * (max_offset / length);
      next[v] = p;
    });
    x.swap(next);
  }

  // Positions, and vertex normals from the filtered face normals.
  std::vector<Eigen::Vector3f> normals(nv, Eigen::Vector3f::Zero());
  for (size_t v = 0; v < nv; ++v) {
    mesh->vertices[v] = x[v].cast<float>();
    stats.mean_offset += (x[v] - start[v].cast<double>()).norm();
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (size_t k = vertex_start[v]; k < vertex_start[v + 1]; ++k) {
      const int f = vertex_faces[k];
      sum += area[f] * normal[f];
    }
    if (sum.norm() > 0.0) {
      normals[v] = sum.normalized().cast<float>();
    } else if (!mesh->normals.empty()) {
      normals[v] = mesh->normals[v];
    }
  }
  stats.mean_offset /= static_cast<double>(std::max<size_t>(nv, 1));
  mesh->normals = std::move(normals);
  return stats;
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
