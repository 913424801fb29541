#include "inverse/lights/normal_equations.h"

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <numeric>
#include <utility>

#include "core/check.h"
#include "core/parallel.h"
#include "inverse/lights/lights_internal.h"

namespace genscene::inverse {

namespace lights_internal {

double EquationBytes(double voxels) {
  const double parameters = 6.0 * voxels;
  return 2.0 * 3.0 * parameters * parameters * sizeof(double);
}

}  // namespace lights_internal

namespace {

// Rows per dense chunk, and the side of the square tiles of G that one task computes.
constexpr int kRows = 2048, kTile = 256;

// The equations are built from the rows a_i (first cache) and b_i (second) of the same pixels,
// through the mean rows and the half differences
//     m_i = (a_i + b_i) / 2,   d_i = (a_i - b_i) / 2,
// per channel c (gamma: the noise correction)
//     G_c = sum_i m_ic m_ic^T - gamma sum_i d_ic d_ic^T,   b_c = sum_i m_ic I_ic,
//     I_c^T I_c = sum_i I_ic^2.
// The halves are independent and alike, so E[m m^T] = E[m] E[m]^T + Var(m) and E[d d^T] = Var(m):
// gamma = 1 takes the coefficients' noise out of G (G = (A^T B + B^T A) / 2). When both caches
// are one (FromCache), d = 0 and G is the plain Gram matrix.

// Parameter -> compact index (-1: no pixel touches it); the touched parameters, sorted, go to
// eq->used.
std::vector<int> CompactIndices(const LightCache& first, const LightCache& second,
                                NormalEquations* eq) {
  std::vector<int> compact(static_cast<size_t>(eq->parameters), -1);
  for (const LightCache* cache : {&first, &second}) {
    for (int32_t p : cache->index) compact[p] = 0;
  }
  for (int p = 0; p < eq->parameters; ++p) {
    if (compact[p] == 0) {
      compact[p] = static_cast<int>(eq->used.size());
      eq->used.push_back(p);
    }
  }
  return compact;
}

// The compact parameters of `eq` that `known` holds (`known_at`: its compact index there, else
// -1) and the others (`fresh`): only the entries of G with a fresh parameter are computed.
// Without `known` every parameter is fresh.
void SplitKnown(const NormalEquations& eq, const NormalEquations* known, std::vector<int>* known_at,
                std::vector<int>* fresh) {
  const int n = static_cast<int>(eq.used.size());
  known_at->assign(static_cast<size_t>(n), -1);
  if (known) {
    GS_CHECK_EQ(known->parameters, eq.parameters);
    GS_CHECK_EQ(known->pixels, eq.pixels);
    for (int i = 0; i < n; ++i) {
      const auto it = std::lower_bound(known->used.begin(), known->used.end(), eq.used[i]);
      if (it != known->used.end() && *it == eq.used[i]) {
        (*known_at)[i] = static_cast<int>(it - known->used.begin());
      } else {
        fresh->push_back(i);
      }
    }
  } else {
    fresh->resize(static_cast<size_t>(n));
    std::iota(fresh->begin(), fresh->end(), 0);
  }
}

// The tiles (a, b), a <= b, of the upper triangle of an n x n matrix.
std::vector<std::pair<int, int>> UpperTilePairs(int n) {
  const int tiles = (n + kTile - 1) / kTile;
  std::vector<std::pair<int, int>> tile_pairs;
  for (int a = 0; a < tiles; ++a) {
    for (int b = a; b < tiles; ++b) tile_pairs.emplace_back(a, b);
  }
  return tile_pairs;
}

// Per row, the merged entries of both halves: compact indices (sorted), m_i and d_i.
struct SparseRows {
  std::vector<size_t> begin{0};
  std::vector<int> index;
  std::vector<Eigen::Vector3f> mean, half_difference;
};

SparseRows MergeSparseRows(const LightCache& first, const LightCache& second,
                           const std::vector<int>& compact, size_t pixels) {
  const bool same = &first == &second;
  SparseRows rows;
  for (size_t i = 0; i < pixels; ++i) {
    size_t a = first.row_begin[i], b = second.row_begin[i];
    const size_t a_end = first.row_begin[i + 1], b_end = same ? b : second.row_begin[i + 1];
    while (a < a_end || b < b_end) {
      const int32_t pa = a < a_end ? first.index[a] : INT32_MAX,
                    pb = b < b_end ? second.index[b] : INT32_MAX;
      const int32_t p = std::min(pa, pb);
      Eigen::Vector3f ca = Eigen::Vector3f::Zero(), cb = Eigen::Vector3f::Zero();
      if (pa == p) ca = first.coefficient[a++];
      if (pb == p) cb = second.coefficient[b++];
      if (same) cb = ca;
      rows.index.push_back(compact[p]);
      rows.mean.push_back(0.5f * (ca + cb));
      rows.half_difference.push_back(0.5f * (ca - cb));
    }
    rows.begin.push_back(rows.index.size());
  }
  return rows;
}

// The normal equations from sparse rows: per tile of G, the products of each row's entries that
// fall in it. Cost sum_i nnz_i^2 instead of pixels x n^2.
void FillSparse(const LightCache& first, const LightCache& second, double correction,
                const std::vector<int>& compact, const std::vector<std::pair<int, int>>& tile_pairs,
                int tile, NormalEquations* eq) {
  const int n = static_cast<int>(eq->used.size());
  const SparseRows rows = MergeSparseRows(first, second, compact, eq->pixels);
  const std::vector<size_t>& begin = rows.begin;
  const std::vector<int>& index = rows.index;
  const std::vector<Eigen::Vector3f>& mean = rows.mean;
  const std::vector<Eigen::Vector3f>& half_difference = rows.half_difference;
  for (int c = 0; c < 3; ++c) {
    eq->gram[c] = Eigen::MatrixXd::Zero(n, n);
    eq->rhs[c] = Eigen::VectorXd::Zero(n);
    eq->observed_sq[c] = 0.0;
  }
  // b_c = sum_i m_ic I_ic and I_c^T I_c, row by row, in total and per view.
  for (size_t i = 0; i < eq->pixels; ++i) {
    const Eigen::Vector3d observed = first.pixels[i].observed.cast<double>();
    const size_t view = static_cast<size_t>(first.pixels[i].view);
    for (int c = 0; c < 3; ++c) {
      eq->observed_sq[c] += observed[c] * observed[c];
      eq->view_observed_sq[view][c] += observed[c] * observed[c];
    }
    for (size_t e = begin[i]; e < begin[i + 1]; ++e) {
      for (int c = 0; c < 3; ++c) {
        eq->rhs[c][index[e]] += static_cast<double>(mean[e][c]) * observed[c];
        eq->view_rhs[view][c][index[e]] += static_cast<double>(mean[e][c]) * observed[c];
      }
    }
  }
  // G_c(p, q) += m_ip m_iq - gamma d_ip d_iq over the upper triangle, one task per tile.
  ParallelFor(
      0, tile_pairs.size(),
      [&](size_t t) {
        const auto [ta, tb] = tile_pairs[t];
        const int a_lo = ta * tile, a_hi = a_lo + tile, b_lo = tb * tile, b_hi = b_lo + tile;
        for (size_t i = 0; i < eq->pixels; ++i) {
          const auto row = index.begin() + static_cast<std::ptrdiff_t>(begin[i]);
          const auto row_end = index.begin() + static_cast<std::ptrdiff_t>(begin[i + 1]);
          const auto a0 = std::lower_bound(row, row_end, a_lo),
                     a1 = std::lower_bound(a0, row_end, a_hi);
          const auto b0 = std::lower_bound(row, row_end, b_lo),
                     b1 = std::lower_bound(b0, row_end, b_hi);
          for (auto ia = a0; ia != a1; ++ia) {
            const size_t ea = static_cast<size_t>(ia - index.begin());
            for (auto ib = std::max(b0, ia); ib != b1; ++ib) {
              const size_t eb = static_cast<size_t>(ib - index.begin());
              for (int c = 0; c < 3; ++c) {
                eq->gram[c](*ia, *ib) += static_cast<double>(mean[ea][c]) * mean[eb][c] -
                                         correction * static_cast<double>(half_difference[ea][c]) *
                                             half_difference[eb][c];
              }
            }
          }
        }
      },
      1);
  for (int c = 0; c < 3; ++c)
    eq->gram[c].triangularView<Eigen::StrictlyLower>() = eq->gram[c].transpose();
}

// The normal equations from dense rows: per channel, the rows in chunks of kRows as dense
// matrices M (mean rows) and D (half differences), G_c = sum over the chunks of
// M^T M - gamma D^T D by tiles. Each tile is written by one task, chunks in a fixed order, so the
// sums do not depend on the thread count. With `known` only the columns of the fresh parameters
// are computed and the rest of G is taken from it.
class DenseGram {
 public:
  DenseGram(const LightCache& first, const LightCache& second, double correction,
            const std::vector<int>& compact, const std::vector<int>& known_at,
            const std::vector<int>& fresh, const NormalEquations* known, NormalEquations* eq)
      : first_(first),
        second_(second),
        correction_(correction),
        compact_(compact),
        known_at_(known_at),
        fresh_(fresh),
        known_(known),
        eq_(*eq),
        n_(static_cast<int>(eq->used.size())),
        same_(&first == &second),
        incremental_(fresh.size() < static_cast<size_t>(n_)),
        tiles_((n_ + kTile - 1) / kTile),
        tile_pairs_(UpperTilePairs(n_)),
        fresh_n_(static_cast<int>(fresh.size())),
        fresh_tiles_((fresh_n_ + kTile - 1) / kTile) {}

