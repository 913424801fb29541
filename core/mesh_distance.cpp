#include "core/mesh_distance.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"

namespace genscene {

namespace {

using Eigen::Vector3d;

// Closest point of triangle abc to p.
Vector3d ClosestOnTriangle(const Vector3d& p, const Vector3d& a, const Vector3d& b,
                           const Vector3d& c) {
  const Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + d1 / (d1 - d3) * ab;
  const Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0.0)) return a;  // degenerate triangle
  return a + ab * (vb / denom) + ac * (vc / denom);
}

}  // namespace

Eigen::Vector3i MeshDistance::CellOf(const Vector3d& cell_units) const {
  const Eigen::Array3d hi = (dims_.array() - 1).cast<double>();
  return cell_units.array().floor().max(0.0).min(hi).cast<int>();
}

MeshDistance::MeshDistance(const TriangleMesh& mesh, double max_distance)
    : mesh_(mesh), max_distance_(max_distance) {
  if (!(max_distance > 0.0))
    throw Error(Format("mesh distance: cut-off ", max_distance, " must be positive"));
  if (mesh.faces.empty()) throw Error("mesh distance: the reference mesh has no triangles");
  Eigen::AlignedBox3d box;
  for (const auto& v : mesh.vertices) box.extend(v.cast<double>());
  // Cells about the cut-off radius, at most 128 per axis.
  cell_ = std::max(max_distance, box.sizes().maxCoeff() / 128.0);
  origin_ = box.min();
  for (int k = 0; k < 3; ++k)
    dims_[k] = std::max(1, static_cast<int>(std::ceil(box.sizes()[k] / cell_)) + 1);
  cells_.assign(static_cast<size_t>(dims_.prod()), {});
  for (int f = 0; f < static_cast<int>(mesh.faces.size()); ++f) {
    Eigen::AlignedBox3d t;
    for (int k = 0; k < 3; ++k) t.extend(mesh.vertices[mesh.faces[f][k]].cast<double>());
    const Eigen::Vector3i lo = CellOf((t.min() - origin_) / cell_);
    const Eigen::Vector3i hi = CellOf((t.max() - origin_) / cell_);
    for (int z = lo.z(); z <= hi.z(); ++z)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int x = lo.x(); x <= hi.x(); ++x)
          cells_[(static_cast<size_t>(z) * dims_.y() + y) * dims_.x() + x].push_back(f);
  }
}

double MeshDistance::Distance(const Vector3d& point) const {
  double best = max_distance_;
  const Eigen::Vector3i lo =
      CellOf((point.array() - origin_.array() - max_distance_).matrix() / cell_);
  const Eigen::Vector3i hi =
      CellOf((point.array() - origin_.array() + max_distance_).matrix() / cell_);
  for (int z = lo.z(); z <= hi.z(); ++z) {
    for (int y = lo.y(); y <= hi.y(); ++y) {
      for (int x = lo.x(); x <= hi.x(); ++x) {
        for (int f : cells_[(static_cast<size_t>(z) * dims_.y() + y) * dims_.x() + x]) {
          const auto& face = mesh_.faces[f];
          const Vector3d q = ClosestOnTriangle(point, mesh_.vertices[face[0]].cast<double>(),
                                               mesh_.vertices[face[1]].cast<double>(),
                                               mesh_.vertices[face[2]].cast<double>());
          best = std::min(best, (q - point).norm());
        }
      }
    }
  }
  return best;
}

SurfaceError MeasureSurfaceError(const TriangleMesh& mesh, const TriangleMesh& truth,
                                 double max_distance) {
  const MeshDistance distance(truth, max_distance);
  SurfaceError e;
  double sum = 0.0, squares = 0.0;
  for (const auto& v : mesh.vertices) {
    const double d = distance.Distance(v.cast<double>());
    sum += d;
    squares += d * d;
    e.max = std::max(e.max, d);
    ++e.points;
  }
  if (e.points > 0) {
    e.mean = sum / e.points;
    e.rms = std::sqrt(squares / e.points);
  }
  static const double kBary[4][3] = {{4.0 / 6, 1.0 / 6, 1.0 / 6},
                                     {1.0 / 6, 4.0 / 6, 1.0 / 6},
                                     {1.0 / 6, 1.0 / 6, 4.0 / 6},
                                     {1.0 / 3, 1.0 / 3, 1.0 / 3}};
  double area_sum = 0.0, area_squares = 0.0, area = 0.0;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const Eigen::Vector3i& face = mesh.faces[f];
    const double a = 0.5 * mesh.FaceNormalScaled(f).cast<double>().norm();
    for (const auto& b : kBary) {
      const Eigen::Vector3d p = b[0] * mesh.vertices[face[0]].cast<double>() +
                                b[1] * mesh.vertices[face[1]].cast<double>() +
                                b[2] * mesh.vertices[face[2]].cast<double>();
      const double d = distance.Distance(p);
      area_sum += a * d;
      area_squares += a * d * d;
      area += a;
    }
  }
  if (area > 0.0) {
    e.area_mean = area_sum / area;
    e.area_rms = std::sqrt(area_squares / area);
  }
  return e;
}

}  // namespace genscene
