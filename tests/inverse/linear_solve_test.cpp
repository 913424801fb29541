// The refinement's coupling matrix Q = C^T C, kept as its factor C: its products, diagonal blocks
// and cost against Q formed explicitly.
#include "inverse/refine/linear_solve.h"

#include <gtest/gtest.h>

#include "core/rng.h"

namespace genscene::inverse::refine_detail {
namespace {

// A random sparse C over `vertices` vertices: each row touches a few vertices, some coordinates
// of a vertex only (as the bending rows along a normal do), with repeated entries summed.
Eigen::SparseMatrix<double, Eigen::RowMajor> RandomFactor(int rows, int vertices, uint64_t seed) {
  CounterRng rng(seed, 0);
  std::vector<Eigen::Triplet<double>> entries;
  for (int r = 0; r < rows; ++r) {
    for (int k = 0; k < 4; ++k) {
      const int v = static_cast<int>(rng.UniformInt(vertices));
      for (int c = 0; c < 3; ++c) {
        if (rng.UniformDouble() < 0.7)
          entries.emplace_back(r, 3 * v + c, 2.0 * rng.UniformDouble() - 1.0);
      }
    }
  }
  Eigen::SparseMatrix<double, Eigen::RowMajor> c(rows, 3 * vertices);
  c.setFromTriplets(entries.begin(), entries.end());
  return c;
}

TEST(Coupling, ProductBlocksAndCostAreThoseOfTheExplicitMatrix) {
  const int vertices = 40;
  Coupling coupling;
  coupling.Set(RandomFactor(70, vertices, 5), vertices);
  ASSERT_FALSE(coupling.Empty());
  const Eigen::MatrixXd q = Eigen::MatrixXd(coupling.Matrix());
  const Eigen::MatrixXd c = Eigen::MatrixXd(coupling.factor);
  EXPECT_LT((q - c.transpose() * c).cwiseAbs().maxCoeff(), 1e-12);

  CounterRng rng(8, 0);
  Eigen::VectorXd v(3 * vertices), out(3 * vertices), scratch;
  for (int i = 0; i < v.size(); ++i) v[i] = rng.UniformDouble() - 0.5;
  out.setConstant(1.0);  // AddProduct adds
  coupling.AddProduct(v, &out, &scratch);
  EXPECT_LT((out - (q * v + Eigen::VectorXd::Ones(v.size()))).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(coupling.HalfSquaredNorm(v), 0.5 * v.dot(q * v), 1e-12);
  ASSERT_EQ(coupling.blocks.size(), static_cast<size_t>(vertices));
  for (int i = 0; i < vertices; ++i) {
    EXPECT_LT((coupling.blocks[i] - q.block<3, 3>(3 * i, 3 * i)).cwiseAbs().maxCoeff(), 1e-12)
        << "vertex " << i;
  }
}

TEST(Coupling, NoEntriesIsNoCoupling) {
  Coupling coupling;
  coupling.Set(Eigen::SparseMatrix<double, Eigen::RowMajor>(9, 9), 3);
  EXPECT_TRUE(coupling.Empty());
  Eigen::VectorXd v = Eigen::VectorXd::Ones(9), out = Eigen::VectorXd::Zero(9), scratch;
  coupling.AddProduct(v, &out, &scratch);
  EXPECT_EQ(out, Eigen::VectorXd::Zero(9));
  EXPECT_EQ(coupling.HalfSquaredNorm(v), 0.0);
  for (const Eigen::Matrix3d& b : coupling.blocks) EXPECT_EQ(b, Eigen::Matrix3d::Zero());
}

}  // namespace
}  // namespace genscene::inverse::refine_detail