  // G_c, b_c and I_c^T I_c of channel c.
  void Channel(int c) {
    Eigen::MatrixXd& gram = eq_.gram[c];
    gram = Eigen::MatrixXd::Zero(n_, n_);
    Eigen::MatrixXd fresh_columns;
    if (incremental_) fresh_columns = Eigen::MatrixXd::Zero(n_, fresh_n_);
    eq_.rhs[c] = Eigen::VectorXd::Zero(n_);
    eq_.observed_sq[c] = 0.0;
    Eigen::MatrixXf mean, half_difference;
    for (size_t begin = 0; begin < eq_.pixels; begin += kRows)
      Chunk(begin, c, &mean, &half_difference, &fresh_columns);
    if (incremental_) Assemble(c, fresh_columns);
    gram.triangularView<Eigen::StrictlyLower>() = gram.transpose();
  }

 private:
  // The rows [begin, begin + kRows) of channel c: I^T I, b += M^T I, G (or the fresh columns)
  // += M^T M - gamma D^T D.
  void Chunk(size_t begin, int c, Eigen::MatrixXf* mean, Eigen::MatrixXf* half_difference,
             Eigen::MatrixXd* fresh_columns) {
    Eigen::MatrixXd& gram = eq_.gram[c];
    const size_t end = std::min(eq_.pixels, begin + kRows);
    Fill(begin, end, c, 1.0f, mean);
    Eigen::VectorXd observed(static_cast<Eigen::Index>(end - begin));
    for (size_t i = begin; i < end; ++i)
      observed[static_cast<Eigen::Index>(i - begin)] = first_.pixels[i].observed[c];
    eq_.observed_sq[c] += observed.squaredNorm();
    eq_.rhs[c] += mean->cast<double>().transpose() * observed;
    // Per view: the runs of rows of one view (pixels are sampled view by view).
    for (size_t run = begin; run < end;) {
      const int view = first_.pixels[run].view;
      size_t run_end = run + 1;
      while (run_end < end && first_.pixels[run_end].view == view) ++run_end;
      const Eigen::Index at = static_cast<Eigen::Index>(run - begin),
                         rows = static_cast<Eigen::Index>(run_end - run);
      eq_.view_observed_sq[static_cast<size_t>(view)][c] +=
          observed.segment(at, rows).squaredNorm();
      eq_.view_rhs[static_cast<size_t>(view)][c] +=
          mean->middleRows(at, rows).cast<double>().transpose() * observed.segment(at, rows);
      run = run_end;
    }
    if (incremental_) {
      AccumulateFresh(*mean, 1.0, fresh_columns);
    } else {
      Accumulate(*mean, 1.0, &gram);
    }
    if (!same_ && correction_ > 0.0) {
      Fill(begin, end, c, -1.0f, half_difference);
      if (incremental_) {
        AccumulateFresh(*half_difference, -correction_, fresh_columns);
      } else {
        Accumulate(*half_difference, -correction_, &gram);
      }
    }
  }

