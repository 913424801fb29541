#include "inverse/refine/linear_solve.h"

#include <Eigen/SparseCholesky>

#include "core/check.h"
#include "inverse/refine/robust_loss.h"

namespace genscene::inverse::refine_detail {
using namespace genscene::render;  // the renderer the inverse stages are built on

void NormalEquations::Multiply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const {
  out->setZero(v.size());
  for (size_t r = 0; r + 1 < row_start.size(); ++r) {
    double s = 0.0;
    for (size_t k = row_start[r]; k < row_start[r + 1]; ++k)
      s += row_d[k].dot(v.segment<3>(3 * row_vertex[k]));
    s *= row_weight[r];
    for (size_t k = row_start[r]; k < row_start[r + 1]; ++k)
      out->segment<3>(3 * row_vertex[k]) += s * row_d[k];
  }
}

void Coupling::Set(Eigen::SparseMatrix<double, Eigen::RowMajor> c, int vertices) {
  factor = std::move(c);
  factor.makeCompressed();
  blocks.assign(vertices, Eigen::Matrix3d::Zero());
  // A row's entries are sorted by column: those of one vertex are adjacent.
  for (int r = 0; r < factor.outerSize(); ++r) {
    const int begin = factor.outerIndexPtr()[r], end = factor.outerIndexPtr()[r + 1];
    const int* col = factor.innerIndexPtr();
    const double* value = factor.valuePtr();
    for (int a = begin; a < end; ++a) {
      for (int b = a; b < end && col[b] / 3 == col[a] / 3; ++b) {
        const double ab = value[a] * value[b];
        blocks[col[a] / 3](col[a] % 3, col[b] % 3) += ab;
        if (b != a) blocks[col[a] / 3](col[b] % 3, col[a] % 3) += ab;
      }
    }
  }
}

void Coupling::AddProduct(const Eigen::VectorXd& v, Eigen::VectorXd* out,
                          Eigen::VectorXd* scratch) const {
  if (Empty()) return;
  scratch->noalias() = factor * v;
  out->noalias() += factor.transpose() * *scratch;
}

double Coupling::HalfSquaredNorm(const Eigen::VectorXd& x) const {
  return Empty() ? 0.0 : 0.5 * (factor * x).squaredNorm();
}

Eigen::SparseMatrix<double> Coupling::Matrix() const {
  Eigen::SparseMatrix<double> c = factor;
  return Eigen::SparseMatrix<double>(c.transpose() * c);
}

// Per residual r with partials d_a = dr / dx_a (one 3-vector per vertex a it depends on) and
// weight w: g_a += w r d_a, H_aa += w d_a d_a^T, H_ab += w d_a d_b^T.
NormalEquations Assemble(const Evaluation& e, int vertices, double robust, bool keep_blocks) {
  NormalEquations n;
  n.blocks_kept = keep_blocks;
  n.gradient = Eigen::VectorXd::Zero(3 * vertices);
  n.diagonal.assign(vertices, Eigen::Matrix3d::Zero());
  if (!keep_blocks) n.row_start.push_back(0);
  for (const DualRgb& row : e.rows) {
    for (const SparseDual& r : row) {
      const auto& d = r.partials();
      const double w = HuberWeight(r.value(), robust);
      n.nonzeros += 3.0 * d.size();
      for (size_t a = 0; a < d.size(); ++a) {
        n.gradient.segment<3>(3 * d[a].vertex) += (w * r.value()) * d[a].d;
        n.diagonal[d[a].vertex] += w * d[a].d * d[a].d.transpose();
        if (keep_blocks) {
          for (size_t b = a + 1; b < d.size(); ++b) {
            auto [it, fresh] =
                n.blocks.try_emplace({d[a].vertex, d[b].vertex}, Eigen::Matrix3d::Zero());
            it->second += w * d[a].d * d[b].d.transpose();
          }
        } else {
          n.row_vertex.push_back(d[a].vertex);
          n.row_d.push_back(d[a].d);
        }
      }
      if (!keep_blocks) {
        n.row_weight.push_back(w);
        n.row_start.push_back(n.row_vertex.size());
      }
    }
  }
  return n;
}

namespace {

// diag(H), H = J^T W J + P + Q.
Eigen::VectorXd DiagonalOf(const NormalEquations& n, const std::vector<Eigen::Matrix3d>& prior,
                           const Coupling& coupling) {
  const int size = static_cast<int>(n.gradient.size());
  Eigen::VectorXd diagonal(size);
  for (int i = 0; i < size / 3; ++i) {
    diagonal.segment<3>(3 * i) = (n.diagonal[i] + prior[i]).diagonal();
    if (!coupling.Empty()) diagonal.segment<3>(3 * i) += coupling.blocks[i].diagonal();
  }
  return diagonal;
}

// H + mu diag(H) from the kept blocks, `diagonal` = diag(H).
Eigen::SparseMatrix<double> DampedMatrix(const NormalEquations& n,
                                         const std::vector<Eigen::Matrix3d>& prior,
                                         const Coupling& coupled_by,
                                         const Eigen::VectorXd& diagonal, double mu) {
  const int size = static_cast<int>(n.gradient.size());
  const int vertices = size / 3;
  const bool coupled = !coupled_by.Empty();
  const Eigen::SparseMatrix<double> coupling =
      coupled ? coupled_by.Matrix() : Eigen::SparseMatrix<double>(size, size);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(n.blocks.size() * 18 + 9 * vertices);
  for (int i = 0; i < vertices; ++i) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        const double value =
            r == c ? diagonal[3 * i + r] * (1.0 + mu) : n.diagonal[i](r, c) + prior[i](r, c);
        triplets.emplace_back(3 * i + r, 3 * i + c, value);
      }
    }
  }
  for (int c = 0; coupled && c < coupling.outerSize(); ++c) {  // its diagonal is in `diagonal`
    for (Eigen::SparseMatrix<double>::InnerIterator e(coupling, c); e; ++e) {
      if (e.row() != e.col())
        triplets.emplace_back(static_cast<int>(e.row()), static_cast<int>(e.col()), e.value());
    }
  }
  for (const auto& [ij, block] : n.blocks) {
    const auto [i, j] = ij;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        triplets.emplace_back(3 * i + r, 3 * j + c, block(r, c));
        triplets.emplace_back(3 * j + c, 3 * i + r, block(r, c));
      }
    }
  }
  Eigen::SparseMatrix<double> h(size, size);
  h.setFromTriplets(triplets.begin(), triplets.end());
  return h;
}

