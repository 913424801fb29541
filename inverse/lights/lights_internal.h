// Internal to inverse/lights/: helpers shared between its source files. Not installed and not
// included from outside this folder (light_estimation.h is the public header).
#pragma once

#include <Eigen/Core>

#include "inverse/lights/normal_equations.h"

namespace genscene::inverse::lights_internal {

// Bytes of two sets (the running total and a round's) of three dense Gram matrices over
// 6 x `voxels` parameters (normal_equations.cpp).
double EquationBytes(double voxels);

// The best uniform lighting, every used parameter x = alpha_c (light_cost.cpp):
//     alpha_c = max(0, 1^T b_c / 1^T G_c 1).
Eigen::Vector3d UniformFit(const NormalEquations& eq);

}  // namespace genscene::inverse::lights_internal