  // Dense rows of one chunk: sign +1 gives the mean rows (a + b) / 2, -1 the half differences.
  void Fill(size_t begin, size_t end, int c, float sign, Eigen::MatrixXf* m) const {
    *m = Eigen::MatrixXf::Zero(static_cast<Eigen::Index>(end - begin), n_);
    for (const LightCache* cache : {&first_, &second_}) {
      const float w = cache == &first_ ? 0.5f : 0.5f * sign;
      for (size_t i = begin; i < end; ++i) {
        for (size_t e = cache->row_begin[i]; e < cache->row_begin[i + 1]; ++e) {
          (*m)(static_cast<Eigen::Index>(i - begin), compact_[cache->index[e]]) +=
              w * cache->coefficient[e][c];
        }
      }
    }
  }

  // gram += scale M^T M over the upper tiles.
  void Accumulate(const Eigen::MatrixXf& m, double scale, Eigen::MatrixXd* gram) const {
    ParallelFor(
        0, tile_pairs_.size(),
        [&](size_t t) {
          const auto [ta, tb] = tile_pairs_[t];
          const int ca = ta * kTile, cb = tb * kTile;
          const int wa = std::min(kTile, n_ - ca), wb = std::min(kTile, n_ - cb);
          const Eigen::MatrixXf block = m.middleCols(ca, wa).transpose() * m.middleCols(cb, wb);
          gram->block(ca, cb, wa, wb) += scale * block.cast<double>();
        },
        1);
  }

