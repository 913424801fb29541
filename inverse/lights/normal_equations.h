// Step 3 of light estimation: the cache reduced to its normal equations, per channel c
//     G_c = sum_i a_ic a_ic^T,   b_c = sum_i a_ic I_ic,   I_c^T I_c = sum_i I_ic^2
// (a_ic: pixel i's coefficients, I_ic: its observed value), so that one cost evaluation is
// O(parameters^2), independent of the number of pixels. Two independent halves of the paths give
// the unbiased cross product instead (NormalEquations::FromCaches).
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

#include "inverse/lights/light_cache.h"

namespace genscene::inverse {

// The cache reduced to its normal equations over the parameters that any pixel touches.
struct NormalEquations {
  int parameters = 0;                   // 6 x voxels
  std::vector<int> used;                // parameter index of each compact index
  std::array<Eigen::MatrixXd, 3> gram;  // per channel, compact x compact (both triangles stored)
  std::array<Eigen::VectorXd, 3> rhs;   // per channel, compact
  std::array<double, 3> observed_sq{};  // per channel, sum of I^2
  size_t pixels = 0;
  // The same two per view (SampledPixel::view), for the exposure step: rhs and observed_sq are
  // their sums, with each view's observations scaled as ScaleObserved last said (1 at first).
  std::vector<std::array<Eigen::VectorXd, 3>> view_rhs;
  std::vector<Eigen::Vector3d> view_observed_sq;

  static NormalEquations FromCache(const LightCache& cache);
  // From two independent traces of the same pixels (rows a_i, b_i): the mean rows m = (a + b) / 2
  // and the half differences d = (a - b) / 2 give G_c = M^T M - gamma D^T D, b_c = M^T I.
  // M^T M alone carries the Monte Carlo variance of the coefficients in its expectation
  // (errors-in-variables: it acts as a regulariser that shrinks and smears the lights);
  // E[D^T D] is that variance, so gamma = 1 is unbiased (= (A^T B + B^T A) / 2), gamma = 0 the
  // plain Gram matrix of the mean rows. gamma < 1 keeps G safely positive definite.
  // `known`: the equations of the same caches before entries of further parameters were merged
  // in (LightCache::Merge); the entries of G between two of its parameters are taken from it and
  // only those with a new parameter are computed (dense rows only; sparse ones are recomputed).
  static NormalEquations FromCaches(const LightCache& first, const LightCache& second,
                                    double correction, const NormalEquations* known = nullptr);
  // Adds another cache's equations (same parameters), e.g. from a later tracing round.
  void Add(const NormalEquations& other);
  // rhs and observed_sq of the observations of view v scaled by scale[v] (per channel), I -> s I;
  // G does not depend on the observations. scale holds an entry for every view of view_rhs.
  void ScaleObserved(const std::vector<Eigen::Vector3d>& scale);
};

// Bytes of the normal equations EstimateLights may hold at once for a grid of `dims`^3 voxels: two
// sets (the running total and a round's) of three dense Gram matrices over all 6 dims^3 parameters.
double NormalEquationsBoundBytes(int dims);

}  // namespace genscene::inverse
