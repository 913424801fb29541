// Internal to vertex refinement (inverse/refine/*.cpp): Huber's loss, which both the data term
// (threshold `robust`) and the prior (threshold `prior_robust`) pass their residuals through. The
// public API is in vertex_refinement.h.
#pragma once

#include <cmath>

namespace genscene::inverse::refine_detail {

// Huber's loss of a residual r with threshold k:
//   rho(r) = r^2 / 2            for |r| <= k
//   rho(r) = k (|r| - k / 2)    for |r| >  k
// so that a few large residuals (pixels whose visibility differs from the reference, a move the
// images support far beyond the prior's sigma) pull with a constant force, not in proportion.
// k = 0: plain least squares.
inline double HuberCost(double r, double k) {
  const double a = std::abs(r);
  return k <= 0.0 || a <= k ? 0.5 * r * r : k * (a - 0.5 * k);
}

// IRLS weight of a residual under Huber's loss, w(r) = rho'(r) / r = min(1, k / |r|): the normal
// equations use w J^T J and w J^T r.
inline double HuberWeight(double r, double k) {
  const double a = std::abs(r);
  return k <= 0.0 || a <= k ? 1.0 : k / a;
}

}  // namespace genscene::inverse::refine_detail