  // x += scale M^T M[:, fresh], by tiles of x.
  void AccumulateFresh(const Eigen::MatrixXf& m, double scale, Eigen::MatrixXd* x) const {
    const Eigen::MatrixXf m_fresh = m(Eigen::all, fresh_);
    ParallelFor(
        0, static_cast<size_t>(tiles_) * fresh_tiles_,
        [&](size_t t) {
          const int ta = static_cast<int>(t) / fresh_tiles_,
                    tb = static_cast<int>(t) % fresh_tiles_;
          const int ca = ta * kTile, cb = tb * kTile;
          const int wa = std::min(kTile, n_ - ca), wb = std::min(kTile, fresh_n_ - cb);
          const Eigen::MatrixXf block =
              m.middleCols(ca, wa).transpose() * m_fresh.middleCols(cb, wb);
          x->block(ca, cb, wa, wb) += scale * block.cast<double>();
        },
        1);
  }

  // The upper triangle of G_c: the entries between two known parameters from `known`, those with
  // a fresh one from `fresh_columns`.
  void Assemble(int c, const Eigen::MatrixXd& fresh_columns) {
    Eigen::MatrixXd& gram = eq_.gram[c];
    for (int a = 0; a < n_; ++a) {
      if (known_at_[a] < 0) continue;
      for (int b = a; b < n_; ++b) {
        if (known_at_[b] >= 0) gram(a, b) = known_->gram[c](known_at_[a], known_at_[b]);
      }
    }
    for (int f = 0; f < fresh_n_; ++f) {
      for (int a = 0; a <= fresh_[f]; ++a) gram(a, fresh_[f]) = fresh_columns(a, f);
      for (int b = fresh_[f] + 1; b < n_; ++b) gram(fresh_[f], b) = fresh_columns(b, f);
    }
  }

