// Internal to vertex refinement (inverse/refine/*.cpp): the terms of E besides the data term: the
// robust prior on the starting positions, the tangential relaxation and the bending term. The
// public API is in vertex_refinement.h.
#pragma once

#include <Eigen/Sparse>
#include <vector>

#include "inverse/refine/linear_solve.h"
#include "inverse/refine/vertex_refinement.h"

namespace genscene::inverse::refine_detail {

// A prior this many times the usual one holds a vertex in place (its steps come out ~1e-10 of
// the others') without taking it out of the linear system.
constexpr double kHeld = 1e10;

// P_i, the prior's information matrix per parameter vertex:
//   P_i = n n^T / sigma_n^2 + (I - n n^T) / sigma_t^2,   sigma_n = prior_sigma,
//   sigma_t = prior_tangent_sigma (0: prior_sigma),
// n the vertex's starting normal (area-weighted). By default sigma_t = sigma_n: the relaxation
// term, not this prior, keeps the vertices from sliding across the surface, and a firm prior
// across the starting normal of a noisy mesh, whose normals are tilted, also holds the moves
// along the true normal that the images ask for. Vertices without a normal (no face) get the
// isotropic 1 / sigma_n^2.
std::vector<Eigen::Matrix3d> PriorBlocks(const render::DifferentiablePathTracer& tracer,
                                         const RefineOptions& options);

// The relaxation and bending terms together as x^T Q x / 2, Q = A^T A / relax_sigma^2 +
// B^T B / smooth_sigma^2 (Factor gives their rows). Both act on a vertex's offset from the
// centroid of its one-ring, c_i = mean_{j in ring(i)} x_j, at the normals n_i of the positions
// Factor is given (held for an iteration, so the terms are quadratic).
//
// Relaxation (relax_sigma): three rows of A per vertex inside its mesh,
//   a_i = T_i (x_i - c_i),   T_i = I - n_i n_i^T,
// the vertex's offset across the surface from its ring's centroid: zero where the vertices are
// evenly spread, and blind to moves along the normal, which the images see. The images barely see
// a vertex slide across a smooth surface, so noise across the surface in the starting positions
// stays where the prior holds it (and drifts with the render noise where none does); this term
// spreads the vertices evenly instead (tangential relaxation, as in isotropic remeshing), which on
// the noisy sphere of bench_refine's section 3 takes out most of the error across the surface.
// Vertices on a mesh boundary get no row: their one-ring's centroid lies inside the surface.
//
// Bending (smooth_sigma): one row of B per vertex whose ring has rows too, a change of curvature
// from a vertex to its ring (see Factor). It holds a single vertex from walking along its normal,
// where visibility changes (not differentiated) at a silhouette pull it.
//
// The connectivity (one-rings, boundaries) is found once; only the normals change with x.
class Relaxation {
 public:
  Relaxation(const render::DifferentiablePathTracer& tracer, double sigma, double smooth_sigma);

  // C with Q = C^T C at the parameter vector `x`: the rows of A / relax_sigma, then those of
  // B / smooth_sigma; no non-zeros when relax_sigma and smooth_sigma are 0.
  Eigen::SparseMatrix<double, Eigen::RowMajor> Factor(const Eigen::VectorXd& x) const;

 private:
  struct Row {
    int vertex;                  // parameter vertex
    std::vector<int> ring;       // its neighbours' parameter vertices
    std::vector<int> ring_rows;  // their rows (empty when a neighbour has none: no bending row)
  };
  void AddMesh(const render::DifferentiablePathTracer& tracer, int mesh);
  // The unit normals n_r per row at x (0: no normal).
  std::vector<Eigen::Vector3d> UnitNormals(const Eigen::VectorXd& x) const;
  // The rows of A / relax_sigma (row 3 i + k for vertex i) and of B / smooth_sigma (from row
  // `first`), as triplets; *rows becomes the row after the last bending row.
  void RelaxationRows(const std::vector<Eigen::Vector3d>& unit,
                      std::vector<Eigen::Triplet<double>>* entries) const;
  void BendingRows(const Eigen::VectorXd& x, const std::vector<Eigen::Vector3d>& unit, int first,
                   int* rows, std::vector<Eigen::Triplet<double>>* entries) const;

  int size_;
  double sigma_, smooth_sigma_;
  std::vector<Eigen::Vector3i> faces_;  // of the refined meshes, as parameter vertices
  std::vector<Row> rows_;               // the vertices inside their mesh
};

// The prior, relaxation and bending terms of E at x: their cost, gradient and the matrices the
// step's linear system adds. `held` vertices get kHeld times the prior, quadratic.
class Regularisers {
 public:
  Regularisers(const render::DifferentiablePathTracer& tracer, const RefineOptions& options,
               const Eigen::VectorXd& initial, const std::vector<bool>& held);

  // Q from the normals at x, for the iteration that starts at x.
  void Relinearise(const Eigen::VectorXd& x) {
    coupling_.Set(relax_.Factor(x), static_cast<int>(prior_.size()));
  }
  double Cost(const Eigen::VectorXd& at) const;
  Eigen::VectorXd Gradient(const Eigen::VectorXd& at) const;
  // The prior's matrix for the step at `at`: w_i P_i, w_i the IRLS weight of its distance.
  std::vector<Eigen::Matrix3d> PriorBlocksAt(const Eigen::VectorXd& at) const;
  // Q (may be empty).
  const refine_detail::Coupling& Coupling() const { return coupling_; }

 private:
  double Threshold(size_t v) const { return held_[v] ? 0.0 : prior_robust_; }
  double Distance(const Eigen::VectorXd& at, size_t v) const;
  double PriorWeight(const Eigen::VectorXd& at, size_t v) const;

  double prior_robust_;
  Eigen::VectorXd initial_;             // x0
  std::vector<Eigen::Matrix3d> prior_;  // P_i (kHeld P_i when held)
  std::vector<bool> held_;
  Relaxation relax_;
  refine_detail::Coupling coupling_;  // Q at the start of the iteration
};

}  // namespace genscene::inverse::refine_detail