Eigen::VectorXd SolveByCholesky(const NormalEquations& n, const std::vector<Eigen::Matrix3d>& prior,
                                const Coupling& coupling, const Eigen::VectorXd& diagonal,
                                double mu, const Eigen::VectorXd& rhs) {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(
      DampedMatrix(n, prior, coupling, diagonal, mu));
  if (solver.info() != Eigen::Success)
    throw Error("vertex refinement: the normal equations could not be factorised");
  return solver.solve(rhs);
}

// Preconditioned conjugate gradients on (H + mu diag(H)) dx = rhs, H applied as
// J^T W J v + P v + Q v; the preconditioner is the inverse of each vertex's damped 3 x 3 block.
Eigen::VectorXd SolveByConjugateGradients(const NormalEquations& n,
                                          const std::vector<Eigen::Matrix3d>& prior,
                                          const Coupling& coupling, const Eigen::VectorXd& diagonal,
                                          double mu, const Eigen::VectorXd& rhs) {
  const int size = static_cast<int>(n.gradient.size());
  const int vertices = size / 3;
  const bool coupled = !coupling.Empty();
  std::vector<Eigen::Matrix3d> preconditioner(vertices);
  for (int i = 0; i < vertices; ++i) {
    Eigen::Matrix3d m = n.diagonal[i] + prior[i];
    if (coupled) m += coupling.blocks[i];
    m.diagonal() = diagonal.segment<3>(3 * i) * (1.0 + mu);
    preconditioner[i] = m.inverse();
  }
  Eigen::VectorXd scratch;
  const auto apply = [&](const Eigen::VectorXd& v, Eigen::VectorXd* out) {
    n.Multiply(v, out);
    for (int i = 0; i < vertices; ++i) out->segment<3>(3 * i) += prior[i] * v.segment<3>(3 * i);
    coupling.AddProduct(v, out, &scratch);
    *out += mu * diagonal.cwiseProduct(v);
  };
  const auto precondition = [&](const Eigen::VectorXd& r, Eigen::VectorXd* z) {
    for (int i = 0; i < vertices; ++i)
      z->segment<3>(3 * i) = preconditioner[i] * r.segment<3>(3 * i);
  };
  // Every vector is allocated once: the loop only writes into them.
  Eigen::VectorXd step = Eigen::VectorXd::Zero(size);
  Eigen::VectorXd residual = rhs, z(size), direction(size), product(size);
  precondition(residual, &z);
  direction = z;
  double rz = residual.dot(z);
  const double stop = 1e-20 * rhs.squaredNorm();
  for (int k = 0; k < 1000 && residual.squaredNorm() > stop; ++k) {
    apply(direction, &product);
    const double curvature = direction.dot(product);
    if (!(curvature > 0.0)) break;
    const double alpha = rz / curvature;
    step += alpha * direction;
    residual -= alpha * product;
    precondition(residual, &z);
    const double rz_next = residual.dot(z);
    direction = z + (rz_next / rz) * direction;
    rz = rz_next;
  }
  return step;
}

}  // namespace

Eigen::VectorXd SolveStep(const NormalEquations& n, const Eigen::VectorXd& prior_gradient,
                          const std::vector<Eigen::Matrix3d>& prior, const Coupling& coupling,
                          double mu) {
  const Eigen::VectorXd diagonal = DiagonalOf(n, prior, coupling);
  const Eigen::VectorXd rhs = -(n.gradient + prior_gradient);
  const Eigen::VectorXd step =
      n.blocks_kept ? SolveByCholesky(n, prior, coupling, diagonal, mu, rhs)
                    : SolveByConjugateGradients(n, prior, coupling, diagonal, mu, rhs);
  if (!step.allFinite()) throw Error("vertex refinement: the step is not finite");
  return step;
}

}  // namespace genscene::inverse::refine_detail