  const LightCache &first_, &second_;
  const double correction_;
  const std::vector<int>& compact_;
  const std::vector<int>& known_at_;
  const std::vector<int>& fresh_;
  const NormalEquations* known_;
  NormalEquations& eq_;
  const int n_;
  const bool same_, incremental_;
  const int tiles_;
  const std::vector<std::pair<int, int>> tile_pairs_;
  const int fresh_n_, fresh_tiles_;
};

// `from`'s equations over the parameters `merged` (a superset of from.used), zero elsewhere.
void Expand(const NormalEquations& from, const std::vector<int>& merged,
            std::array<Eigen::MatrixXd, 3>* gram, std::array<Eigen::VectorXd, 3>* rhs,
            std::vector<std::array<Eigen::VectorXd, 3>>* view_rhs) {
  std::vector<int> at(from.used.size());
  for (size_t i = 0; i < from.used.size(); ++i) {
    at[i] = static_cast<int>(std::lower_bound(merged.begin(), merged.end(), from.used[i]) -
                             merged.begin());
  }
  const int n = static_cast<int>(merged.size());
  for (int c = 0; c < 3; ++c) {
    (*gram)[c] = Eigen::MatrixXd::Zero(n, n);
    (*rhs)[c] = Eigen::VectorXd::Zero(n);
    for (auto& r : *view_rhs) r[c] = Eigen::VectorXd::Zero(n);
    for (size_t b = 0; b < at.size(); ++b) {
      (*rhs)[c][at[b]] = from.rhs[c][static_cast<Eigen::Index>(b)];
      for (size_t v = 0; v < from.view_rhs.size(); ++v)
        (*view_rhs)[v][c][at[b]] = from.view_rhs[v][c][static_cast<Eigen::Index>(b)];
      for (size_t a = 0; a < at.size(); ++a) {
        (*gram)[c](at[a], at[b]) =
            from.gram[c](static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
      }
    }
  }
}

}  // namespace

double NormalEquationsBoundBytes(int dims) {
  return lights_internal::EquationBytes(static_cast<double>(dims) * dims * dims);
}

NormalEquations NormalEquations::FromCache(const LightCache& cache) {
  return FromCaches(cache, cache, 0.0);
}

NormalEquations NormalEquations::FromCaches(const LightCache& first, const LightCache& second,
                                            double correction, const NormalEquations* known) {
  GS_CHECK_EQ(first.parameters, second.parameters);
  GS_CHECK_EQ(first.pixels.size(), second.pixels.size());
  NormalEquations eq;
  eq.parameters = first.parameters;
  eq.pixels = first.pixels.size();
  // 1. The parameters some pixel touches, in compact indices.
  const std::vector<int> compact = CompactIndices(first, second, &eq);
  const int n = static_cast<int>(eq.used.size());
  int views = 0;
  for (const SampledPixel& p : first.pixels) views = std::max(views, p.view + 1);
  eq.view_rhs.resize(static_cast<size_t>(views));
  for (auto& r : eq.view_rhs)
    for (Eigen::VectorXd& channel : r) channel = Eigen::VectorXd::Zero(n);
  eq.view_observed_sq.assign(static_cast<size_t>(views), Eigen::Vector3d::Zero());
  const bool same = &first == &second;
  // 2. Which of them `known` holds.
  std::vector<int> known_at, fresh;
  SplitKnown(eq, known, &known_at, &fresh);
  // 3. Sparse rows (few entries per row): products of the entries, always computed whole.
  size_t nonzeros = 0;
  for (const LightCache* cache : {&first, &second}) nonzeros += cache->NonZeros();
  if (static_cast<double>(nonzeros) <
      0.2 * static_cast<double>(n) * static_cast<double>(eq.pixels)) {
    FillSparse(first, second, same ? 0.0 : correction, compact, UpperTilePairs(n), kTile, &eq);
    return eq;
  }
  // 4. Dense rows: per channel, by chunks of rows and tiles of G.
  DenseGram dense(first, second, correction, compact, known_at, fresh, known, &eq);
  for (int c = 0; c < 3; ++c) dense.Channel(c);
  return eq;
}

void NormalEquations::Add(const NormalEquations& other) {
  GS_CHECK_EQ(parameters, other.parameters);
  const size_t views = std::max(view_rhs.size(), other.view_rhs.size());
  view_observed_sq.resize(views, Eigen::Vector3d::Zero());
  for (size_t v = 0; v < other.view_observed_sq.size(); ++v)
    view_observed_sq[v] += other.view_observed_sq[v];
  if (used == other.used) {  // the usual case: add in place, no third copy
    const Eigen::Index n = static_cast<Eigen::Index>(used.size());
    view_rhs.resize(
        views, std::array<Eigen::VectorXd, 3>{Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n),
                                              Eigen::VectorXd::Zero(n)});
    for (int c = 0; c < 3; ++c) {
      gram[c] += other.gram[c];
      rhs[c] += other.rhs[c];
      observed_sq[c] += other.observed_sq[c];
      for (size_t v = 0; v < other.view_rhs.size(); ++v) view_rhs[v][c] += other.view_rhs[v][c];
    }
    pixels += other.pixels;
    return;
  }
  std::vector<int> merged;
  std::set_union(used.begin(), used.end(), other.used.begin(), other.used.end(),
                 std::back_inserter(merged));
  std::array<Eigen::MatrixXd, 3> g1, g2;
  std::array<Eigen::VectorXd, 3> r1, r2;
  std::vector<std::array<Eigen::VectorXd, 3>> v1(views), v2(views);
  Expand(*this, merged, &g1, &r1, &v1);
  Expand(other, merged, &g2, &r2, &v2);
  for (int c = 0; c < 3; ++c) {
    gram[c] = g1[c] + g2[c];
    rhs[c] = r1[c] + r2[c];
    observed_sq[c] += other.observed_sq[c];
    for (size_t v = 0; v < views; ++v) v1[v][c] += v2[v][c];
  }
  view_rhs = std::move(v1);
  used = std::move(merged);
  pixels += other.pixels;
}

void NormalEquations::ScaleObserved(const std::vector<Eigen::Vector3d>& scale) {
  GS_CHECK(scale.size() >= view_rhs.size());
  for (int c = 0; c < 3; ++c) {
    rhs[c] = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(used.size()));
    observed_sq[c] = 0.0;
    for (size_t v = 0; v < view_rhs.size(); ++v) {
      rhs[c] += scale[v][c] * view_rhs[v][c];
      observed_sq[c] += scale[v][c] * scale[v][c] * view_observed_sq[v][c];
    }
  }
}

}  // namespace genscene::inverse
