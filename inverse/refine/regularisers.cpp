#include "inverse/refine/regularisers.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "inverse/refine/robust_loss.h"

namespace genscene::inverse::refine_detail {
using namespace genscene::render;  // the renderer the inverse stages are built on

std::vector<Eigen::Matrix3d> PriorBlocks(const DifferentiablePathTracer& tracer,
                                         const RefineOptions& options) {
  const double wn = 1.0 / (options.prior_sigma * options.prior_sigma);
  const double sigma_t =
      options.prior_tangent_sigma > 0.0 ? options.prior_tangent_sigma : options.prior_sigma;
  const double wt = 1.0 / (sigma_t * sigma_t);
  std::vector<Eigen::Matrix3d> blocks(tracer.VertexCount(), wn * Eigen::Matrix3d::Identity());
  if (wt == wn) return blocks;
  for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
    if (tracer.ParameterVertex(static_cast<int>(m), 0) < 0) continue;
    TriangleMesh mesh = tracer.scene().meshes[m].mesh;
    mesh.ComputeVertexNormals();
    for (size_t v = 0; v < mesh.vertices.size(); ++v) {
      const Eigen::Vector3d n = mesh.normals[v].cast<double>();
      if (n.squaredNorm() < 0.5) continue;  // no incident face
      blocks[tracer.ParameterVertex(static_cast<int>(m), static_cast<int>(v))] =
          wt * Eigen::Matrix3d::Identity() + (wn - wt) * n * n.transpose();
    }
  }
  return blocks;
}

// --- Relaxation and bending ----------------------------------------------------------------------

Relaxation::Relaxation(const DifferentiablePathTracer& tracer, double sigma, double smooth_sigma)
    : size_(3 * tracer.VertexCount()), sigma_(sigma), smooth_sigma_(smooth_sigma) {
  if (sigma <= 0.0 && smooth_sigma <= 0.0) return;
  for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
    if (tracer.ParameterVertex(static_cast<int>(m), 0) >= 0) AddMesh(tracer, static_cast<int>(m));
  }
  std::vector<int> row_of(tracer.VertexCount(), -1);
  for (size_t r = 0; r < rows_.size(); ++r) row_of[rows_[r].vertex] = static_cast<int>(r);
  for (Row& row : rows_) {  // the bending row needs every neighbour's offset
    for (int j : row.ring) {
      if (row_of[j] < 0) {
        row.ring_rows.clear();
        break;
      }
      row.ring_rows.push_back(row_of[j]);
    }
  }
}

// The faces of refined mesh `mesh` and a row per vertex inside it: its one-ring, found from the
// faces; a vertex on an edge with other than two faces is on the boundary.
void Relaxation::AddMesh(const DifferentiablePathTracer& tracer, int mesh) {
  const TriangleMesh& triangles = tracer.scene().meshes[mesh].mesh;
  const size_t n = triangles.vertices.size();
  std::vector<std::vector<int>> ring(n);
  std::map<std::pair<int, int>, int> edges;  // faces per undirected edge
  for (const Eigen::Vector3i& f : triangles.faces) {
    Eigen::Vector3i face;
    for (int k = 0; k < 3; ++k) {
      const int a = f[k], b = f[(k + 1) % 3];
      ring[a].push_back(b), ring[b].push_back(a);
      ++edges[{std::min(a, b), std::max(a, b)}];
      face[k] = tracer.ParameterVertex(mesh, a);
    }
    faces_.push_back(face);
  }
  std::vector<bool> boundary(n, false);
  for (const auto& [edge, faces] : edges) {
    if (faces != 2) boundary[edge.first] = boundary[edge.second] = true;
  }
  for (size_t v = 0; v < n; ++v) {
    std::sort(ring[v].begin(), ring[v].end());
    ring[v].erase(std::unique(ring[v].begin(), ring[v].end()), ring[v].end());
    if (boundary[v] || ring[v].empty()) continue;
    Row row{tracer.ParameterVertex(mesh, static_cast<int>(v)), {}, {}};
    for (int j : ring[v]) row.ring.push_back(tracer.ParameterVertex(mesh, j));
    rows_.push_back(std::move(row));
  }
}

