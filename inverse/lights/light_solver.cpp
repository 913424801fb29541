#include "inverse/lights/light_solver.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "core/check.h"
#include "core/parallel.h"
#include "inverse/lights/light_cost.h"
#include "inverse/lights/lights_internal.h"

namespace genscene::inverse {

namespace {

// Whether every light of `grid` (the voxels and the distant light) is dark.
bool Dark(const VoxelLightGrid& grid) {
  for (int j = 0; j < grid.LightCount(); ++j) {
    if (!(grid.IntensityOf(j).maxCoeff() <= 0.0f)) return false;
  }
  return true;
}

// min_x x^T H x - 2 g^T x + q^T x over lo <= x <= hi by cyclic coordinate descent; `hx` holds H x
// on entry and is kept up to date. Coordinates with H_ii <= 0 (no path reaches them) go to lo.
void CoordinateDescent(const Eigen::MatrixXd& h, const Eigen::VectorXd& g, const Eigen::VectorXd& q,
                       double lo, double hi, int sweeps, Eigen::VectorXd* x, Eigen::VectorXd* hx) {
  const Eigen::Index n = x->size();
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    double change = 0.0, scale = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double hii = h(i, i);
      double value = lo;
      if (hii > 0.0) value = std::clamp((*x)[i] - ((*hx)[i] - g[i] + 0.5 * q[i]) / hii, lo, hi);
      const double delta = value - (*x)[i];
      if (delta != 0.0) {
        hx->noalias() += h.col(i) * delta;
        (*x)[i] = value;
      }
      change = std::max(change, std::abs(delta) * std::sqrt(std::max(hii, 0.0)));
      scale = std::max(scale, std::abs(value) * std::sqrt(std::max(hii, 0.0)));
    }
    if (change <= 1e-9 * scale) break;
  }
}

// The alternating solve of SolveLights: L (voxels x 3) and lambda (voxels x 6), the cost, and
// G_c x_c of the current L, lambda (kept from each evaluation for the next iteration).
class AlternatingSolver {
 public:
  // `distant_first`: a dark grid starts from the distant light's own best fit (the voxels dark)
  // instead of the relaxation over every light.
  AlternatingSolver(const NormalEquations& eq, const LightEstimationOptions& options,
                    const VoxelLightGrid& grid, bool distant_first = false)
      : eq_(eq),
        options_(options),
        cost_(eq, options.penalty_weight, options.penalty_epsilon, options.chroma_weight),
        voxels_(grid.LightCount()),
        grid_voxels_(grid.VoxelCount()),
        energy_(eq.observed_sq[0] + eq.observed_sq[1] + eq.observed_sq[2]),
        n_(static_cast<int>(eq.used.size())) {
    IndexParameters();
    if (Load(grid)) StartFromRelaxation(distant_first ? grid_voxels_ : 0);
  }

  // Up to `iterations` alternating iterations, until the cost decreases less than the tolerance;
  // returns the cost.
  double Run(int iterations, SolveReport* out) {
    double previous = Evaluate(nullptr);
    for (int it = 0; it < iterations; ++it) {
      Iterate();
      const double current = Evaluate(&out->data);
      out->history.push_back(current);
      ++out->iterations;
      const bool done = previous - current <= options_.tolerance * std::abs(previous);
      previous = current;
      if (done) break;
    }
    return previous;
  }

  // Moves: the log penalty's local minima often hold a light one voxel off its place (moving it
  // means switching a second voxel on first, which the activation charge forbids). Each lit
  // voxel, strongest first, tries handing its light (L and lambda) to each of its 6 face
  // neighbours; the solve continues briefly and the move is kept when the cost drops below
  // `best`.
  void Moves(const Eigen::Vector3i& dims, double best, SolveReport* report) {
    for (int pass = 0; pass < options_.move_passes; ++pass) {
      bool improved = false;
      for (int j : Strongest()) {
        if (j >= grid_voxels_) continue;  // the distant light has no neighbours
        const Eigen::Vector3i at(j % dims.x(), j / dims.x() % dims.y(), j / (dims.x() * dims.y()));
        for (int axis = 0; axis < 3; ++axis) {
          for (int step : {-1, 1}) {
            Eigen::Vector3i to = at;
            to[axis] += step;
            if (to[axis] < 0 || to[axis] >= dims[axis] || light_.row(j).sum() <= 0.0) continue;
            const int t = to.x() + dims.x() * (to.y() + dims.y() * to.z());
            improved = TryMove(j, t, &best, report) || improved;
          }
        }
      }
      if (!improved) break;
    }
  }

