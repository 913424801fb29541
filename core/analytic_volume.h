// TSDF volumes sampled from exact signed distance functions (sphere, torus, box), and the mesh
// checks (topology, distance to a mesh) that the marching-cubes tests and bench share.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <utility>

#include "core/mesh.h"
#include "core/tsdf_volume.h"

namespace genscene::analytic {

// Signed distance in metres at a world point (positive outside).
using Sdf = std::function<double(const Eigen::Vector3d&)>;

inline double SphereSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& centre, double radius) {
  return (p - centre).norm() - radius;
}
// Torus around the z axis through `centre`: ring radius R, tube radius r.
inline double TorusSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& centre, double R,
                       double r) {
  const Eigen::Vector3d q = p - centre;
  return std::hypot(std::hypot(q.x(), q.y()) - R, q.z()) - r;
}
// Axis-aligned box with half extents `half` (exact Euclidean distance, also outside the corners).
inline double BoxSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& centre,
                     const Eigen::Vector3d& half) {
  const Eigen::Vector3d q = (p - centre).cwiseAbs() - half;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

struct AnalyticVolumeSpec {
  double voxel_size = 0.02;
  double truncation = 0.06;
  // Global lattice point g sits at world voxel_size * g in every layout; the volume's own lattice
  // is shifted: its voxel v is g = v + shift (origin = voxel_size * shift). Different shifts cut
  // the same lattice into blocks differently, with bit-identical voxel values.
  Eigen::Vector3i shift = Eigen::Vector3i::Zero();
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(-24);  // global lattice bounds, inclusive
  Eigen::Vector3i hi = Eigen::Vector3i::Constant(24);
  bool sparse = true;  // allocate only blocks with a voxel inside the truncation band
};

// Colour of the test volumes: linear in the world position, so that interpolation along an edge
// reproduces it exactly at the vertex.
inline Eigen::Vector3f TestColor(const Eigen::Vector3d& p) {
  return Eigen::Vector3f(0.5f + 0.5f * float(p.x()), 0.5f + 0.5f * float(p.y()),
                         0.5f + 0.5f * float(p.z()));
}

// Samples `sdf` (metres) at the lattice points of the blocks covering [lo, hi], truncated, with
// weight 1. `sdf_of_global`, when given, takes the global lattice point instead (exact values on
// lattice points).
inline TsdfVolume MakeAnalyticVolume(
    const AnalyticVolumeSpec& spec, const Sdf& sdf,
    const std::function<double(const Eigen::Vector3i&)>& sdf_of_global = {}) {
  TsdfVolumeParams params;
  params.voxel_size = spec.voxel_size;
  params.truncation = spec.truncation;
  params.origin = spec.voxel_size * spec.shift.cast<double>();
  TsdfVolume volume(params);
  const Eigen::Vector3i block_lo = TsdfVolume::BlockOf(spec.lo - spec.shift);
  const Eigen::Vector3i block_hi = TsdfVolume::BlockOf(spec.hi - spec.shift);
  TsdfBlock block;
  for (int bz = block_lo.z(); bz <= block_hi.z(); ++bz) {
    for (int by = block_lo.y(); by <= block_hi.y(); ++by) {
      for (int bx = block_lo.x(); bx <= block_hi.x(); ++bx) {
        const Eigen::Vector3i key(bx, by, bz);
        bool near_surface = false;
        for (int i = 0; i < kTsdfBlockVoxels; ++i) {
          const Eigen::Vector3i local(i % 8, (i / 8) % 8, i / 64);
          const Eigen::Vector3i g = kTsdfBlockSide * key + local + spec.shift;
          const Eigen::Vector3d world = spec.voxel_size * g.cast<double>();
          const double d = sdf_of_global ? sdf_of_global(g) : sdf(world);
          TsdfVoxel& voxel = block.voxels[i];
          voxel.sdf = static_cast<float>(std::clamp(d, -spec.truncation, spec.truncation));
          voxel.weight = 1.0f;
          block.colors[i] = TestColor(world);
          near_surface |= std::abs(d) < spec.truncation;
        }
        if (spec.sparse && !near_surface) continue;
        volume.block(volume.AllocateBlock(key)) = block;
      }
    }
  }
  return volume;
}

struct MeshTopology {
  bool closed = true;                 // every edge in exactly two faces
  bool consistently_oriented = true;  // every directed edge at most once
  long long euler = 0;                // V - E + F
  size_t edges = 0;
  size_t duplicate_vertices = 0;  // vertices at exactly the position of another
  size_t degenerate_faces = 0;    // repeated index or area <= min_area
  double min_area = 0.0;          // smallest face area, m^2
};

inline MeshTopology AnalyseMesh(const TriangleMesh& mesh, double zero_area = 0.0) {
  MeshTopology t;
  std::map<std::pair<int, int>, int> undirected, directed;
  t.min_area = mesh.faces.empty() ? 0.0 : 1e300;
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d a = mesh.vertices[f[0]].cast<double>(),
                          b = mesh.vertices[f[1]].cast<double>(),
                          c = mesh.vertices[f[2]].cast<double>();
    const double area = 0.5 * (b - a).cross(c - a).norm();
    t.min_area = std::min(t.min_area, area);
    t.degenerate_faces += f[0] == f[1] || f[1] == f[2] || f[0] == f[2] || area <= zero_area;
    for (int j = 0; j < 3; ++j) {
      const int u = f[j], v = f[(j + 1) % 3];
      ++undirected[{std::min(u, v), std::max(u, v)}];
      ++directed[{u, v}];
    }
  }
  for (const auto& [edge, count] : undirected) t.closed &= count == 2;
  for (const auto& [edge, count] : directed) t.consistently_oriented &= count == 1;
  t.edges = undirected.size();
  t.euler = static_cast<long long>(mesh.vertices.size()) - static_cast<long long>(t.edges) +
            static_cast<long long>(mesh.faces.size());
  std::vector<std::array<float, 3>> sorted;
  for (const Eigen::Vector3f& v : mesh.vertices) sorted.push_back({v.x(), v.y(), v.z()});
  std::sort(sorted.begin(), sorted.end());
  for (size_t i = 1; i < sorted.size(); ++i) t.duplicate_vertices += sorted[i] == sorted[i - 1];
  return t;
}

// Distance from p to the closest point of triangle (a, b, c) (Ericson, Real-Time Collision
// Detection, 5.1.5).
inline double DistanceToTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                 const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  const double denom = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

// Distance from p to a mesh, by brute force (test sizes only).
inline double DistanceToMesh(const Eigen::Vector3d& p, const TriangleMesh& mesh) {
  double best = 1e300;
  for (const Eigen::Vector3i& f : mesh.faces) {
    best = std::min(best, DistanceToTriangle(p, mesh.vertices[f[0]].cast<double>(),
                                             mesh.vertices[f[1]].cast<double>(),
                                             mesh.vertices[f[2]].cast<double>()));
  }
  return best;
}

}  // namespace genscene::analytic
