// Step 4 of light estimation, the cost: over the normal equations,
//     f(L, lambda) = (1/E) sum_i sum_c (P_ic - I_ic)^2 + w sum_j log(1 + s_j / eps)
//                    + w_chroma sum_j |L_j - m s_j|^2 / s_ref^2,
// E = sum_i sum_c I_ic^2 (so the data term is the squared relative residual), s_j = sum_c L_jc,
// eps = penalty_epsilon * s_ref (s_ref: the summed intensity of the best uniform lighting),
// L >= 0, 0 <= lambda <= 1 (the upper bound fixes the L x lambda scale gauge). The log term
// charges a voxel's first activation and then plateaus (the paper's activation penalty). The
// chroma term pulls every voxel's colour toward one chromaticity m (sum 1), that of the best
// uniform lighting (alpha / sum alpha, UniformFit): a voxel's colour departs from the room's
// light colour only as far as the pixels demand. Its scale s_ref^2 makes a deviation cost what
// a relative residual of the same size costs. Without it the lights mix saturated colours (a red
// voxel beside a blue one) that sum to the right one, which a render sampling one light at a
// time turns into colour noise.
#pragma once

#include <Eigen/Core>
#include <array>

#include "core/light_set.h"
#include "inverse/lights/normal_equations.h"

namespace genscene::inverse {

// The cost f(L, lambda) above over the normal equations. Parameters packed per voxel as
// [L_r, L_g, L_b, lambda_0..lambda_5] (9 per voxel).
class LightCost {
 public:
  LightCost(const NormalEquations& equations, double penalty_weight, double penalty_epsilon,
            double chroma_weight = 0.0);

  static Eigen::VectorXd Pack(const VoxelLightGrid& grid);
  static void Unpack(const Eigen::VectorXd& params, VoxelLightGrid* grid);

  // Cost, its data part (squared relative residual) and, when `gradient` is given, the gradient;
  // `gram_x` receives G_c x_c per channel (x_c: the products L_c lambda of the used parameters).
  // The channels are evaluated in parallel, each by one task (the sums do not depend on threads).
  double Evaluate(const Eigen::VectorXd& params, Eigen::VectorXd* gradient = nullptr,
                  double* data = nullptr, std::array<Eigen::VectorXd, 3>* gram_x = nullptr) const;
  double epsilon() const { return epsilon_; }
  // The chroma term's target m and its weight w_chroma / s_ref^2.
  const Eigen::Vector3d& chroma_target() const { return chroma_target_; }
  double chroma_scale() const { return chroma_scale_; }
  const NormalEquations& equations() const { return eq_; }

 private:
  const NormalEquations& eq_;
  double weight_, epsilon_, energy_;
  Eigen::Vector3d chroma_target_ = Eigen::Vector3d::Constant(1.0 / 3.0);
  double chroma_scale_ = 0.0;
};

}  // namespace genscene::inverse
