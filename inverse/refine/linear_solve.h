// Internal to vertex refinement (inverse/refine/*.cpp): the Gauss-Newton normal equations of the
// data term and the damped solve of a Levenberg-Marquardt step. The public API is in
// vertex_refinement.h.
#pragma once

#include <Eigen/Sparse>
#include <map>
#include <utility>
#include <vector>

#include "inverse/refine/data_term.h"

namespace genscene::inverse::refine_detail {

// The normal equations of the data term, J^T W J and J^T W r (W: the residuals' IRLS weights).
// Small problems keep J^T W J as 3 x 3 blocks per pair of vertices for a sparse Cholesky
// factorisation; large ones keep the Jacobian rows themselves (compressed) for conjugate
// gradients, which only need products J^T W J v: a path-traced pixel depends on vertices all over
// the scene, so the factor of a large J^T W J fills in (87k vertices: minutes and gigabytes),
// while a product costs O(non-zeros).
struct NormalEquations {
  bool blocks_kept = false;
  std::map<std::pair<int, int>, Eigen::Matrix3d> blocks;  // (i, j) with i <= j, when kept
  std::vector<Eigen::Matrix3d> diagonal;                  // (i, i) blocks, always
  std::vector<size_t> row_start;                          // compressed rows, when not kept
  std::vector<int> row_vertex;
  std::vector<Eigen::Vector3d> row_d;
  std::vector<double> row_weight;
  Eigen::VectorXd gradient;  // J^T W r
  double nonzeros = 0.0;     // scalar Jacobian entries

  // out = J^T W J v (from the rows: only when the blocks are not kept)
  void Multiply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const;
};

// The relaxation and bending terms' matrix Q = C^T C, kept as its factor C (one row per residual,
// over its sigma): a product Q v = C^T (C v) costs O(nnz(C)), where Q, which couples each vertex to
// its 4-ring, holds about 4.5 times as many non-zeros (a 65k-vertex mesh: 35 M, 0.4 GB, and a
// sparse-sparse product to form them every iteration).
struct Coupling {
  Eigen::SparseMatrix<double, Eigen::RowMajor> factor;  // C (no rows: Q = 0)
  std::vector<Eigen::Matrix3d> blocks;                  // Q's (i, i) 3 x 3 blocks

  // Sets C and Q's diagonal blocks over `vertices` parameter vertices.
  void Set(Eigen::SparseMatrix<double, Eigen::RowMajor> c, int vertices);
  bool Empty() const { return factor.nonZeros() == 0; }
  // out += Q v (`scratch` holds C v).
  void AddProduct(const Eigen::VectorXd& v, Eigen::VectorXd* out, Eigen::VectorXd* scratch) const;
  // x^T Q x / 2
  double HalfSquaredNorm(const Eigen::VectorXd& x) const;
  // Q itself (for the direct solve of small problems).
  Eigen::SparseMatrix<double> Matrix() const;
};

// The normal equations of the evaluation's rows over `vertices` parameter vertices, each residual
// weighted by HuberWeight(r, robust).
NormalEquations Assemble(const Evaluation& e, int vertices, double robust, bool keep_blocks);

// The Levenberg-Marquardt step: solves
//   (H + mu diag(H)) dx = -g,   H = J^T W J + P + Q,   g = J^T W r + the regularisers' gradient,
// P the prior's 3 x 3 blocks, Q the relaxation and bending matrix (`coupling`; may be empty).
// By sparse Cholesky (Eigen's SimplicialLDLT) when the blocks are kept, else by conjugate
// gradients preconditioned with the inverse 3 x 3 diagonal blocks, to a relative residual of
// 1e-10 (at most 1000 iterations; serial, so the same with any thread count). Throws Error when
// the system cannot be factorised or the step is not finite.
Eigen::VectorXd SolveStep(const NormalEquations& n, const Eigen::VectorXd& prior_gradient,
                          const std::vector<Eigen::Matrix3d>& prior, const Coupling& coupling,
                          double mu);

}  // namespace genscene::inverse::refine_detail