  // The final cost into `report`; each voxel's lambdas scaled to a maximum of 1 (the same
  // products L lambda) into `grid`.
  void Finish(SolveReport* report, VoxelLightGrid* grid) {
    report->cost = Evaluate(&report->data);
    for (int j = 0; j < voxels_; ++j) {
      const double top = lambda_.row(j).maxCoeff();
      if (top > 0.0 && light_.row(j).sum() > 0.0) {
        light_.row(j) *= top;
        lambda_.row(j) /= top;
      } else {
        light_.row(j).setZero();
      }
      grid->IntensityOf(j) = light_.row(j).transpose().cast<float>();
      for (int k = 0; k < 6; ++k) grid->WeightsOf(j)[k] = static_cast<float>(lambda_(j, k));
    }
  }

 private:
  // The voxel and face of each used parameter. The L step works over the voxels some path
  // reaches (`reached_`): with adaptive refinement they are a few hundred of a finer grid's
  // thousands. eq.used is sorted, so a voxel's parameters are the compact range
  // [slot_begin_[v], slot_begin_[v + 1]).
  void IndexParameters() {
    voxel_of_.resize(static_cast<size_t>(n_));
    face_of_.resize(static_cast<size_t>(n_));
    for (int i = 0; i < n_; ++i) voxel_of_[i] = eq_.used[i] / 6, face_of_[i] = eq_.used[i] % 6;
    is_reached_.assign(static_cast<size_t>(voxels_), false);
    for (int i = 0; i < n_; ++i) {
      GS_CHECK(i == 0 || eq_.used[i] > eq_.used[i - 1]);
      if (reached_.empty() || reached_.back() != voxel_of_[i]) {
        reached_.push_back(voxel_of_[i]);
        slot_begin_.push_back(i);
      }
      is_reached_[voxel_of_[i]] = true;
    }
    slots_ = static_cast<int>(reached_.size());
    slot_begin_.push_back(n_);
  }

  // L and lambda from `grid` (lambda clamped to [0, 1]); true when every voxel is dark.
  bool Load(const VoxelLightGrid& grid) {
    light_.resize(voxels_, 3);
    lambda_.resize(voxels_, 6);
    for (int j = 0; j < voxels_; ++j) {
      light_.row(j) = grid.IntensityOf(j).cast<double>().transpose();
      for (int k = 0; k < 6; ++k)
        lambda_(j, k) = std::clamp<double>(grid.WeightsOf(j)[k], 0.0, 1.0);
    }
    return Dark(grid);
  }

  // A dark start begins from the convex relaxation: the products x = L lambda as free
  // non-negative parameters, per channel
  //     min_x x^T G_c x - 2 b_c^T x,  x >= 0,
  // from the best uniform lighting, then each voxel's 6 x 3 product matrix X_j (faces x channels)
  // reduced to its best rank-1 non-negative factor X_j ~ lambda_j L_j^T by power iteration.
  // With `first_light` > 0 only the lights from it on take part (the others stay dark).
  void StartFromRelaxation(int first_light = 0) {
    const Eigen::Vector3d alpha = lights_internal::UniformFit(eq_);
    Eigen::MatrixXd products = Eigen::MatrixXd::Zero(6 * voxels_, 3);
    std::vector<int> free;
    for (int i = 0; i < n_; ++i) {
      if (voxel_of_[i] >= first_light) free.push_back(i);
    }
    const int m = static_cast<int>(free.size());
    for (int c = 0; c < 3; ++c) {
      const Eigen::MatrixXd gram = m == n_ ? eq_.gram[c] : Eigen::MatrixXd(eq_.gram[c](free, free));
      const Eigen::VectorXd rhs = m == n_ ? eq_.rhs[c] : Eigen::VectorXd(eq_.rhs[c](free));
      Eigen::VectorXd x = Eigen::VectorXd::Constant(m, alpha[c]);
      Eigen::VectorXd gx = gram * x;
      CoordinateDescent(gram, rhs, Eigen::VectorXd::Zero(m), 0.0,
                        std::numeric_limits<double>::infinity(), 20, &x, &gx);
      for (int a = 0; a < m; ++a) products(eq_.used[free[a]], c) = x[a];
    }
    for (int j = 0; j < voxels_; ++j) {
      const Eigen::Matrix<double, 6, 3> x = products.middleRows<6>(6 * j);
      Eigen::Matrix<double, 6, 1> l6 = Eigen::Matrix<double, 6, 1>::Ones();
      Eigen::Vector3d l3 = Eigen::Vector3d::Zero();
      for (int step = 0; step < 20 && x.maxCoeff() > 0.0; ++step) {
        l3 = x.transpose() * l6 / l6.squaredNorm();
        if (l3.squaredNorm() <= 0.0) break;
        l6 = x * l3 / l3.squaredNorm();
      }
      const double top = l6.maxCoeff();
      if (top > 0.0 && l3.maxCoeff() > 0.0) {
        light_.row(j) = (l3 * top).transpose();
        lambda_.row(j) = (l6 / top).transpose();
      } else {
        light_.row(j).setZero();
        lambda_.row(j).setOnes();
      }
    }
  }

