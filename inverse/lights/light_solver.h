// Step 4 of light estimation, the solve: LightCost minimised by alternating between L and lambda.
// Each block is a bound-constrained quadratic solved exactly by coordinate descent, with the log
// term majorised by its tangent (reweighted L1), so the true cost never increases. Moves then
// hand a lit voxel's light to a neighbour when that lowers the cost.
#pragma once

#include <vector>

#include "core/light_set.h"
#include "inverse/lights/light_options.h"
#include "inverse/lights/normal_equations.h"

namespace genscene::inverse {

struct SolveReport {
  int iterations = 0;
  int moves = 0;                  // light handed to a neighbouring voxel and kept
  double cost = 0.0, data = 0.0;  // final cost and its data part
  std::vector<double> history;    // cost after each iteration
};

// Minimises LightCost from `grid` (initial values; all-dark starts from the best uniform
// lighting) and writes the result into it, each voxel's lambdas scaled to a maximum of 1.
SolveReport SolveLights(const NormalEquations& equations, const LightEstimationOptions& options,
                        VoxelLightGrid* grid);

}  // namespace genscene::inverse
