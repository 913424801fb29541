#include "inverse/lights/light_cost.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/check.h"
#include "core/parallel.h"
#include "inverse/lights/lights_internal.h"

namespace genscene::inverse {

namespace lights_internal {

Eigen::Vector3d UniformFit(const NormalEquations& eq) {
  Eigen::Vector3d alpha = Eigen::Vector3d::Zero();
  for (int c = 0; c < 3; ++c) {
    const double denominator = eq.gram[c].sum();
    if (denominator > 0.0) alpha[c] = std::max(0.0, eq.rhs[c].sum() / denominator);
  }
  return alpha;
}

}  // namespace lights_internal

namespace {

// Data term, per channel c, with x_c the products x_p = L_jc lambda_jk of the used parameters
// p = 6 j + k:
//     r_c = |A_c x_c - I_c|^2 = x_c^T G_c x_c - 2 b_c^T x_c + I_c^T I_c,
//     data = (r_r + r_g + r_b) / E,   E = I_r^T I_r + I_g^T I_g + I_b^T I_b.
// Returns r_c and leaves G_c x_c in `gx`. The channels in parallel, each by one task.
std::array<double, 3> ChannelResiduals(const NormalEquations& eq, const Eigen::VectorXd& params,
                                       std::array<Eigen::VectorXd, 3>* gx) {
  const int n = static_cast<int>(eq.used.size());
  std::array<double, 3> part{};
  ParallelFor(
      0, 3,
      [&](size_t c) {
        Eigen::VectorXd x(n);
        for (int i = 0; i < n; ++i) {
          const int j = eq.used[i] / 6, k = eq.used[i] % 6;
          x[i] = params[9 * j + c] * params[9 * j + 3 + k];
        }
        // x is sparse once the penalty has switched most voxels off: then G x is a sum of the
        // columns of the lit parameters, O(n nnz) instead of O(n^2).
        std::vector<int> lit;
        for (int i = 0; i < n; ++i) {
          if (x[i] != 0.0) lit.push_back(i);
        }
        if (4 * lit.size() < static_cast<size_t>(n)) {
          (*gx)[c] = Eigen::VectorXd::Zero(n);
          for (int i : lit) (*gx)[c].noalias() += x[i] * eq.gram[c].col(i);
        } else {
          (*gx)[c].noalias() = eq.gram[c].selfadjointView<Eigen::Upper>() * x;
        }
        part[c] = x.dot((*gx)[c]) - 2.0 * eq.rhs[c].dot(x) + eq.observed_sq[c];
      },
      1);
  return part;
}

// The data term's gradient, with g_c = d data / d x_c = 2 (G_c x_c - b_c) / E, through
// x_p = L_jc lambda_jk:
//     d data / d L_jc = sum_k g_c,p lambda_jk,   d data / d lambda_jk = sum_c g_c,p L_jc.
void AddDataGradient(const NormalEquations& eq, const Eigen::VectorXd& params,
                     const std::array<Eigen::VectorXd, 3>& gx, double energy,
                     Eigen::VectorXd* gradient) {
  const int n = static_cast<int>(eq.used.size());
  for (int c = 0; c < 3; ++c) {
    const Eigen::VectorXd d = 2.0 * (gx[c] - eq.rhs[c]) / energy;
    for (int i = 0; i < n; ++i) {
      const int j = eq.used[i] / 6, k = eq.used[i] % 6;
      (*gradient)[9 * j + c] += d[i] * params[9 * j + 3 + k];
      (*gradient)[9 * j + 3 + k] += d[i] * params[9 * j + c];
    }
  }
}

// The log activation penalty, s_j = L_jr + L_jg + L_jb:
//     penalty = w sum_j log(1 + s_j / eps),   d penalty / d L_jc = w / (eps + s_j).
// Adds the gradient when given.
double Penalty(const Eigen::VectorXd& params, int voxels, double weight, double epsilon,
               Eigen::VectorXd* gradient) {
  double penalty = 0.0;
  for (int j = 0; j < voxels; ++j) {
    const double s = params[9 * j] + params[9 * j + 1] + params[9 * j + 2];
    penalty += weight * std::log1p(s / epsilon);
    if (gradient) {
      for (int c = 0; c < 3; ++c) (*gradient)[9 * j + c] += weight / (epsilon + s);
    }
  }
  return penalty;
}

// The chroma term, r_j = L_j - m s_j (sum_c r_jc = 0):
//     chroma = scale sum_j |r_j|^2,   d chroma / d L_jc = 2 scale (r_jc - m . r_j).
// Adds the gradient when given.
double ChromaPenalty(const Eigen::VectorXd& params, int voxels, const Eigen::Vector3d& m,
                     double scale, Eigen::VectorXd* gradient) {
  double sum = 0.0;
  for (int j = 0; j < voxels; ++j) {
    const Eigen::Vector3d l = params.segment<3>(9 * j);
    const Eigen::Vector3d r = l - m * l.sum();
    sum += r.squaredNorm();
    if (gradient) {
      const double mr = m.dot(r);
      for (int c = 0; c < 3; ++c) (*gradient)[9 * j + c] += 2.0 * scale * (r[c] - mr);
    }
  }
  return scale * sum;
}

}  // namespace

// E = sum_c I_c^T I_c normalises the data term. The activation scale is
//     eps = penalty_epsilon * s_ref,   s_ref = (alpha_r + alpha_g + alpha_b) x voxels reached,
// the summed intensity of the best uniform lighting (UniformFit), which lights every voxel some
// path reaches (with adaptive refinement only the candidates are traced).
LightCost::LightCost(const NormalEquations& equations, double penalty_weight,
                     double penalty_epsilon, double chroma_weight)
    : eq_(equations), weight_(penalty_weight) {
  energy_ = eq_.observed_sq[0] + eq_.observed_sq[1] + eq_.observed_sq[2];
  if (eq_.used.empty()) {
    throw Error(
        "light estimation: no sampled path reaches any voxel (every shadow ray is blocked or faces "
        "away)");
  }
  if (!(energy_ > 0.0)) throw Error("light estimation: the sampled pixels are all black");
  const Eigen::Vector3d alpha = lights_internal::UniformFit(eq_);
  int used_voxels = 0;
  for (size_t i = 0; i < eq_.used.size(); ++i)
    used_voxels += i == 0 || eq_.used[i] / 6 != eq_.used[i - 1] / 6;
  const double s_ref = alpha.sum() * used_voxels;
  epsilon_ = penalty_epsilon * std::max(s_ref, 1e-30);
  if (alpha.sum() > 0.0) chroma_target_ = alpha / alpha.sum();
  if (chroma_weight > 0.0 && s_ref > 0.0) chroma_scale_ = chroma_weight / (s_ref * s_ref);
}

Eigen::VectorXd LightCost::Pack(const VoxelLightGrid& grid) {
  Eigen::VectorXd x(9 * grid.LightCount());
  for (int j = 0; j < grid.LightCount(); ++j) {
    x.segment<3>(9 * j) = grid.IntensityOf(j).cast<double>();
    for (int k = 0; k < 6; ++k) x[9 * j + 3 + k] = grid.WeightsOf(j)[k];
  }
  return x;
}

void LightCost::Unpack(const Eigen::VectorXd& params, VoxelLightGrid* grid) {
  GS_CHECK_EQ(params.size(), 9 * grid->LightCount());
  for (int j = 0; j < grid->LightCount(); ++j) {
    grid->IntensityOf(j) = params.segment<3>(9 * j).cast<float>();
    for (int k = 0; k < 6; ++k) grid->WeightsOf(j)[k] = static_cast<float>(params[9 * j + 3 + k]);
  }
}

// f = data + penalty + chroma (ChannelResiduals, Penalty, ChromaPenalty above).
double LightCost::Evaluate(const Eigen::VectorXd& params, Eigen::VectorXd* gradient, double* data,
                           std::array<Eigen::VectorXd, 3>* gram_x) const {
  const int voxels = eq_.parameters / 6;
  GS_CHECK_EQ(params.size(), 9 * voxels);
  std::array<Eigen::VectorXd, 3> local_gx;
  std::array<Eigen::VectorXd, 3>& gx = gram_x ? *gram_x : local_gx;
  const std::array<double, 3> part = ChannelResiduals(eq_, params, &gx);
  const double data_sum = part[0] + part[1] + part[2];
  if (gradient) {
    *gradient = Eigen::VectorXd::Zero(params.size());
    AddDataGradient(eq_, params, gx, energy_, gradient);
  }
  const double penalty = weight_ > 0.0 ? Penalty(params, voxels, weight_, epsilon_, gradient) : 0.0;
  const double chroma = chroma_scale_ > 0.0
                            ? ChromaPenalty(params, voxels, chroma_target_, chroma_scale_, gradient)
                            : 0.0;
  if (data) *data = data_sum / energy_;
  return data_sum / energy_ + penalty + chroma;
}

}  // namespace genscene::inverse