  Eigen::VectorXd Pack() const {
    Eigen::VectorXd p(9 * voxels_);
    for (int j = 0; j < voxels_; ++j) {
      p.segment<3>(9 * j) = light_.row(j).transpose();
      p.segment<6>(9 * j + 3) = lambda_.row(j).transpose();
    }
    return p;
  }

  // The cost at the current L, lambda, keeping G_c x_c per channel for the next iteration's
  // dark-voxel faces.
  double Evaluate(double* data) { return cost_.Evaluate(Pack(), nullptr, data, &gx_); }

  // One alternating iteration; `gx_` holds G_c x_c of the current L, lambda on entry.
  void Iterate() {
    FaceDarkVoxels();
    LStep();
    LambdaStep();
  }

  // Dark voxels face where the data pull hardest: lambda = the face k whose products have the
  // most negative data gradient (G x - b summed over the channels). A dark voxel can then
  // switch on as a directional light in the L step; with lambda = 1 on every face it could only
  // switch on as an omnidirectional one, which the data rarely want.
  void FaceDarkVoxels() {
    Eigen::VectorXd pull = Eigen::VectorXd::Zero(n_);
    for (int c = 0; c < 3; ++c) pull += gx_[c] - eq_.rhs[c];
    std::vector<double> best(static_cast<size_t>(voxels_), 0.0);
    std::vector<int> best_face(static_cast<size_t>(voxels_), -1);
    for (int i = 0; i < n_; ++i) {
      const int j = voxel_of_[i];
      if (light_.row(j).sum() > 0.0 || pull[i] >= best[j]) continue;
      best[j] = pull[i];
      best_face[j] = face_of_[i];
    }
    for (int j = 0; j < voxels_; ++j) {
      if (best_face[j] >= 0) {
        lambda_.row(j).setZero();
        lambda_(j, best_face[j]) = 1.0;
      }
    }
  }

  // L step, per channel c: x_p = lambda_p L_j(p)c, so the cost x E is the quadratic
  //     L_c^T H_c L_c - 2 g_c^T L_c + q^T L_c,   H_c = S^T D G_c D S,   g_c = S^T D b_c
  // (D = diag(lambda), S the parameter-to-voxel selection) over L >= 0, where the log penalty
  // is majorised by its tangent at the current s_j: the linear weight q_j = E w / (eps + s_j) on
  // every L_jc. Voxels no path reaches are dark.
  void LStep() {
    for (int j = 0; j < voxels_; ++j) {
      if (!is_reached_[j]) light_.row(j).setZero();
    }
    const double w = options_.penalty_weight;
    Eigen::VectorXd q(slots_);
    for (int v = 0; v < slots_; ++v) {
      q[v] = w > 0.0 ? energy_ * w / (cost_.epsilon() + light_.row(reached_[v]).sum()) : 0.0;
    }
    Eigen::VectorXd lambda_of(n_);
    for (int i = 0; i < n_; ++i) lambda_of[i] = lambda_(voxel_of_[i], face_of_[i]);
    if (cost_.chroma_scale() > 0.0) {
      // The chroma term couples a voxel's channels: one after the other, each seeing the
      // others' latest values.
      for (size_t c = 0; c < 3; ++c) LStepChannel(c, q, lambda_of);
    } else {
      // Channels in parallel, each by one task.
      ParallelFor(
          0, 3, [&](size_t c) { LStepChannel(c, q, lambda_of); }, 1);
    }
  }

