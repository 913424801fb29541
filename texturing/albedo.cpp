#include "texturing/albedo.h"

#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "core/check.h"
#include "core/color.h"
#include "core/disjoint_sets.h"

namespace genscene::texturing {

namespace {
constexpr double kMinEdgeConfidence = 0.01;  // boundary edges less sure than this are left out
constexpr double kNeutralShare = 0.1;        // white balance: modes with this share at least
}  // namespace

void AlbedoOptions::Validate() const {
  RequireRange("chroma_bandwidth", chroma_bandwidth, 1e-3, 0.5);
  RequireRange("min_mode_fraction", min_mode_fraction, 0.0, 0.5);
  RequireRange("dark_fraction", dark_fraction, 0.0, 1.0);
  RequireRange("min_piece_texels", min_piece_texels, 1, 1000000);
  RequireRange("merge_tolerance", merge_tolerance, 0.0, 10.0);
  RequireRange("max_albedo", max_albedo, 1e-3, 1.0);
  RequireRange("prior_weight", prior_weight, 0.0, 1e6);
  RequireRange("neutral_distance", neutral_distance, 0.0, 1.0);
}

namespace {

constexpr float kTiny = 1e-8f;

Eigen::Vector2d Chroma(const Eigen::Vector3f& c) {
  const double sum = std::max(1e-12, static_cast<double>(c.sum()));
  return Eigen::Vector2d(c.x() / sum, c.y() / sum);
}

// Mean shift over a weighted 2D histogram of chromaticities (step 1 of albedo.h): the surviving
// modes, heaviest first.
std::vector<Eigen::Vector2d> ChromaModes(const std::vector<Eigen::Vector2d>& chroma,
                                         const std::vector<uint8_t>& votes, double h,
                                         double min_fraction) {
  const double bin = h / 4.0;
  const int n_bins = static_cast<int>(std::ceil(1.0 / bin)) + 1;
  std::vector<double> weight(static_cast<size_t>(n_bins) * n_bins, 0.0);
  std::vector<Eigen::Vector2d> sum(weight.size(), Eigen::Vector2d::Zero());
  double total = 0.0;
  for (size_t s = 0; s < chroma.size(); ++s) {
    if (!votes[s]) continue;
    const int i = std::clamp(static_cast<int>(chroma[s].x() / bin), 0, n_bins - 1);
    const int j = std::clamp(static_cast<int>(chroma[s].y() / bin), 0, n_bins - 1);
    weight[static_cast<size_t>(j) * n_bins + i] += 1.0;
    sum[static_cast<size_t>(j) * n_bins + i] += chroma[s];
    total += 1.0;
  }
  const int reach = static_cast<int>(std::ceil(h / bin));
  auto shift = [&](const Eigen::Vector2d& x) {
    const int ci = static_cast<int>(x.x() / bin), cj = static_cast<int>(x.y() / bin);
    Eigen::Vector2d acc = Eigen::Vector2d::Zero();
    double w = 0.0;
    for (int j = std::max(0, cj - reach); j <= std::min(n_bins - 1, cj + reach); ++j) {
      for (int i = std::max(0, ci - reach); i <= std::min(n_bins - 1, ci + reach); ++i) {
        const size_t b = static_cast<size_t>(j) * n_bins + i;
        if (weight[b] == 0.0) continue;
        const Eigen::Vector2d centre = sum[b] / weight[b];
        if ((centre - x).norm() > h) continue;
        acc += sum[b];
        w += weight[b];
      }
    }
    return w > 0.0 ? Eigen::Vector2d(acc / w) : x;
  };
  struct Mode {
    Eigen::Vector2d at;
    double mass;
  };
  std::vector<Mode> modes;
  for (size_t b = 0; b < weight.size(); ++b) {
    if (weight[b] == 0.0) continue;
    Eigen::Vector2d x = sum[b] / weight[b];
    for (int it = 0; it < 100; ++it) {
      const Eigen::Vector2d next = shift(x);
      const bool done = (next - x).norm() < 1e-5;
      x = next;
      if (done) break;
    }
    bool merged = false;
    for (Mode& m : modes) {
      if ((m.at - x).norm() < 0.5 * h) {
        m.at = (m.at * m.mass + x * weight[b]) / (m.mass + weight[b]);
        m.mass += weight[b];
        merged = true;
        break;
      }
    }
    if (!merged) modes.push_back({x, weight[b]});
  }
  std::stable_sort(modes.begin(), modes.end(),
                   [](const Mode& a, const Mode& b) { return a.mass > b.mass; });
  std::vector<Eigen::Vector2d> out;
  for (const Mode& m : modes) {
    if (m.mass >= min_fraction * total || out.empty()) out.push_back(m.at);
  }
  return out;
}

}  // namespace

AlbedoResult EstimateAlbedo(const MeshColors& texture, const std::vector<int32_t>& view_counts,
                            const AlbedoOptions& o) {
  o.Validate();
  const size_t n = texture.SampleCount();
  if (n == 0) throw Error("albedo: the texture has no samples");
  if (!view_counts.empty() && view_counts.size() != n) {
    throw Error(Format("albedo: ", view_counts.size(), " view counts for ", n, " texels"));
  }
  std::vector<Eigen::Vector3f> color = texture.colors();  // white-balanced below
  std::vector<uint8_t> observed(n, 1);
  size_t n_observed = n;
  if (!view_counts.empty()) {
    n_observed = 0;
    for (size_t s = 0; s < n; ++s) n_observed += (observed[s] = view_counts[s] > 0);
  }
  if (n_observed == 0) throw Error("albedo: no texel of the texture was observed by a keyframe");

  // 1. Chromaticity classes.
  std::vector<float> lum(n);
  std::vector<Eigen::Vector2d> chroma(n);
  std::vector<uint8_t> dark(n), votes(n);
  std::vector<Eigen::Vector2d> modes;
  const auto find_modes = [&] {
    std::vector<float> observed_lum;
    for (size_t s = 0; s < n; ++s) {
      lum[s] = std::max(0.0f, Luminance(color[s]));
      if (observed[s]) observed_lum.push_back(lum[s]);
    }
    const size_t half = observed_lum.size() / 2;
    std::nth_element(observed_lum.begin(), observed_lum.begin() + half, observed_lum.end());
    const float dark_level = static_cast<float>(o.dark_fraction) * observed_lum[half];
    for (size_t s = 0; s < n; ++s) {
      dark[s] = lum[s] <= dark_level || color[s].minCoeff() < 0.0f;
      chroma[s] = Chroma(color[s].cwiseMax(0.0f));
      votes[s] = observed[s] && !dark[s];
    }
    modes = ChromaModes(chroma, votes, o.chroma_bandwidth, o.min_mode_fraction);
  };
  const auto nearest_mode = [&](size_t s) {
    int best = 0;
    for (int m = 1; m < static_cast<int>(modes.size()); ++m) {
      if ((chroma[s] - modes[m]).squaredNorm() < (chroma[s] - modes[best]).squaredNorm()) best = m;
    }
    return best;
  };
  find_modes();
  // White balance: the mode nearest to neutral among those holding at least kNeutralShare of the
  // voting texels is taken as a white or grey surface when within neutral_distance of neutral.
  // Its tint is the light's: every texel's colour is divided by it per channel, and the modes
  // are found again (under a tinted light, colours crowd toward the light's chromaticity).
  AlbedoResult result;
  if (o.neutral_distance > 0.0) {
    std::vector<size_t> class_votes(modes.size(), 0);
    size_t voting = 0;
    for (size_t s = 0; s < n; ++s) {
      if (!votes[s]) continue;
      ++class_votes[nearest_mode(s)];
      ++voting;
    }
    const Eigen::Vector2d neutral(1.0 / 3.0, 1.0 / 3.0);
    int nearest = -1;
    for (size_t k = 0; k < modes.size(); ++k) {
      if (static_cast<double>(class_votes[k]) < kNeutralShare * static_cast<double>(voting))
        continue;
      if (nearest < 0 || (modes[k] - neutral).norm() < (modes[nearest] - neutral).norm())
        nearest = static_cast<int>(k);
    }
    if (nearest >= 0 && (modes[nearest] - neutral).norm() <= o.neutral_distance) {
      const Eigen::Vector2d& m = modes[nearest];
      const Eigen::Vector3f tint =
          3.0f * Eigen::Vector3f(m.x(), m.y(), std::max(1e-3, 1.0 - m.x() - m.y()));
      result.stats.white_balance = tint.cwiseInverse();
      for (Eigen::Vector3f& c : color) c = c.cwiseQuotient(tint);
      find_modes();
    }
  }
  const int dark_class = static_cast<int>(modes.size());
  std::vector<int> klass(n);
  bool any_dark = false;
  for (size_t s = 0; s < n; ++s) {
    if (dark[s]) {
      klass[s] = dark_class;
      any_dark = true;
      continue;
    }
    klass[s] = nearest_mode(s);
  }

  // 2. Connected pieces of one class; small pieces join their strongest neighbour.
  const auto pairs = texture.SampleNeighbours();
  std::vector<uint32_t> piece_of(n);
  int n_pieces = 0;
  for (int round = 0; round < 4; ++round) {
    DisjointSets sets(n);
    for (const auto& [a, b] : pairs) {
      if (klass[a] == klass[b]) sets.Union(a, b);
    }
    std::vector<int> index(n, -1);
    n_pieces = 0;
    for (size_t s = 0; s < n; ++s) {
      const uint32_t root = sets.Find(static_cast<uint32_t>(s));
      if (index[root] < 0) index[root] = n_pieces++;
      piece_of[s] = static_cast<uint32_t>(index[root]);
    }
    std::vector<size_t> size(n_pieces, 0);
    for (size_t s = 0; s < n; ++s) ++size[piece_of[s]];
    // For each small piece, the neighbouring piece with the most boundary edges.
    std::vector<std::map<uint32_t, int>> border(n_pieces);
    for (const auto& [a, b] : pairs) {
      const uint32_t pa = piece_of[a], pb = piece_of[b];
      if (pa == pb) continue;
      if (size[pa] < static_cast<size_t>(o.min_piece_texels)) ++border[pa][pb];
      if (size[pb] < static_cast<size_t>(o.min_piece_texels)) ++border[pb][pa];
    }
    std::vector<int> new_class(n_pieces, -1);
    bool changed = false;
    for (int p = 0; p < n_pieces; ++p) {
      if (size[p] >= static_cast<size_t>(o.min_piece_texels) || border[p].empty()) continue;
      uint32_t best = border[p].begin()->first;
      for (const auto& [q, count] : border[p]) {
        if (count > border[p][best] || (count == border[p][best] && size[q] > size[best])) best = q;
      }
      if (size[best] < size[p]) continue;  // join something at least as large
      new_class[p] = static_cast<int>(best);
      changed = true;
    }
    if (!changed) break;
    std::vector<int> piece_class(n_pieces);
    for (size_t s = 0; s < n; ++s) piece_class[piece_of[s]] = klass[s];
    for (size_t s = 0; s < n; ++s) {
      const int target = new_class[piece_of[s]];
      if (target >= 0) klass[s] = piece_class[target];
    }
  }

  // 3. Piece colours and the scale solve.
  std::vector<Eigen::Vector3d> mean(n_pieces, Eigen::Vector3d::Zero());
  std::vector<Eigen::Vector3d> mean_all(n_pieces, Eigen::Vector3d::Zero());
  std::vector<size_t> texels(n_pieces, 0), seen(n_pieces, 0);
  std::vector<int> piece_class(n_pieces);
  for (size_t s = 0; s < n; ++s) {
    const uint32_t p = piece_of[s];
    piece_class[p] = klass[s];
    ++texels[p];
    mean_all[p] += color[s].cast<double>();
    if (observed[s]) mean[p] += color[s].cast<double>(), ++seen[p];
  }
  for (int p = 0; p < n_pieces; ++p) {
    mean[p] = seen[p] > 0 ? Eigen::Vector3d(mean[p] / static_cast<double>(seen[p]))
                          : Eigen::Vector3d(mean_all[p] / static_cast<double>(texels[p]));
    mean[p] = mean[p].cwiseMax(1e-6);
    // The class's mode, not the piece's mean, gives the chromaticity: colour bleeding and
    // coloured shadows pull the mean away from the surface's own colour, the density peak is
    // where the surface is least tinted. Luminance stays the piece's mean.
    if (piece_class[p] < dark_class) {
      const Eigen::Vector2d& m = modes[piece_class[p]];
      const Eigen::Vector3d chroma(m.x(), m.y(), std::max(0.0, 1.0 - m.x() - m.y()));
      const double l_chroma = Luminance(chroma);
      const double l_mean = Luminance(mean[p]);
      if (l_chroma > 1e-9) mean[p] = (chroma * (l_mean / l_chroma)).cwiseMax(1e-6);
    }
  }
  auto log_lum = [](const Eigen::Vector3d& c) { return std::log(std::max(1e-9, Luminance(c))); };
  std::vector<double> log_mean(n_pieces);
  for (int p = 0; p < n_pieces; ++p) log_mean[p] = log_lum(mean[p]);
  // The largest piece of each class anchors the prior.
  std::map<int, int> anchor;
  for (int p = 0; p < n_pieces; ++p) {
    auto it = anchor.find(piece_class[p]);
    if (it == anchor.end() || texels[p] > texels[it->second]) anchor[piece_class[p]] = p;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n_pieces);
  auto add_difference = [&](int p, int q, double target, double w) {  // w (x_p - x_q - target)^2
    triplets.emplace_back(p, p, w);
    triplets.emplace_back(q, q, w);
    triplets.emplace_back(p, q, -w);
    triplets.emplace_back(q, p, -w);
    rhs[p] += w * target;
    rhs[q] -= w * target;
  };
  struct Boundary {
    int p, q;
    double target, weight;
  };
  // A texel whose chromaticity is far from its class's mode (a white wall pink from the red wall
  // beside it, or a texel that mixes both walls where the keyframes disagree by a pixel) says
  // little about its piece's shading: its luminance is the other surface's. Each edge weighs the
  // product of its texels' closeness to their modes, exp(-d^2 / 2 h^2) (h: chroma_bandwidth), and
  // an edge under kMinEdgeConfidence is left out. Near-black texels have no confidence: their
  // chromaticity is noise and their luminance sits at the sensor's floor, where a log ratio is
  // noise too (on TUM fr1/desk they pulled whole walls toward black). Two pieces joined by no
  // edge left are held together by nothing but the gauge: each keeps its own mean observed
  // luminance.
  const double inv_h2 = 1.0 / (2.0 * o.chroma_bandwidth * o.chroma_bandwidth);
  const auto confidence = [&](size_t s) {
    if (klass[s] >= dark_class) return 0.0;
    return std::exp(-(chroma[s] - modes[klass[s]]).squaredNorm() * inv_h2);
  };
  std::vector<Boundary> boundaries;
  for (const auto& [a, b] : pairs) {
    const int p = static_cast<int>(piece_of[a]), q = static_cast<int>(piece_of[b]);
    if (p == q || !observed[a] || !observed[b]) continue;
    const double la = std::log(std::max(1e-9f, lum[a])), lb = std::log(std::max(1e-9f, lum[b]));
    const double weight = confidence(a) * confidence(b);
    if (weight < kMinEdgeConfidence) continue;
    boundaries.push_back({p, q, (la - log_mean[p]) - (lb - log_mean[q]), weight});
    add_difference(p, q, boundaries.back().target, weight);
  }
  for (int p = 0; p < n_pieces; ++p) {
    const int c = anchor[piece_class[p]];
    if (c != p && o.prior_weight > 0.0)
      add_difference(p, c, log_mean[c] - log_mean[p], o.prior_weight);
  }
  for (int p = 0; p < n_pieces; ++p)
    triplets.emplace_back(p, p, 1e-9);  // pins isolated gauges at 0
  Eigen::SparseMatrix<double> normal(n_pieces, n_pieces);
  normal.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  if (solver.info() != Eigen::Success)
    throw Error("albedo: the scale system could not be factorised");
  Eigen::VectorXd x = solver.solve(rhs);
  double weighted = 0.0;
  for (int p = 0; p < n_pieces; ++p) weighted += x[p] * static_cast<double>(texels[p]);
  x.array() -= weighted / static_cast<double>(n);

  AlbedoStats& stats = result.stats;
  stats.chroma_classes = static_cast<int>(modes.size()) + (any_dark ? 1 : 0);
  stats.pieces = n_pieces;
  stats.boundary_edges = boundaries.size();
  double sq = 0.0, weights = 0.0;
  for (const Boundary& b : boundaries) {
    sq += b.weight * std::pow(x[b.p] - x[b.q] - b.target, 2);
    weights += b.weight;
  }
  stats.shading_jump_rms = weights <= 0.0 ? 0.0 : std::sqrt(sq / weights);

  std::vector<Eigen::Vector3d> piece_albedo(n_pieces);
  for (int p = 0; p < n_pieces; ++p) piece_albedo[p] = std::exp(x[p]) * mean[p];

  // Gauge: the 95th percentile (over texels) of the largest albedo channel is max_albedo.
  std::vector<std::pair<double, size_t>> by_max;
  for (int p = 0; p < n_pieces; ++p) by_max.emplace_back(piece_albedo[p].maxCoeff(), texels[p]);
  std::sort(by_max.begin(), by_max.end());
  size_t acc = 0;
  double top = by_max.back().first;
  for (const auto& [value, count] : by_max) {
    acc += count;
    if (acc >= 0.95 * n) {
      top = value;
      break;
    }
  }
  for (Eigen::Vector3d& a : piece_albedo) a = (a * (o.max_albedo / top)).cwiseMin(1.0);

  // 4. Pieces of one class with agreeing albedo are one cluster; largest pieces first.
  std::vector<int> order(n_pieces);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return texels[a] > texels[b]; });
  struct Building {
    int klass;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double lum = 0.0;  // luminance of the first (largest) piece
    size_t texels = 0, observed = 0;
    int pieces = 0;
  };
  std::vector<Building> building;
  std::vector<int> cluster_of_piece(n_pieces);
  for (int p : order) {
    const double l = std::max(1e-9, Luminance(piece_albedo[p]));
    int found = -1;
    for (size_t c = 0; c < building.size(); ++c) {
      if (building[c].klass == piece_class[p] &&
          std::abs(std::log(l / building[c].lum)) <= std::log1p(o.merge_tolerance)) {
        found = static_cast<int>(c);
        break;
      }
    }
    if (found < 0) {
      found = static_cast<int>(building.size());
      building.push_back({piece_class[p]});
      building.back().lum = l;
    }
    Building& b = building[found];
    b.sum += piece_albedo[p] * static_cast<double>(texels[p]);
    b.texels += texels[p];
    b.observed += seen[p];
    ++b.pieces;
    cluster_of_piece[p] = found;
  }
  for (size_t c = 0; c < building.size(); ++c) {
    AlbedoCluster cluster;
    cluster.id = static_cast<int>(c);
    cluster.albedo = (building[c].sum / static_cast<double>(building[c].texels)).cast<float>();
    cluster.chromaticity = cluster.albedo / std::max(kTiny, cluster.albedo.sum());
    cluster.texels = building[c].texels;
    cluster.observed_texels = building[c].observed;
    cluster.pieces = building[c].pieces;
    cluster.dark = building[c].klass == dark_class;
    result.clusters.push_back(cluster);
  }
  // Ids by size (the building order is by the largest piece, which is nearly that).
  std::vector<int> rank(result.clusters.size());
  std::iota(rank.begin(), rank.end(), 0);
  std::stable_sort(rank.begin(), rank.end(), [&](int a, int b) {
    return result.clusters[a].texels > result.clusters[b].texels;
  });
  std::vector<int> new_id(rank.size());
  std::vector<AlbedoCluster> sorted;
  for (size_t i = 0; i < rank.size(); ++i) {
    new_id[rank[i]] = static_cast<int>(i);
    sorted.push_back(result.clusters[rank[i]]);
    sorted.back().id = static_cast<int>(i);
  }
  result.clusters = std::move(sorted);

  result.albedo = texture;
  result.albedo.labels().assign(n, 0);
  for (size_t s = 0; s < n; ++s) {
    const int id = new_id[cluster_of_piece[piece_of[s]]];
    result.albedo.labels()[s] = id;
    result.albedo.colors()[s] = result.clusters[id].albedo;
  }
  return result;
}

}  // namespace genscene::texturing