Eigen::SparseMatrix<double, Eigen::RowMajor> Relaxation::Factor(const Eigen::VectorXd& x) const {
  std::vector<Eigen::Triplet<double>> entries;
  int rows = size_;  // A's rows, zero where relax_sigma is 0
  if (sigma_ > 0.0 || smooth_sigma_ > 0.0) {
    const std::vector<Eigen::Vector3d> unit = UnitNormals(x);
    if (sigma_ > 0.0) RelaxationRows(unit, &entries);
    if (smooth_sigma_ > 0.0) BendingRows(x, unit, size_, &rows, &entries);
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> c(rows, size_);
  c.setFromTriplets(entries.begin(), entries.end());
  c.prune(0.0);
  return c;
}

// n_r: the area-weighted normal of row r's vertex at x, normalised.
std::vector<Eigen::Vector3d> Relaxation::UnitNormals(const Eigen::VectorXd& x) const {
  std::vector<Eigen::Vector3d> normal(size_ / 3, Eigen::Vector3d::Zero());
  for (const Eigen::Vector3i& f : faces_) {
    const auto at = [&](int k) -> Eigen::Vector3d { return x.segment<3>(3 * f[k]); };
    const Eigen::Vector3d area = (at(1) - at(0)).cross(at(2) - at(0));  // twice the area
    for (int k = 0; k < 3; ++k) normal[f[k]] += area;
  }
  std::vector<Eigen::Vector3d> unit(rows_.size(), Eigen::Vector3d::Zero());  // 0: no normal
  for (size_t r = 0; r < rows_.size(); ++r) {
    if (normal[rows_[r].vertex].norm() > 0.0) unit[r] = normal[rows_[r].vertex].normalized();
  }
  return unit;
}

// The rows of A / relax_sigma (Q's part A^T A / relax_sigma^2), the relaxation's residuals
//   r_i = T_i (x_i - c_i) / relax_sigma,   T_i = I - n_i n_i^T,   c_i = mean_{j in ring(i)} x_j,
// three rows per vertex that has a normal.
void Relaxation::RelaxationRows(const std::vector<Eigen::Vector3d>& unit,
                                std::vector<Eigen::Triplet<double>>* entries) const {
  for (size_t r = 0; r < rows_.size(); ++r) {
    const Row& row = rows_[r];
    if (unit[r].isZero()) continue;
    const Eigen::Matrix3d t =
        (Eigen::Matrix3d::Identity() - unit[r] * unit[r].transpose()) / sigma_;
    const auto put = [&](int vertex, double scale) {
      for (int i = 0; i < 3; ++i) {
        for (int c = 0; c < 3; ++c)
          entries->emplace_back(3 * row.vertex + i, 3 * vertex + c, scale * t(i, c));
      }
    };
    put(row.vertex, 1.0);
    for (int j : row.ring) put(j, -1.0 / row.ring.size());
  }
}

// The rows of B / smooth_sigma (Q's part B^T B / smooth_sigma^2), the bending term's residuals
//   r_i = (k_i - mean_{j in ring(i)} k_j) / smooth_sigma,   k_i = n_i . (x_i - c_i) * l / l_i,
// where n_i . (x_i - c_i) is the vertex's offset along its normal from its one-ring's centroid
// (the umbrella Laplacian along the normal), l_i the mean squared length of its edges and l the
// mean of l_i over the vertices (which makes k a length). k_i is half the mean curvature, times l,
// wherever the ring lies on a sphere (a neighbour at distance d is d^2 / 2R below the tangent
// plane), whatever the valence and the edge lengths, so a sphere or a plane bends at no cost; the
// offset alone differs by 19 % between the icosphere's vertices of valence 5 and 6, which this
// term would then flatten. One row per vertex whose ring has rows, normals and edges.
void Relaxation::BendingRows(const Eigen::VectorXd& x, const std::vector<Eigen::Vector3d>& unit,
                             int first, int* rows,
                             std::vector<Eigen::Triplet<double>>* entries) const {
  std::vector<double> spread(rows_.size(), 0.0);  // l_r
  double mean_spread = 0.0;
  for (size_t r = 0; r < rows_.size(); ++r) {
    const Eigen::Vector3d at = x.segment<3>(3 * rows_[r].vertex);
    for (int j : rows_[r].ring) spread[r] += (x.segment<3>(3 * j) - at).squaredNorm();
    spread[r] /= rows_[r].ring.size();
    mean_spread += spread[r] / rows_.size();
  }
  int row_index = first;
  for (size_t r = 0; r < rows_.size(); ++r) {
    const Row& row = rows_[r];
    if (row.ring_rows.empty() || unit[r].isZero() || !(spread[r] > 0.0)) continue;
    bool complete = true;
    for (int k : row.ring_rows) complete = complete && !unit[k].isZero() && spread[k] > 0.0;
    if (!complete) continue;
    const auto put_h = [&](int k, double scale) {  // scale * k_k
      const Row& of = rows_[k];
      const Eigen::Vector3d n = unit[k] * (scale * mean_spread / spread[k] / smooth_sigma_);
      for (int c = 0; c < 3; ++c) {
        entries->emplace_back(row_index, 3 * of.vertex + c, n[c]);
        for (int j : of.ring) entries->emplace_back(row_index, 3 * j + c, -n[c] / of.ring.size());
      }
    };
    put_h(static_cast<int>(r), 1.0);
    for (int k : row.ring_rows) put_h(k, -1.0 / row.ring_rows.size());
    ++row_index;
  }
  *rows = row_index;
}

// --- The regularisers of E together --------------------------------------------------------------

Regularisers::Regularisers(const DifferentiablePathTracer& tracer, const RefineOptions& options,
                           const Eigen::VectorXd& initial, const std::vector<bool>& held)
    : prior_robust_(options.prior_robust),
      initial_(initial),
      prior_(PriorBlocks(tracer, options)),
      held_(held),
      relax_(tracer, options.relax_sigma, options.smooth_sigma) {
  for (size_t v = 0; v < prior_.size(); ++v) {
    if (held_[v]) prior_[v] *= kHeld;
  }
  Relinearise(initial);
}

// The prior's residual per vertex is its Mahalanobis distance from the start,
//   s_i = sqrt(d_i^T P_i d_i),   d_i = x_i - x0_i,
// and its cost HuberCost(s_i, prior_robust): quadratic for the small moves that noise makes,
// linear for a large move that the images support, which a quadratic prior would pull back in
// proportion (on the replica a 3 mm prior leaves the 40 mm spike 4-5 mm short). Held vertices
// stay quadratic (threshold 0, as prior_robust 0).
double Regularisers::Distance(const Eigen::VectorXd& at, size_t v) const {
  const Eigen::Vector3d d = at.segment<3>(3 * v) - initial_.segment<3>(3 * v);
  return std::sqrt(d.dot(prior_[v] * d));
}

double Regularisers::PriorWeight(const Eigen::VectorXd& at, size_t v) const {
  return HuberWeight(Distance(at, v), Threshold(v));
}

// sum_i HuberCost(s_i, prior_robust) + x^T Q x / 2
double Regularisers::Cost(const Eigen::VectorXd& at) const {
  double sum = 0.0;
  for (size_t v = 0; v < prior_.size(); ++v) sum += HuberCost(Distance(at, v), Threshold(v));
  return sum + coupling_.HalfSquaredNorm(at);
}

// w_i P_i d_i per vertex, plus Q x
Eigen::VectorXd Regularisers::Gradient(const Eigen::VectorXd& at) const {
  Eigen::VectorXd g(at.size());
  for (size_t v = 0; v < prior_.size(); ++v)
    g.segment<3>(3 * v) =
        PriorWeight(at, v) * (prior_[v] * (at.segment<3>(3 * v) - initial_.segment<3>(3 * v)));
  Eigen::VectorXd scratch;
  coupling_.AddProduct(at, &g, &scratch);
  return g;
}

std::vector<Eigen::Matrix3d> Regularisers::PriorBlocksAt(const Eigen::VectorXd& at) const {
  std::vector<Eigen::Matrix3d> blocks(prior_.size());
  for (size_t v = 0; v < prior_.size(); ++v) blocks[v] = PriorWeight(at, v) * prior_[v];
  return blocks;
}

}  // namespace genscene::inverse::refine_detail