  // Cyclic coordinate descent on L_jc with H = S^T D G D S never formed: H_jj is the voxel's
  // 6 x 6 block, (H L)_j = sum_i lambda_i (G x)_i over its parameters, and a change of L_jc adds
  // the voxel's columns of G to G x. A sweep costs O(n) plus O(n) per parameter of a voxel
  // that changes; most stay dark. `gx_[c]` holds G_c x_c (current L, lambda) on entry and after.
  // The chroma term (scale a, target m) adds, with u = L_jc and o the voxel's other channels'
  // sum, E a [((1 - m_c) u - m_c o)^2 + sum_{c' != c} (L_jc' - m_c' (u + o))^2]: to the
  // curvature E a kappa_c, kappa_c = (1 - m_c)^2 + sum_{c' != c} m_c'^2, and to g
  // E a [(1 - m_c) m_c o + sum_{c' != c} m_c' (L_jc' - m_c' o)].
  void LStepChannel(size_t c, const Eigen::VectorXd& q, const Eigen::VectorXd& lambda_of) {
    const Eigen::MatrixXd& gram = eq_.gram[c];
    Eigen::VectorXd& gxc = gx_[c];
    Eigen::VectorXd h(slots_), g(slots_), l(slots_);
    for (int v = 0; v < slots_; ++v) {
      double hvv = 0.0, gv = 0.0;
      for (int a = slot_begin_[v]; a < slot_begin_[v + 1]; ++a) {
        if (lambda_of[a] == 0.0) continue;
        gv += lambda_of[a] * eq_.rhs[c][a];
        for (int b = slot_begin_[v]; b < slot_begin_[v + 1]; ++b)
          hvv += lambda_of[a] * lambda_of[b] * gram(a, b);
      }
      h[v] = hvv;
      g[v] = gv;
      l[v] = light_(reached_[v], c);
    }
    // The chroma term's curvature and linear part per voxel (the other channels held).
    const double a = energy_ * cost_.chroma_scale();
    const Eigen::Vector3d& m = cost_.chroma_target();
    Eigen::VectorXd hc = Eigen::VectorXd::Zero(slots_), gc = Eigen::VectorXd::Zero(slots_);
    if (a > 0.0) {
      double kappa = (1.0 - m[c]) * (1.0 - m[c]);
      for (size_t o = 0; o < 3; ++o) kappa += o == c ? 0.0 : m[o] * m[o];
      for (int v = 0; v < slots_; ++v) {
        const int j = reached_[v];
        double others = 0.0;
        for (size_t o = 0; o < 3; ++o) others += o == c ? 0.0 : light_(j, o);
        double lin = (1.0 - m[c]) * m[c] * others;
        for (size_t o = 0; o < 3; ++o)
          if (o != c) lin += m[o] * (light_(j, o) - m[o] * others);
        hc[v] = a * kappa;
        gc[v] = a * lin;
      }
    }
    for (int sweep = 0; sweep < 10; ++sweep) {
      double change = 0.0, scale = 0.0;
      for (int v = 0; v < slots_; ++v) {
        double value = 0.0;
        if (h[v] > 0.0) {
          double hl = 0.0;
          for (int a = slot_begin_[v]; a < slot_begin_[v + 1]; ++a) hl += lambda_of[a] * gxc[a];
          value = std::max(0.0,
                           l[v] - (hl + hc[v] * l[v] - g[v] - gc[v] + 0.5 * q[v]) / (h[v] + hc[v]));
        }
        const double delta = value - l[v];
        if (delta != 0.0) {
          for (int a = slot_begin_[v]; a < slot_begin_[v + 1]; ++a) {
            if (lambda_of[a] != 0.0) gxc.noalias() += (lambda_of[a] * delta) * gram.col(a);
          }
          l[v] = value;
        }
        change = std::max(change, std::abs(delta) * std::sqrt(std::max(h[v], 0.0)));
        scale = std::max(scale, std::abs(value) * std::sqrt(std::max(h[v], 0.0)));
      }
      if (change <= 1e-9 * scale) break;
    }
    for (int v = 0; v < slots_; ++v) light_(reached_[v], c) = l[v];
  }

  // lambda step over the parameters of lit voxels: x_p = L_j(p)c lambda_p, so the cost x E is
  //     lambda^T H lambda - 2 g^T lambda,   H = sum_c D_c G_c D_c,   g = sum_c D_c b_c
  // (D_c = diag(L_j(p)c)) over 0 <= lambda <= 1; the penalty does not depend on lambda.
  void LambdaStep() {
    std::vector<int> active;
    for (int i = 0; i < n_; ++i) {
      if (light_.row(voxel_of_[i]).sum() > 0.0) active.push_back(i);
    }
    const int m = static_cast<int>(active.size());
    if (m == 0) return;
    // The channels' terms in parallel and added in order.
    std::array<Eigen::MatrixXd, 3> hc;
    std::array<Eigen::VectorXd, 3> gc;
    ParallelFor(
        0, 3,
        [&](size_t c) {
          Eigen::VectorXd l(m);
          for (int a = 0; a < m; ++a) l[a] = light_(voxel_of_[active[a]], c);
          hc[c] = l.asDiagonal() * eq_.gram[c](active, active) * l.asDiagonal();
          gc[c] = l.cwiseProduct(eq_.rhs[c](active));
        },
        1);
    Eigen::MatrixXd h = hc[0] + hc[1] + hc[2];
    Eigen::VectorXd g = gc[0] + gc[1] + gc[2], x(m);
    for (int a = 0; a < m; ++a) x[a] = lambda_(voxel_of_[active[a]], face_of_[active[a]]);
    Eigen::VectorXd hx = h * x;
    CoordinateDescent(h, g, Eigen::VectorXd::Zero(m), 0.0, 1.0, 5, &x, &hx);
    for (int a = 0; a < m; ++a) lambda_(voxel_of_[active[a]], face_of_[active[a]]) = x[a];
  }

  // The lit voxels, strongest (L summed x lambda summed) first, move_voxels at most.
  std::vector<int> Strongest() const {
    std::vector<std::pair<double, int>> lit;
    for (int j = 0; j < voxels_; ++j) {
      const double power = light_.row(j).sum() * lambda_.row(j).sum();
      if (power > 0.0) lit.emplace_back(-power, j);
    }
    std::sort(lit.begin(), lit.end());
    if (lit.size() > static_cast<size_t>(options_.move_voxels))
      lit.resize(static_cast<size_t>(options_.move_voxels));
    std::vector<int> out;
    for (const auto& [negative_power, j] : lit) out.push_back(j);
    return out;
  }

  // Hands voxel j's light to voxel t and continues the solve for move_iterations; keeps the move
  // (true) when the cost ends below `best`, else restores L and lambda.
  bool TryMove(int j, int t, double* best, SolveReport* report) {
    const Eigen::MatrixXd keep_light = light_, keep_lambda = lambda_;
    light_.row(t) += light_.row(j);
    lambda_.row(t) = lambda_.row(j);
    light_.row(j).setZero();
    SolveReport trial;
    const double after = Run(options_.move_iterations, &trial);
    report->iterations += trial.iterations;
    if (after < *best) {
      *best = after;
      ++report->moves;
      return true;
    }
    light_ = keep_light;
    lambda_ = keep_lambda;
    return false;
  }

  const NormalEquations& eq_;
  const LightEstimationOptions& options_;
  const LightCost cost_;
  const int voxels_;       // the lights: the voxels, then the distant light when there is one
  const int grid_voxels_;  // the voxels
  const double energy_;
  const int n_;
  std::vector<int> voxel_of_, face_of_;
  std::vector<int> reached_, slot_begin_;
  std::vector<bool> is_reached_;
  int slots_ = 0;
  Eigen::MatrixXd light_;   // L
  Eigen::MatrixXd lambda_;  // lambda
  std::array<Eigen::VectorXd, 3> gx_;
};

}  // namespace

SolveReport SolveLights(const NormalEquations& eq, const LightEstimationOptions& options,
                        VoxelLightGrid* grid) {
  options.Validate();
  GS_CHECK_EQ(6 * grid->LightCount(), eq.parameters);
  // 1. The start: the grid's lights, or the convex relaxation when it is dark. A dark grid with a
  // distant light is also solved from the distant light's own fit (voxels near the scan's edge
  // can stand for light from beyond it, a local minimum the relaxation often lands in), and the
  // lower cost wins.
  const bool dark = Dark(*grid);
  const auto solve = [&](bool distant_first, VoxelLightGrid* out) {
    AlternatingSolver solver(eq, options, *out, distant_first);
    // 2. The alternating iterations.
    SolveReport report;
    const double best = solver.Run(options.max_iterations, &report);
    // 3. Moves of lit voxels to their neighbours.
    if (options.penalty_weight > 0.0) solver.Moves(grid->dims, best, &report);
    // 4. The result.
    solver.Finish(&report, out);
    return report;
  };
  if (!(dark && grid->distant)) return solve(false, grid);
  VoxelLightGrid from_distant = *grid;
  const SolveReport relaxed = solve(false, grid);
  SolveReport distant = solve(true, &from_distant);
  distant.iterations += relaxed.iterations;
  if (!(distant.cost < relaxed.cost)) return relaxed;
  *grid = std::move(from_distant);
  return distant;
}

}  // namespace genscene::inverse
