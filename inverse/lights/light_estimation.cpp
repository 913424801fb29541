#include "inverse/lights/light_estimation.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>
#include <utility>

#include "core/check.h"
#include "core/color.h"
#include "core/options.h"
#include "core/parallel.h"
#include "core/rng.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on

namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Calls sink(connections, scale) for every vertex of the `paths.spp` paths through `pixel` (see
// VoxelConnections): the coefficients times `scale` summed over all of them estimate the pixel.
// Direct light (the first vertex's connections) comes from the first `direct_paths` of them,
// indirect light from all. Each group's positions in the pixel are a Latin hypercube (stratified in
// x and in y) over the box filter's footprint [u - 0.5, u + 0.5) x [v - 0.5, v + 0.5). Random
// numbers are keyed by (seed, view, pixel).
template <typename Sink>
void WalkPixel(const PathTracer& tracer, const VoxelLightGrid& grid,
               const VoxelSplitting& splitting, const SampledPixel& pixel, const PosedView& view,
               const RenderOptions& paths, int direct_paths, uint64_t seed, const Sink& sink,
               RayCounts* rays) {
  const CameraIntrinsics& k = view.intrinsics;
  const Eigen::Matrix3f rotation = view.world_from_camera.rotation().cast<float>();
  const Eigen::Vector3f eye = view.world_from_camera.translation().cast<float>();
  const uint64_t stream = (static_cast<uint64_t>(pixel.view) << 32) |
                          static_cast<uint64_t>(pixel.v * k.width + pixel.u);
  const int total = paths.spp, direct = std::clamp(direct_paths, 1, total);
  const float scale = 1.0f / static_cast<float>(total);
  const VoxelCoefficientSink scaled = [&](const VoxelConnections& connections) {
    sink(connections, scale);
  };
  // Latin hypercube per group: path s of a group of n takes x stratum s and y stratum perm[s].
  CounterRng strata(seed, stream, 0xFFFFFFFFull);
  std::vector<int> perm(static_cast<size_t>(total));
  for (int begin : {0, direct}) {
    const int end = begin == 0 ? direct : total;
    for (int s = begin; s < end; ++s) perm[s] = s - begin;
    for (int s = end - 1; s > begin; --s)
      std::swap(perm[s], perm[begin + strata.UniformInt(static_cast<uint32_t>(s - begin + 1))]);
  }
  for (int s = 0; s < total; ++s) {
    CounterRng rng(seed, stream, static_cast<uint64_t>(s));
    const int n = s < direct ? direct : total - direct, stratum = s < direct ? s : s - direct;
    const double x = pixel.u - 0.5 + (stratum + rng.UniformDouble()) / n;
    const double y = pixel.v - 0.5 + (perm[s] + rng.UniformDouble()) / n;
    const Eigen::Vector3f dir = rotation * k.RayDirection(x, y).cast<float>().normalized();
    const float first_weight =
        s < direct ? static_cast<float>(total) / static_cast<float>(direct) : 0.0f;
    tracer.VoxelCoefficients(eye, dir, grid, splitting, paths, rng, scaled, rays, first_weight);
  }
}

void CheckView(const PosedImage& tv, size_t index) {
  const CameraIntrinsics& k = tv.view.intrinsics;
  k.Validate(Format("view ", index));
  if (tv.image.width() != k.width || tv.image.height() != k.height) {
    throw Error(Format("view ", index, ": image ", tv.image.width(), "x", tv.image.height(),
                       " but intrinsics say ", k.width, "x", k.height));
  }
}

}  // namespace

void LightEstimationOptions::Validate() const {
  RequireRange("grid", grid, 1, 64);
  RequireRange("pixels_per_view", pixels_per_view, 1, 1 << 24);
  paths.Validate();
  if (paths.spp < 2 || paths.spp % 2)
    throw Error(Format("option spp = ", paths.spp, " must be even (two independent halves)"));
  RequireRange("direct_paths", direct_paths, 1, 1 << 16);  // at most all of a half's paths
  RequireRange("split_depth", split_depth, 1, 1 << 20);
  RequireRange("refine_coarse_pixels", refine_coarse_pixels, 0, 1 << 24);
  RequireRange("boundary_inset", boundary_inset, 0.0, 0.5);
  RequireRange("penalty_weight", penalty_weight, 0.0, 1e6);
  RequireRange("penalty_epsilon", penalty_epsilon, 1e-9, 1e6);
  RequireRange("rounds", rounds, 1, 100);
  RequireRange("round_tolerance", round_tolerance, 0.0, 10.0);
  RequireRange("resample_voxels", resample_voxels, 1, 1 << 16);
  RequireRange("resample_uniform", resample_uniform, 0.0, 1.0);
  RequireRange("max_iterations", max_iterations, 1, 1 << 20);
  RequireRange("move_passes", move_passes, 0, 100);
  RequireRange("move_voxels", move_voxels, 1, 1 << 20);
  RequireRange("move_iterations", move_iterations, 1, 1 << 20);
  RequireRange("tolerance", tolerance, 0.0, 1.0);
  RequireRange("saturation", saturation, 0.0, 1e30);
  RequireRange("emitter_factor", emitter_factor, 1.0, 1e30);
  RequireRange("noise_correction", noise_correction, 0.0, 1.0);
  RequireRange("refine_levels", refine_levels, 0, 4);
  RequireRange("refine_fraction", refine_fraction, 0.0, 1.0);
  RequireRange("refine_reach", refine_reach, 0.0, 10.0);
  RequireRange("refine_penalty_scale", refine_penalty_scale, 0.0, 1e6);
  RequireRange("refine_max_voxels", refine_max_voxels, 1, 1 << 20);
  RequireRange("refine_spp", refine_spp, 0, 1 << 16);
  RequireRange("refine_grow", refine_grow, 0, 100);
  if (refine_spp % 2)
    throw Error(
        Format("option refine_spp = ", refine_spp, " must be even (two independent halves)"));
  if (grid << refine_levels > 256) {
    throw Error(Format("option refine_levels = ", refine_levels, " with grid = ", grid, " gives a ",
                       grid << refine_levels, "^3 grid; at most 256 per axis"));
  }
  RequireRange("active_fraction", active_fraction, 0.0, 1.0);
  RequireRange("memory_cap", memory_cap, 1.0, 1e7);
}

Scene WithoutLights(const Scene& scene) {
  Scene out;
  for (const SceneMesh& m : scene.meshes) {
    if (!m.IsEmitter()) out.meshes.push_back(m);
  }
  if (out.meshes.empty())
    throw Error("light estimation: the scene has no reflecting (non-emitting) mesh");
  return out;
}

VoxelLightGrid MakeVoxelGrid(const Scene& scene, int dims, double boundary_inset) {
  GS_CHECK(boundary_inset >= 0.0 && boundary_inset <= 0.5);
  VoxelLightGrid g;
  for (const SceneMesh& m : scene.meshes) {
    if (m.IsEmitter()) continue;
    for (const auto& v : m.mesh.vertices) g.bounds.extend(v.cast<double>());
  }
  if (g.bounds.isEmpty() || g.bounds.sizes().minCoeff() <= 0.0) {
    // A flat scene (one wall): give the grid some depth so it still has volume.
    const double size = std::max(1e-3, g.bounds.isEmpty() ? 1.0 : g.bounds.sizes().maxCoeff());
    g.bounds.extend(g.bounds.min() - Eigen::Vector3d::Constant(0.5 * size));
    g.bounds.extend(g.bounds.max() + Eigen::Vector3d::Constant(0.5 * size));
  }
  if (dims > 1) {
    // The outer layer of voxel centres lies `boundary_inset` voxels inside the bounding box
    // (a voxel centre grid would hold it half a voxel inside): lights sit on ceilings and walls.
    // The voxels are then (size / (dims - 1 + 2 inset)) wide and the box grows by
    // (1/2 - inset) of one on every side.
    const Eigen::Vector3d voxel = g.bounds.sizes() / (dims - 1 + 2.0 * boundary_inset);
    const Eigen::Vector3d grow = voxel * (0.5 - boundary_inset);
    g.bounds = Eigen::AlignedBox3d(g.bounds.min() - grow, g.bounds.max() + grow);
  }
  g.dims = Eigen::Vector3i::Constant(dims);
  g.intensity.assign(static_cast<size_t>(g.VoxelCount()), Eigen::Vector3f::Zero());
  g.weights.assign(static_cast<size_t>(g.VoxelCount()), {1, 1, 1, 1, 1, 1});
  g.cube_size = 0.05 * g.bounds.sizes().minCoeff() / dims;
  return g;
}

Image<uint8_t> ValidPixels(const PathTracer& tracer, const PosedImage& tv,
                           const LightEstimationOptions& options, PixelMaskCounts* counts) {
  const CameraIntrinsics& k = tv.view.intrinsics;
  Image<uint8_t> valid(k.width, k.height, 0);
  PixelMaskCounts local;
  std::vector<float> luminance;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Eigen::Vector3f& observed = tv.image(u, v);
      if (!observed.allFinite()) {
        throw Error(Format("pixel (", u, ", ", v, ") holds a non-finite value (",
                           observed.transpose(), ")"));
      }
      const auto hit = tracer.PixelCentreHit(tv.view, u, v);
      bool reflects = false;
      if (hit) {
        const SceneMesh& m = tracer.scene().meshes[hit->mesh];
        reflects =
            !m.IsEmitter() && m.albedo.Eval(m.mesh, hit->face, hit->b1, hit->b2).maxCoeff() > 0.0f;
      }
      if (!reflects) {
        ++local.miss;
      } else if (options.saturation > 0.0 && observed.maxCoeff() >= options.saturation) {
        ++local.saturated;
      } else {
        valid(u, v) = 1;
        luminance.push_back(Luminance(observed));
      }
    }
  }
  // Emitters seen directly: far brighter than anything the lit surfaces show.
  if (!luminance.empty()) {
    std::vector<float> sorted = luminance;
    const size_t at = static_cast<size_t>(0.95 * static_cast<double>(sorted.size() - 1));
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(at),
                     sorted.end());
    const double limit = options.emitter_factor * std::max(0.0f, sorted[at]);
    // The box filter mixes an emitter into the pixels around it: those go too (8-neighbours).
    Image<uint8_t> bright(k.width, k.height, 0);
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u)
        bright(u, v) = limit > 0.0 && Luminance(tv.image(u, v)) > limit;
    }
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        bool near = false;
        for (int dv = -1; dv <= 1; ++dv) {
          for (int du = -1; du <= 1; ++du) {
            const int uu = u + du, vv = v + dv;
            near = near || (uu >= 0 && vv >= 0 && uu < k.width && vv < k.height && bright(uu, vv));
          }
        }
        if (valid(u, v) && near) {
          valid(u, v) = 0;
          ++local.emitter;
        }
      }
    }
  }
  for (size_t i = 0; i < valid.size(); ++i) local.valid += valid.data()[i];
  if (counts) *counts = local;
  return valid;
}

std::vector<SampledPixel> SamplePixels(const PathTracer& tracer,
                                       const std::vector<PosedImage>& views,
                                       const LightEstimationOptions& options, uint64_t seed,
                                       std::vector<PixelMaskCounts>* counts) {
  options.Validate();
  if (views.empty()) throw Error("light estimation: no training views");
  std::vector<SampledPixel> out;
  if (counts) counts->clear();
  for (size_t i = 0; i < views.size(); ++i) {
    CheckView(views[i], i);
    PixelMaskCounts c;
    Image<uint8_t> valid;
    try {
      valid = ValidPixels(tracer, views[i], options, &c);
    } catch (const Error& e) {
      throw Error(Format("view ", i, ": ", e.what()));
    }
    if (counts) counts->push_back(c);
    std::vector<int> candidates;
    for (size_t p = 0; p < valid.size(); ++p) {
      if (valid.data()[p]) candidates.push_back(static_cast<int>(p));
    }
    // Partial Fisher-Yates: the first n of a seeded shuffle, then raster order.
    const size_t n = std::min(candidates.size(), static_cast<size_t>(options.pixels_per_view));
    CounterRng rng(seed, 0x9E3779B97F4A7C15ull, i);
    for (size_t a = 0; a < n; ++a) {
      const size_t b = a + rng.UniformInt(static_cast<uint32_t>(candidates.size() - a));
      std::swap(candidates[a], candidates[b]);
    }
    candidates.resize(n);
    std::sort(candidates.begin(), candidates.end());
    const int width = views[i].image.width();
    for (int p : candidates) {
      SampledPixel s;
      s.view = static_cast<int>(i);
      s.u = p % width;
      s.v = p / width;
      s.observed = views[i].image(s.u, s.v);
      out.push_back(s);
    }
  }
  if (out.empty()) {
    throw Error(
        "light estimation: no valid pixel in any view (every camera ray misses the geometry, sees "
        "an "
        "emitter or is saturated)");
  }
  return out;
}

size_t LightCache::Bytes() const {
  return index.capacity() * sizeof(int32_t) + coefficient.capacity() * sizeof(Eigen::Vector3f) +
         row_begin.capacity() * sizeof(size_t) + pixels.capacity() * sizeof(SampledPixel);
}

namespace {

// Two sets (the running total and a round's) of three dense Gram matrices over 6 x `voxels`.
double EquationBytes(double voxels) {
  const double parameters = 6.0 * voxels;
  return 2.0 * 3.0 * parameters * parameters * sizeof(double);
}

}  // namespace

double NormalEquationsBoundBytes(int dims) {
  return EquationBytes(static_cast<double>(dims) * dims * dims);
}

LightCache TraceLightCache(const PathTracer& tracer, const VoxelLightGrid& grid,
                           const VoxelSplitting& splitting, const std::vector<PosedImage>& views,
                           const std::vector<SampledPixel>& pixels,
                           const LightEstimationOptions& options, uint64_t seed, double cap_bytes) {
  const RenderOptions paths = options.paths;
  const int parameters = 6 * grid.VoxelCount();
  struct Row {
    std::vector<int32_t> index;
    std::vector<Eigen::Vector3f> coefficient;
    RayCounts rays;
  };
  constexpr size_t kEntryBytes = sizeof(int32_t) + sizeof(Eigen::Vector3f);
  // The rows live twice for a moment (per row, then packed): count them twice against the cap.
  const size_t fixed = pixels.size() * (sizeof(Row) + sizeof(size_t) + sizeof(SampledPixel));
  if (cap_bytes > 0.0 && 2.0 * fixed > cap_bytes) {
    throw Error(Format("light estimation: the path-coefficient cache of ", pixels.size(),
                       " pixels needs more than", " the memory cap of ", cap_bytes / 1e6,
                       " MB; lower lights pixels_per_view or raise the", " lights memory_cap"));
  }
  VoxelSplitting prepared = splitting;
  prepared.Prepare(grid);
  std::atomic<size_t> entries{0};
  std::vector<Row> rows(pixels.size());
  ParallelForChunks(0, pixels.size(), 8, [&](size_t begin, size_t end) {
    // Dense accumulator over the parameters; the voxels a pixel touches are listed (first touch:
    // `stamp` differs from the pixel's) and their parameters collected and reset after the pixel.
    std::vector<Eigen::Vector3f> sum(static_cast<size_t>(parameters), Eigen::Vector3f::Zero());
    std::vector<size_t> stamp(static_cast<size_t>(grid.VoxelCount()), SIZE_MAX);
    std::vector<int32_t> touched;
    for (size_t i = begin; i < end; ++i) {
      const SampledPixel& pixel = pixels[i];
      GS_CHECK_LT(static_cast<size_t>(pixel.view), views.size());
      touched.clear();
      WalkPixel(
          tracer, grid, prepared, pixel, views[pixel.view].view, paths, options.direct_paths, seed,
          [&](const VoxelConnections& to, float scale) {
            for (int c = 0; c < to.count; ++c) {
              const int j = to.voxel[c];
              if (stamp[j] != i) {
                stamp[j] = i;
                touched.push_back(j);
              }
              Eigen::Vector3f* faces = &sum[6 * static_cast<size_t>(j)];
              for (int axis = 0; axis < 3; ++axis) {
                const float w = to.w[c][axis];
                if (w != 0.0f) faces[VoxelFace(axis, w)] += (to.base[c] * std::abs(w)) * scale;
              }
            }
          },
          &rows[i].rays);
      std::sort(touched.begin(), touched.end());
      Row& row = rows[i];
      for (int32_t j : touched) {
        for (int32_t p = 6 * j; p < 6 * j + 6; ++p) {
          if (sum[p].maxCoeff() > 0.0f) {
            row.index.push_back(p);
            row.coefficient.push_back(sum[p]);
          }
          sum[p].setZero();
        }
      }
      const size_t held = entries.fetch_add(row.index.size()) + row.index.size();
      if (cap_bytes > 0.0 && 2.0 * static_cast<double>(held * kEntryBytes + fixed) > cap_bytes) {
        throw Error(
            Format("light estimation: the path-coefficient cache outgrew the memory cap of ",
                   cap_bytes / 1e6, " MB (", held, " coefficients so far, ", pixels.size(),
                   " pixels); lower lights ",
                   "pixels_per_view, spp or grid, or raise the lights memory_cap"));
      }
    }
  });
  LightCache cache;
  cache.parameters = parameters;
  cache.pixels = pixels;
  cache.row_begin.push_back(0);
  for (Row& row : rows) {
    cache.index.insert(cache.index.end(), row.index.begin(), row.index.end());
    cache.coefficient.insert(cache.coefficient.end(), row.coefficient.begin(),
                             row.coefficient.end());
    cache.row_begin.push_back(cache.index.size());
    cache.rays.intersect += row.rays.intersect;
    cache.rays.occluded += row.rays.occluded;
  }
  return cache;
}

void LightCache::Merge(const LightCache& other) {
  GS_CHECK_EQ(parameters, other.parameters);
  GS_CHECK_EQ(pixels.size(), other.pixels.size());
  std::vector<size_t> begin;
  std::vector<int32_t> merged_index;
  std::vector<Eigen::Vector3f> merged_coefficient;
  begin.reserve(row_begin.size());
  merged_index.reserve(index.size() + other.index.size());
  merged_coefficient.reserve(index.size() + other.index.size());
  begin.push_back(0);
  for (size_t i = 0; i < pixels.size(); ++i) {
    size_t a = row_begin[i], b = other.row_begin[i];
    const size_t a_end = row_begin[i + 1], b_end = other.row_begin[i + 1];
    while (a < a_end || b < b_end) {
      const bool from_a = b == b_end || (a < a_end && index[a] < other.index[b]);
      GS_CHECK(from_a || a == a_end || index[a] != other.index[b]);
      merged_index.push_back(from_a ? index[a] : other.index[b]);
      merged_coefficient.push_back(from_a ? coefficient[a++] : other.coefficient[b++]);
    }
    begin.push_back(merged_index.size());
  }
  row_begin = std::move(begin);
  index = std::move(merged_index);
  coefficient = std::move(merged_coefficient);
  rays.intersect += other.rays.intersect;
  rays.occluded += other.rays.occluded;
}

std::pair<LightCache, LightCache> TraceLightCacheHalves(
    const PathTracer& tracer, const VoxelLightGrid& grid, const VoxelSplitting& splitting,
    const std::vector<PosedImage>& views, const std::vector<SampledPixel>& pixels,
    const LightEstimationOptions& options, uint64_t seed_a, uint64_t seed_b, double cap_bytes) {
  LightEstimationOptions half = options;
  half.paths.spp = options.paths.spp / 2;
  std::pair<LightCache, LightCache> out;
  out.first = TraceLightCache(tracer, grid, splitting, views, pixels, half, seed_a, cap_bytes);
  const double left =
      cap_bytes > 0.0 ? std::max(1.0, cap_bytes - static_cast<double>(out.first.Bytes())) : 0.0;
  out.second = TraceLightCache(tracer, grid, splitting, views, pixels, half, seed_b, left);
  return out;
}

Eigen::Vector3f RenderSampledPixel(const PathTracer& tracer, const VoxelLightGrid& grid,
                                   const VoxelSplitting& splitting, const SampledPixel& pixel,
                                   const std::vector<PosedImage>& views,
                                   const LightEstimationOptions& options, uint64_t seed) {
  Eigen::Vector3f radiance = Eigen::Vector3f::Zero();
  WalkPixel(
      tracer, grid, splitting, pixel, views.at(static_cast<size_t>(pixel.view)).view, options.paths,
      options.direct_paths, seed,
      [&](const VoxelConnections& to, float scale) {
        for (int i = 0; i < to.count; ++i) {
          const int j = to.voxel[i];
          for (int axis = 0; axis < 3; ++axis) {
            const float w = to.w[i][axis];
            if (w == 0.0f) continue;
            const Eigen::Vector3f c = (to.base[i] * std::abs(w)) * scale;
            radiance += c.cwiseProduct(grid.intensity[j]) * grid.weights[j][VoxelFace(axis, w)];
          }
        }
      },
      nullptr);
  return radiance;
}

std::vector<Eigen::Vector3f> LightCache::Predict(const VoxelLightGrid& grid) const {
  GS_CHECK_EQ(grid.VoxelCount() * 6, parameters);
  std::vector<Eigen::Vector3f> out(pixels.size(), Eigen::Vector3f::Zero());
  ParallelFor(0, pixels.size(), [&](size_t i) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (size_t e = row_begin[i]; e < row_begin[i + 1]; ++e) {
      const int j = index[e] / 6, k = index[e] % 6;
      sum += coefficient[e].cwiseProduct(grid.intensity[j]) * grid.weights[j][k];
    }
    out[i] = sum;
  });
  return out;
}

// ------------------------------------------------------------------------------------------------
// Normal equations

namespace {

// The normal equations of NormalEquations::FromCaches from sparse rows: per row, the merged
// entries of both halves (compact indices, sorted), then per tile of G the products of the
// row's entries that fall in it. Cost sum_i nnz_i^2 instead of pixels x n^2.
void FillSparse(const LightCache& first, const LightCache& second, double correction,
                const std::vector<int>& compact, const std::vector<std::pair<int, int>>& tile_pairs,
                int tile, NormalEquations* eq) {
  const int n = static_cast<int>(eq->used.size());
  const bool same = &first == &second;
  std::vector<size_t> begin{0};
  std::vector<int> index;
  std::vector<Eigen::Vector3f> mean, half_difference;
  for (size_t i = 0; i < eq->pixels; ++i) {
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
      index.push_back(compact[p]);
      mean.push_back(0.5f * (ca + cb));
      half_difference.push_back(0.5f * (ca - cb));
    }
    begin.push_back(index.size());
  }
  for (int c = 0; c < 3; ++c) {
    eq->gram[c] = Eigen::MatrixXd::Zero(n, n);
    eq->rhs[c] = Eigen::VectorXd::Zero(n);
    eq->observed_sq[c] = 0.0;
  }
  for (size_t i = 0; i < eq->pixels; ++i) {
    const Eigen::Vector3d observed = first.pixels[i].observed.cast<double>();
    for (int c = 0; c < 3; ++c) eq->observed_sq[c] += observed[c] * observed[c];
    for (size_t e = begin[i]; e < begin[i + 1]; ++e) {
      for (int c = 0; c < 3; ++c)
        eq->rhs[c][index[e]] += static_cast<double>(mean[e][c]) * observed[c];
    }
  }
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

}  // namespace

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
  std::vector<int> compact(static_cast<size_t>(eq.parameters), -1);
  for (const LightCache* cache : {&first, &second}) {
    for (int32_t p : cache->index) compact[p] = 0;
  }
  for (int p = 0; p < eq.parameters; ++p) {
    if (compact[p] == 0) {
      compact[p] = static_cast<int>(eq.used.size());
      eq.used.push_back(p);
    }
  }
  const int n = static_cast<int>(eq.used.size());
  const bool same = &first == &second;
  // Parameters `known` holds (`known_at`: its compact index) and the others (`fresh`): only the
  // entries of G with a fresh parameter are computed.
  std::vector<int> known_at(static_cast<size_t>(n), -1), fresh;
  if (known) {
    GS_CHECK_EQ(known->parameters, eq.parameters);
    GS_CHECK_EQ(known->pixels, eq.pixels);
    for (int i = 0; i < n; ++i) {
      const auto it = std::lower_bound(known->used.begin(), known->used.end(), eq.used[i]);
      if (it != known->used.end() && *it == eq.used[i]) {
        known_at[i] = static_cast<int>(it - known->used.begin());
      } else {
        fresh.push_back(i);
      }
    }
  } else {
    fresh.resize(static_cast<size_t>(n));
    std::iota(fresh.begin(), fresh.end(), 0);
  }
  const bool incremental = fresh.size() < static_cast<size_t>(n);
  constexpr int kRows = 2048, kTile = 256;
  const int tiles = (n + kTile - 1) / kTile;
  std::vector<std::pair<int, int>> tile_pairs;
  for (int a = 0; a < tiles; ++a) {
    for (int b = a; b < tiles; ++b) tile_pairs.emplace_back(a, b);
  }
  // Dense rows of one chunk: sign +1 gives the mean row (a + b) / 2, -1 the half difference.
  const auto fill = [&](size_t begin, size_t end, int c, float sign, Eigen::MatrixXf* m) {
    *m = Eigen::MatrixXf::Zero(static_cast<Eigen::Index>(end - begin), n);
    for (const LightCache* cache : {&first, &second}) {
      const float w = cache == &first ? 0.5f : 0.5f * sign;
      for (size_t i = begin; i < end; ++i) {
        for (size_t e = cache->row_begin[i]; e < cache->row_begin[i + 1]; ++e) {
          (*m)(static_cast<Eigen::Index>(i - begin), compact[cache->index[e]]) +=
              w * cache->coefficient[e][c];
        }
      }
    }
  };
  // Upper tiles of M^T M: each tile is written by one task, chunks in a fixed order, so the sums
  // do not depend on the thread count.
  const auto accumulate = [&](const Eigen::MatrixXf& m, double scale, Eigen::MatrixXd* gram) {
    ParallelFor(
        0, tile_pairs.size(),
        [&](size_t t) {
          const auto [ta, tb] = tile_pairs[t];
          const int ca = ta * kTile, cb = tb * kTile;
          const int wa = std::min(kTile, n - ca), wb = std::min(kTile, n - cb);
          const Eigen::MatrixXf block = m.middleCols(ca, wa).transpose() * m.middleCols(cb, wb);
          gram->block(ca, cb, wa, wb) += scale * block.cast<double>();
        },
        1);
  };
  // With `known`: the columns of the fresh parameters, X = M^T M[:, fresh], by tiles of X.
  const int fresh_n = static_cast<int>(fresh.size());
  const int fresh_tiles = (fresh_n + kTile - 1) / kTile;
  const auto accumulate_fresh = [&](const Eigen::MatrixXf& m, double scale, Eigen::MatrixXd* x) {
    const Eigen::MatrixXf m_fresh = m(Eigen::all, fresh);
    ParallelFor(
        0, static_cast<size_t>(tiles) * fresh_tiles,
        [&](size_t t) {
          const int ta = static_cast<int>(t) / fresh_tiles, tb = static_cast<int>(t) % fresh_tiles;
          const int ca = ta * kTile, cb = tb * kTile;
          const int wa = std::min(kTile, n - ca), wb = std::min(kTile, fresh_n - cb);
          const Eigen::MatrixXf block =
              m.middleCols(ca, wa).transpose() * m_fresh.middleCols(cb, wb);
          x->block(ca, cb, wa, wb) += scale * block.cast<double>();
        },
        1);
  };
  size_t nonzeros = 0;
  for (const LightCache* cache : {&first, &second}) nonzeros += cache->NonZeros();
  if (static_cast<double>(nonzeros) <
      0.2 * static_cast<double>(n) * static_cast<double>(eq.pixels)) {
    FillSparse(first, second, same ? 0.0 : correction, compact, tile_pairs, kTile, &eq);
    return eq;
  }
  for (int c = 0; c < 3; ++c) {
    Eigen::MatrixXd& gram = eq.gram[c];
    gram = Eigen::MatrixXd::Zero(n, n);
    Eigen::MatrixXd fresh_columns;
    if (incremental) fresh_columns = Eigen::MatrixXd::Zero(n, fresh_n);
    eq.rhs[c] = Eigen::VectorXd::Zero(n);
    eq.observed_sq[c] = 0.0;
    Eigen::MatrixXf mean, half_difference;
    for (size_t begin = 0; begin < eq.pixels; begin += kRows) {
      const size_t end = std::min(eq.pixels, begin + kRows);
      fill(begin, end, c, 1.0f, &mean);
      Eigen::VectorXd observed(static_cast<Eigen::Index>(end - begin));
      for (size_t i = begin; i < end; ++i)
        observed[static_cast<Eigen::Index>(i - begin)] = first.pixels[i].observed[c];
      eq.observed_sq[c] += observed.squaredNorm();
      eq.rhs[c] += mean.cast<double>().transpose() * observed;
      if (incremental) {
        accumulate_fresh(mean, 1.0, &fresh_columns);
      } else {
        accumulate(mean, 1.0, &gram);
      }
      if (!same && correction > 0.0) {
        fill(begin, end, c, -1.0f, &half_difference);
        if (incremental) {
          accumulate_fresh(half_difference, -correction, &fresh_columns);
        } else {
          accumulate(half_difference, -correction, &gram);
        }
      }
    }
    if (incremental) {
      for (int a = 0; a < n; ++a) {
        if (known_at[a] < 0) continue;
        for (int b = a; b < n; ++b) {
          if (known_at[b] >= 0) gram(a, b) = known->gram[c](known_at[a], known_at[b]);
        }
      }
      for (int f = 0; f < fresh_n; ++f) {
        for (int a = 0; a <= fresh[f]; ++a) gram(a, fresh[f]) = fresh_columns(a, f);
        for (int b = fresh[f] + 1; b < n; ++b) gram(fresh[f], b) = fresh_columns(b, f);
      }
    }
    gram.triangularView<Eigen::StrictlyLower>() = gram.transpose();
  }
  return eq;
}

void NormalEquations::Add(const NormalEquations& other) {
  GS_CHECK_EQ(parameters, other.parameters);
  if (used == other.used) {  // the usual case: add in place, no third copy
    for (int c = 0; c < 3; ++c) {
      gram[c] += other.gram[c];
      rhs[c] += other.rhs[c];
      observed_sq[c] += other.observed_sq[c];
    }
    pixels += other.pixels;
    return;
  }
  std::vector<int> merged;
  std::set_union(used.begin(), used.end(), other.used.begin(), other.used.end(),
                 std::back_inserter(merged));
  const auto expand = [&](const NormalEquations& from, std::array<Eigen::MatrixXd, 3>* gram,
                          std::array<Eigen::VectorXd, 3>* rhs) {
    std::vector<int> at(from.used.size());
    for (size_t i = 0; i < from.used.size(); ++i) {
      at[i] = static_cast<int>(std::lower_bound(merged.begin(), merged.end(), from.used[i]) -
                               merged.begin());
    }
    const int n = static_cast<int>(merged.size());
    for (int c = 0; c < 3; ++c) {
      (*gram)[c] = Eigen::MatrixXd::Zero(n, n);
      (*rhs)[c] = Eigen::VectorXd::Zero(n);
      for (size_t b = 0; b < at.size(); ++b) {
        (*rhs)[c][at[b]] = from.rhs[c][static_cast<Eigen::Index>(b)];
        for (size_t a = 0; a < at.size(); ++a) {
          (*gram)[c](at[a], at[b]) =
              from.gram[c](static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b));
        }
      }
    }
  };
  std::array<Eigen::MatrixXd, 3> g1, g2;
  std::array<Eigen::VectorXd, 3> r1, r2;
  expand(*this, &g1, &r1);
  expand(other, &g2, &r2);
  for (int c = 0; c < 3; ++c) {
    gram[c] = g1[c] + g2[c];
    rhs[c] = r1[c] + r2[c];
    observed_sq[c] += other.observed_sq[c];
  }
  used = std::move(merged);
  pixels += other.pixels;
}

// ------------------------------------------------------------------------------------------------
// Cost

namespace {

// The best uniform lighting (every used parameter x = alpha_c): alpha_c = sum b_c / 1^T G_c 1.
Eigen::Vector3d UniformFit(const NormalEquations& eq) {
  Eigen::Vector3d alpha = Eigen::Vector3d::Zero();
  for (int c = 0; c < 3; ++c) {
    const double denominator = eq.gram[c].sum();
    if (denominator > 0.0) alpha[c] = std::max(0.0, eq.rhs[c].sum() / denominator);
  }
  return alpha;
}

}  // namespace

LightCost::LightCost(const NormalEquations& equations, double penalty_weight,
                     double penalty_epsilon)
    : eq_(equations), weight_(penalty_weight) {
  energy_ = eq_.observed_sq[0] + eq_.observed_sq[1] + eq_.observed_sq[2];
  if (eq_.used.empty()) {
    throw Error(
        "light estimation: no sampled path reaches any voxel (every shadow ray is blocked or faces "
        "away)");
  }
  if (!(energy_ > 0.0)) throw Error("light estimation: the sampled pixels are all black");
  const Eigen::Vector3d alpha = UniformFit(eq_);
  // The best uniform lighting lights every voxel some path reaches (with adaptive refinement only
  // the candidates are traced): s_ref is its summed intensity.
  int used_voxels = 0;
  for (size_t i = 0; i < eq_.used.size(); ++i)
    used_voxels += i == 0 || eq_.used[i] / 6 != eq_.used[i - 1] / 6;
  const double s_ref = alpha.sum() * used_voxels;
  epsilon_ = penalty_epsilon * std::max(s_ref, 1e-30);
}

Eigen::VectorXd LightCost::Pack(const VoxelLightGrid& grid) {
  Eigen::VectorXd x(9 * grid.VoxelCount());
  for (int j = 0; j < grid.VoxelCount(); ++j) {
    x.segment<3>(9 * j) = grid.intensity[j].cast<double>();
    for (int k = 0; k < 6; ++k) x[9 * j + 3 + k] = grid.weights[j][k];
  }
  return x;
}

void LightCost::Unpack(const Eigen::VectorXd& params, VoxelLightGrid* grid) {
  GS_CHECK_EQ(params.size(), 9 * grid->VoxelCount());
  for (int j = 0; j < grid->VoxelCount(); ++j) {
    grid->intensity[j] = params.segment<3>(9 * j).cast<float>();
    for (int k = 0; k < 6; ++k) grid->weights[j][k] = static_cast<float>(params[9 * j + 3 + k]);
  }
}

double LightCost::Evaluate(const Eigen::VectorXd& params, Eigen::VectorXd* gradient, double* data,
                           std::array<Eigen::VectorXd, 3>* gram_x) const {
  const int voxels = eq_.parameters / 6;
  GS_CHECK_EQ(params.size(), 9 * voxels);
  const int n = static_cast<int>(eq_.used.size());
  std::array<Eigen::VectorXd, 3> local_gx;
  std::array<Eigen::VectorXd, 3>& gx = gram_x ? *gram_x : local_gx;
  std::array<double, 3> part{};
  ParallelFor(
      0, 3,
      [&](size_t c) {
        Eigen::VectorXd x(n);
        for (int i = 0; i < n; ++i) {
          const int j = eq_.used[i] / 6, k = eq_.used[i] % 6;
          x[i] = params[9 * j + c] * params[9 * j + 3 + k];
        }
        // x is sparse once the penalty has switched most voxels off: then G x is a sum of the
        // columns of the lit parameters, O(n nnz) instead of O(n^2).
        std::vector<int> lit;
        for (int i = 0; i < n; ++i) {
          if (x[i] != 0.0) lit.push_back(i);
        }
        if (4 * lit.size() < static_cast<size_t>(n)) {
          gx[c] = Eigen::VectorXd::Zero(n);
          for (int i : lit) gx[c].noalias() += x[i] * eq_.gram[c].col(i);
        } else {
          gx[c].noalias() = eq_.gram[c].selfadjointView<Eigen::Upper>() * x;
        }
        // |A x - I|^2 = x^T G x - 2 b^T x + I^T I.
        part[c] = x.dot(gx[c]) - 2.0 * eq_.rhs[c].dot(x) + eq_.observed_sq[c];
      },
      1);
  const double data_sum = part[0] + part[1] + part[2];
  if (gradient) {
    *gradient = Eigen::VectorXd::Zero(params.size());
    for (int c = 0; c < 3; ++c) {
      const Eigen::VectorXd d = 2.0 * (gx[c] - eq_.rhs[c]) / energy_;
      for (int i = 0; i < n; ++i) {
        const int j = eq_.used[i] / 6, k = eq_.used[i] % 6;
        (*gradient)[9 * j + c] += d[i] * params[9 * j + 3 + k];
        (*gradient)[9 * j + 3 + k] += d[i] * params[9 * j + c];
      }
    }
  }
  double penalty = 0.0;
  if (weight_ > 0.0) {
    for (int j = 0; j < voxels; ++j) {
      const double s = params[9 * j] + params[9 * j + 1] + params[9 * j + 2];
      penalty += weight_ * std::log1p(s / epsilon_);
      if (gradient) {
        for (int c = 0; c < 3; ++c) (*gradient)[9 * j + c] += weight_ / (epsilon_ + s);
      }
    }
  }
  if (data) *data = data_sum / energy_;
  return data_sum / energy_ + penalty;
}

// ------------------------------------------------------------------------------------------------
// Solve

namespace {

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

}  // namespace

SolveReport SolveLights(const NormalEquations& eq, const LightEstimationOptions& options,
                        VoxelLightGrid* grid) {
  options.Validate();
  const int voxels = grid->VoxelCount();
  GS_CHECK_EQ(6 * voxels, eq.parameters);
  const LightCost cost(eq, options.penalty_weight, options.penalty_epsilon);
  const double energy = eq.observed_sq[0] + eq.observed_sq[1] + eq.observed_sq[2];
  const int n = static_cast<int>(eq.used.size());
  std::vector<int> voxel_of(static_cast<size_t>(n)), face_of(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) voxel_of[i] = eq.used[i] / 6, face_of[i] = eq.used[i] % 6;
  // The L step works over the voxels some path reaches (`reached`): with adaptive refinement
  // they are a few hundred of a finer grid's thousands. eq.used is sorted, so a voxel's
  // parameters are the compact range [slot_begin[v], slot_begin[v + 1]).
  std::vector<int> reached, slot_begin;
  std::vector<bool> is_reached(static_cast<size_t>(voxels), false);
  for (int i = 0; i < n; ++i) {
    GS_CHECK(i == 0 || eq.used[i] > eq.used[i - 1]);
    if (reached.empty() || reached.back() != voxel_of[i]) {
      reached.push_back(voxel_of[i]);
      slot_begin.push_back(i);
    }
    is_reached[voxel_of[i]] = true;
  }
  const int slots = static_cast<int>(reached.size());
  slot_begin.push_back(n);

  Eigen::MatrixXd light(voxels, 3);   // L
  Eigen::MatrixXd lambda(voxels, 6);  // lambda
  bool dark = true;
  for (int j = 0; j < voxels; ++j) {
    light.row(j) = grid->intensity[j].cast<double>().transpose();
    for (int k = 0; k < 6; ++k) lambda(j, k) = std::clamp<double>(grid->weights[j][k], 0.0, 1.0);
    dark = dark && grid->intensity[j].maxCoeff() <= 0.0f;
  }
  if (dark) {
    // Start from the convex relaxation: the products x = L lambda as free non-negative
    // parameters (per channel a non-negative least-squares problem on G_c, from the best uniform
    // lighting), then each voxel's 3 x 6 product matrix reduced to its best rank-1 non-negative
    // factor L lambda^T by power iteration.
    const Eigen::Vector3d alpha = UniformFit(eq);
    Eigen::MatrixXd products = Eigen::MatrixXd::Zero(6 * voxels, 3);
    for (int c = 0; c < 3; ++c) {
      Eigen::VectorXd x = Eigen::VectorXd::Constant(n, alpha[c]);
      Eigen::VectorXd gx = eq.gram[c] * x;
      CoordinateDescent(eq.gram[c], eq.rhs[c], Eigen::VectorXd::Zero(n), 0.0,
                        std::numeric_limits<double>::infinity(), 20, &x, &gx);
      for (int i = 0; i < n; ++i) products(eq.used[i], c) = x[i];
    }
    for (int j = 0; j < voxels; ++j) {
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
        light.row(j) = (l3 * top).transpose();
        lambda.row(j) = (l6 / top).transpose();
      } else {
        light.row(j).setZero();
        lambda.row(j).setOnes();
      }
    }
  }
  const auto pack = [&]() {
    Eigen::VectorXd p(9 * voxels);
    for (int j = 0; j < voxels; ++j) {
      p.segment<3>(9 * j) = light.row(j).transpose();
      p.segment<6>(9 * j + 3) = lambda.row(j).transpose();
    }
    return p;
  };

  // The cost at the current L, lambda, keeping G_c x_c per channel for the next iteration's
  // dark-voxel faces.
  std::array<Eigen::VectorXd, 3> gx;
  const auto evaluate = [&](double* data) { return cost.Evaluate(pack(), nullptr, data, &gx); };

  // One alternating iteration (dark voxels' faces, the L step, the lambda step); `gx` holds
  // G_c x_c of the current L, lambda on entry.
  const auto iterate = [&]() {
    // Dark voxels face where the data pull hardest: lambda = the face k whose products have the
    // most negative data gradient (G x - b summed over the channels). A dark voxel can then
    // switch on as a directional light in the L step; with lambda = 1 on every face it could only
    // switch on as an omnidirectional one, which the data rarely want.
    {
      Eigen::VectorXd pull = Eigen::VectorXd::Zero(n);
      for (int c = 0; c < 3; ++c) pull += gx[c] - eq.rhs[c];
      std::vector<double> best(static_cast<size_t>(voxels), 0.0);
      std::vector<int> best_face(static_cast<size_t>(voxels), -1);
      for (int i = 0; i < n; ++i) {
        const int j = voxel_of[i];
        if (light.row(j).sum() > 0.0 || pull[i] >= best[j]) continue;
        best[j] = pull[i];
        best_face[j] = face_of[i];
      }
      for (int j = 0; j < voxels; ++j) {
        if (best_face[j] >= 0) {
          lambda.row(j).setZero();
          lambda(j, best_face[j]) = 1.0;
        }
      }
    }
    // L step (per channel): x_i = lambda_i L_j(i), so the quadratic in L is S^T D G D S with
    // D = diag(lambda), S the parameter-to-voxel selection; the log penalty is majorised by its
    // tangent at the current s_j: linear weight E w / (eps + s_j) on every L_jc.
    // Voxels no path reaches are dark.
    for (int j = 0; j < voxels; ++j) {
      if (!is_reached[j]) light.row(j).setZero();
    }
    Eigen::VectorXd q(slots);
    for (int v = 0; v < slots; ++v) {
      q[v] = options.penalty_weight > 0.0
                 ? energy * options.penalty_weight / (cost.epsilon() + light.row(reached[v]).sum())
                 : 0.0;
    }
    Eigen::VectorXd lambda_of(n);
    for (int i = 0; i < n; ++i) lambda_of[i] = lambda(voxel_of[i], face_of[i]);
    // Cyclic coordinate descent on L_jc with H = S^T D G D S never formed: H_jj is the voxel's
    // 6 x 6 block, (H L)_j = sum_i lambda_i (G x)_i over its parameters, and a change of L_jc adds
    // the voxel's columns of G to G x. A sweep costs O(n) plus O(n) per parameter of a voxel
    // that changes; most stay dark. `gx` holds G_c x_c (current L, lambda) on entry and after.
    // Channels in parallel, each by one task.
    ParallelFor(
        0, 3,
        [&](size_t c) {
          const Eigen::MatrixXd& gram = eq.gram[c];
          Eigen::VectorXd& gxc = gx[c];
          Eigen::VectorXd h(slots), g(slots), l(slots);
          for (int v = 0; v < slots; ++v) {
            double hvv = 0.0, gv = 0.0;
            for (int a = slot_begin[v]; a < slot_begin[v + 1]; ++a) {
              if (lambda_of[a] == 0.0) continue;
              gv += lambda_of[a] * eq.rhs[c][a];
              for (int b = slot_begin[v]; b < slot_begin[v + 1]; ++b)
                hvv += lambda_of[a] * lambda_of[b] * gram(a, b);
            }
            h[v] = hvv;
            g[v] = gv;
            l[v] = light(reached[v], c);
          }
          for (int sweep = 0; sweep < 10; ++sweep) {
            double change = 0.0, scale = 0.0;
            for (int v = 0; v < slots; ++v) {
              double value = 0.0;
              if (h[v] > 0.0) {
                double hl = 0.0;
                for (int a = slot_begin[v]; a < slot_begin[v + 1]; ++a) hl += lambda_of[a] * gxc[a];
                value = std::max(0.0, l[v] - (hl - g[v] + 0.5 * q[v]) / h[v]);
              }
              const double delta = value - l[v];
              if (delta != 0.0) {
                for (int a = slot_begin[v]; a < slot_begin[v + 1]; ++a) {
                  if (lambda_of[a] != 0.0) gxc.noalias() += (lambda_of[a] * delta) * gram.col(a);
                }
                l[v] = value;
              }
              change = std::max(change, std::abs(delta) * std::sqrt(std::max(h[v], 0.0)));
              scale = std::max(scale, std::abs(value) * std::sqrt(std::max(h[v], 0.0)));
            }
            if (change <= 1e-9 * scale) break;
          }
          for (int v = 0; v < slots; ++v) light(reached[v], c) = l[v];
        },
        1);
    // lambda step over the parameters of lit voxels: x_i = L_j(i)c lambda_i, so the quadratic
    // is sum_c D_c G_c D_c with D_c = diag(L_j(i)c); 0 <= lambda <= 1.
    std::vector<int> active;
    for (int i = 0; i < n; ++i) {
      if (light.row(voxel_of[i]).sum() > 0.0) active.push_back(i);
    }
    const int m = static_cast<int>(active.size());
    if (m > 0) {
      // sum_c D_c G_c[active, active] D_c, the channels' terms in parallel and added in order.
      std::array<Eigen::MatrixXd, 3> hc;
      std::array<Eigen::VectorXd, 3> gc;
      ParallelFor(
          0, 3,
          [&](size_t c) {
            Eigen::VectorXd l(m);
            for (int a = 0; a < m; ++a) l[a] = light(voxel_of[active[a]], c);
            hc[c] = l.asDiagonal() * eq.gram[c](active, active) * l.asDiagonal();
            gc[c] = l.cwiseProduct(eq.rhs[c](active));
          },
          1);
      Eigen::MatrixXd h = hc[0] + hc[1] + hc[2];
      Eigen::VectorXd g = gc[0] + gc[1] + gc[2], x(m);
      for (int a = 0; a < m; ++a) x[a] = lambda(voxel_of[active[a]], face_of[active[a]]);
      Eigen::VectorXd hx = h * x;
      CoordinateDescent(h, g, Eigen::VectorXd::Zero(m), 0.0, 1.0, 5, &x, &hx);
      for (int a = 0; a < m; ++a) lambda(voxel_of[active[a]], face_of[active[a]]) = x[a];
    }
  };
  const auto run = [&](int iterations, SolveReport* out) {
    double previous = evaluate(nullptr);
    for (int it = 0; it < iterations; ++it) {
      iterate();
      const double current = evaluate(&out->data);
      out->history.push_back(current);
      ++out->iterations;
      const bool done = previous - current <= options.tolerance * std::abs(previous);
      previous = current;
      if (done) break;
    }
    return previous;
  };

  SolveReport report;
  double best = run(options.max_iterations, &report);
  // Moves: the log penalty's local minima often hold a light one voxel off its place (moving it
  // means switching a second voxel on first, which the activation charge forbids). Each lit
  // voxel, strongest first, tries handing its light (L and lambda) to each of its 6 face
  // neighbours; the solve continues briefly and the move is kept when the cost drops.
  if (options.penalty_weight > 0.0) {
    const Eigen::Vector3i dims = grid->dims;
    for (int pass = 0; pass < options.move_passes; ++pass) {
      std::vector<std::pair<double, int>> lit;
      for (int j = 0; j < voxels; ++j) {
        const double power = light.row(j).sum() * lambda.row(j).sum();
        if (power > 0.0) lit.emplace_back(-power, j);
      }
      std::sort(lit.begin(), lit.end());
      if (lit.size() > static_cast<size_t>(options.move_voxels))
        lit.resize(static_cast<size_t>(options.move_voxels));
      bool improved = false;
      for (const auto& [negative_power, j] : lit) {
        const Eigen::Vector3i at(j % dims.x(), j / dims.x() % dims.y(), j / (dims.x() * dims.y()));
        for (int axis = 0; axis < 3; ++axis) {
          for (int step : {-1, 1}) {
            Eigen::Vector3i to = at;
            to[axis] += step;
            if (to[axis] < 0 || to[axis] >= dims[axis] || light.row(j).sum() <= 0.0) continue;
            const int t = to.x() + dims.x() * (to.y() + dims.y() * to.z());
            const Eigen::MatrixXd keep_light = light, keep_lambda = lambda;
            light.row(t) += light.row(j);
            lambda.row(t) = lambda.row(j);
            light.row(j).setZero();
            SolveReport trial;
            const double after = run(options.move_iterations, &trial);
            report.iterations += trial.iterations;
            if (after < best) {
              best = after;
              improved = true;
              ++report.moves;
            } else {
              light = keep_light;
              lambda = keep_lambda;
            }
          }
        }
      }
      if (!improved) break;
    }
  }
  report.cost = evaluate(&report.data);
  // Each voxel's lambdas scaled to a maximum of 1 (the same products L lambda).
  for (int j = 0; j < voxels; ++j) {
    const double top = lambda.row(j).maxCoeff();
    if (top > 0.0 && light.row(j).sum() > 0.0) {
      light.row(j) *= top;
      lambda.row(j) /= top;
    } else {
      light.row(j).setZero();
    }
    grid->intensity[j] = light.row(j).transpose().cast<float>();
    for (int k = 0; k < 6; ++k) grid->weights[j][k] = static_cast<float>(lambda(j, k));
  }
  return report;
}

// ------------------------------------------------------------------------------------------------
// Rounds

LightEstimate EstimateLights(const Scene& scene, const std::vector<PosedImage>& views,
                             const LightEstimationOptions& options, uint64_t seed) {
  options.Validate();
  const auto start = std::chrono::steady_clock::now();
  const PathTracer tracer(WithoutLights(scene));
  LightEstimate out;
  const std::vector<SampledPixel> pixels = SamplePixels(tracer, views, options, seed, &out.masks);
  out.pixels = pixels.size();
  // With refinement the coarse rounds only find where the lights are: an even spread of each
  // view's sampled pixels (in raster order) is enough there; the finer levels use all of them.
  std::vector<SampledPixel> coarse_pixels;
  if (options.refine_levels > 0 && options.refine_coarse_pixels > 0) {
    for (size_t begin = 0; begin < pixels.size();) {
      size_t end = begin;
      while (end < pixels.size() && pixels[end].view == pixels[begin].view) ++end;
      const size_t m = end - begin,
                   keep = std::min<size_t>(m, static_cast<size_t>(options.refine_coarse_pixels));
      for (size_t t = 0; t < keep; ++t) coarse_pixels.push_back(pixels[begin + t * m / keep]);
      begin = end;
    }
  } else {
    coarse_pixels = pixels;
  }
  out.lights = MakeVoxelGrid(tracer.scene(), options.grid, options.boundary_inset);
  VoxelLightGrid& grid = out.lights;
  grid.active_fraction = options.active_fraction;
  // The dense normal equations are known before any path is traced: refuse them up front.
  const double cap_bytes = options.memory_cap * 1e6;
  const double equation_bytes = NormalEquationsBoundBytes(options.grid);
  if (equation_bytes >= cap_bytes) {
    throw Error(Format("light estimation: the normal equations of a ", options.grid,
                       "^3 voxel grid (", 6 * grid.VoxelCount(), " parameters, dense) may take ",
                       std::ceil(equation_bytes / 1e6), " MB, over the memory cap of ",
                       options.memory_cap, " MB; lower lights grid or raise the",
                       " lights memory_cap"));
  }
  NormalEquations total;
  LightCache last;
  // Two independent halves of the paths (the second keyed by ~key), kept in `last` and `second`,
  // within what the cap leaves beside `equation_bytes` of normal equations.
  const auto trace_halves = [&](const std::vector<SampledPixel>& traced_pixels,
                                const VoxelLightGrid& lights, const VoxelSplitting& splitting,
                                int spp, uint64_t key, double equation_bytes, LightCache* second,
                                LightRound* r) {
    const auto t = std::chrono::steady_clock::now();
    LightEstimationOptions traced = options;
    traced.paths.spp = spp;
    last = LightCache();  // the previous caches are not needed while tracing
    *second = LightCache();
    std::tie(last, *second) =
        TraceLightCacheHalves(tracer, lights, splitting, views, traced_pixels, traced, key, ~key,
                              std::max(1.0, cap_bytes - equation_bytes));
    r->trace_seconds = SecondsSince(t);
    r->nonzeros = last.NonZeros() + second->NonZeros();
    r->rays = last.rays.total() + second->rays.total();
  };
  // The coarse rounds over `round_pixels`, from the dark grid.
  const auto coarse_rounds = [&](const std::vector<SampledPixel>& round_pixels) {
    grid = MakeVoxelGrid(tracer.scene(), options.grid, options.boundary_inset);
    std::vector<double> previous_power;
    for (int round = 0; round < options.rounds; ++round) {
      LightRound r;
      r.round = static_cast<int>(out.rounds.size());
      // The first vertex connects to every voxel; deeper ones draw voxels, uniformly in round 0,
      // then in proportion to the estimated powers mixed with the uniform distribution.
      VoxelSplitting splitting;
      splitting.all_until_depth = options.split_depth;
      std::vector<double> pmf(static_cast<size_t>(grid.VoxelCount()), 1.0);
      if (round > 0) {
        double total_power = 0.0;
        for (int j = 0; j < grid.VoxelCount(); ++j)
          total_power += pmf[j] = Luminance(grid.Power(j));
        for (double& p : pmf) {
          p = (1.0 - options.resample_uniform) * (total_power > 0.0 ? p / total_power : 0.0) +
              options.resample_uniform / grid.VoxelCount();
        }
      }
      splitting.SetPmf(std::move(pmf), options.resample_voxels);
      LightCache second;
      trace_halves(round_pixels, grid, splitting, options.paths.spp,
                   Mix64(seed + 0x51ED * (round + 1)), equation_bytes, &second, &r);
      auto t = std::chrono::steady_clock::now();
      NormalEquations eq = NormalEquations::FromCaches(last, second, options.noise_correction);
      if (round == 0) {
        total = std::move(eq);
      } else {
        total.Add(eq);
      }
      r.gram_seconds = SecondsSince(t);
      t = std::chrono::steady_clock::now();
      LightEstimationOptions no_moves = options;  // moves once, at the end
      no_moves.move_passes = 0;
      r.solve = SolveLights(total, no_moves, &grid);
      r.solve_seconds = SecondsSince(t);
      r.active_voxels = static_cast<int>(grid.ActiveVoxels(options.active_fraction).size());
      std::vector<double> power(static_cast<size_t>(grid.VoxelCount()));
      for (int j = 0; j < grid.VoxelCount(); ++j) power[j] = Luminance(grid.Power(j));
      if (round > 0) {
        double diff = 0.0, norm = 0.0;
        for (size_t j = 0; j < power.size(); ++j) {
          diff += (power[j] - previous_power[j]) * (power[j] - previous_power[j]);
          norm += power[j] * power[j];
        }
        r.power_change = norm > 0.0 ? std::sqrt(diff / norm) : 0.0;
      }
      previous_power = power;
      out.rounds.push_back(r);
      if (round > 0 && r.power_change < options.round_tolerance) break;
    }
    if (options.move_passes > 0 && options.penalty_weight > 0.0) {
      const auto t = std::chrono::steady_clock::now();
      LightRound& r = out.rounds.back();
      const SolveReport polish = SolveLights(total, options, &grid);
      r.solve.iterations += polish.iterations;
      r.solve.moves = polish.moves;
      r.solve.cost = polish.cost;
      r.solve.data = polish.data;
      r.solve_seconds += SecondsSince(t);
      r.active_voxels = static_cast<int>(grid.ActiveVoxels(options.active_fraction).size());
    }
  };
  coarse_rounds(coarse_pixels);
  // Adaptive refinement: a grid twice as fine, traced and solved over the voxels near the lights
  // only. Growing passes add the neighbours of the finer solution's lights (a coarse voxel
  // standing in for an extended light can sit a layer off it) and solve again.
  // Adds the finer voxels near `lit`'s lights (strongest first) while refine_max_voxels allows;
  // `left_out` tells whether some light's neighbourhood did not fit.
  const auto add_candidates = [&](const VoxelLightGrid& lit, const VoxelLightGrid& fine,
                                  std::vector<bool>* enabled, int* count, bool* left_out) {
    std::vector<std::pair<double, int>> split;
    double top = 0.0;
    for (int j = 0; j < lit.VoxelCount(); ++j) top = std::max<double>(top, Luminance(lit.Power(j)));
    for (int j = 0; j < lit.VoxelCount(); ++j) {
      const double power = Luminance(lit.Power(j));
      if (power > 0.0 && power >= options.refine_fraction * top) split.emplace_back(power, j);
    }
    std::sort(split.begin(), split.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    const Eigen::Vector3d reach = options.refine_reach *
                                  lit.bounds.sizes().cwiseQuotient(lit.dims.cast<double>()) *
                                  (1.0 + 1e-9);
    int added = 0;
    for (const auto& [power, j] : split) {
      const Eigen::Vector3d centre = lit.VoxelCenter(j);
      std::vector<int> near;
      for (int f = 0; f < fine.VoxelCount(); ++f) {
        if (!(*enabled)[f] &&
            ((fine.VoxelCenter(f) - centre).cwiseAbs().array() <= reach.array()).all()) {
          near.push_back(f);
        }
      }
      if (*count + static_cast<int>(near.size()) > options.refine_max_voxels) {
        *left_out = true;
        break;
      }
      for (int f : near) (*enabled)[f] = true;
      *count += static_cast<int>(near.size());
      added += static_cast<int>(near.size());
    }
    return added;
  };
  for (int level = 1; level <= options.refine_levels; ++level) {
    VoxelLightGrid fine = MakeVoxelGrid(tracer.scene(), 2 * grid.dims.x(), options.boundary_inset);
    fine.active_fraction = options.active_fraction;
    std::vector<bool> enabled(static_cast<size_t>(fine.VoxelCount()), false);
    int candidates = 0;
    bool left_out = false;
    if (add_candidates(grid, fine, &enabled, &candidates, &left_out) == 0 && !left_out) break;
    // Lights spread over more voxels than refine_max_voxels can refine: the finer grid would drop
    // the ones left out (it is dark outside its candidates), so the coarser result stands.
    // When the coarser result stands (here or below) and it is the coarse grid of a pixel subset,
    // the coarse grid is estimated again from every sampled pixel.
    const bool reestimate = level == 1 && coarse_pixels.size() < pixels.size();
    if (left_out) {
      out.notes.push_back(Format(
          "adaptive refinement stopped before level ", level, ": the lights of the ", grid.dims.x(),
          "^3 grid spread over more than lights refine_max_voxels = ", options.refine_max_voxels,
          " finer voxels (a larger penalty_weight gives fewer)"));
      if (reestimate) coarse_rounds(pixels);
      break;
    }
    // The coarser result, kept in case this level fits worse (below); its cache only when it
    // would be the result's (not re-estimated).
    const double coarser_data = out.rounds.back().solve.data;
    VoxelLightGrid coarser = grid;
    LightCache coarser_cache;
    if (!reestimate) coarser_cache = std::move(last);
    const double coarser_bytes = static_cast<double>(coarser_cache.Bytes());
    std::vector<bool> traced(enabled.size(), false);
    LightCache second;
    for (int pass = 0; pass <= options.refine_grow; ++pass) {
      bool grow_left_out = false;  // a growing pass adds what fits
      if (pass > 0 && add_candidates(fine, fine, &enabled, &candidates, &grow_left_out) == 0) break;
      LightRound r;
      r.round = static_cast<int>(out.rounds.size());
      r.level = level;
      r.candidates = candidates;
      const double level_equation_bytes = EquationBytes(candidates);
      if (level_equation_bytes >= cap_bytes) {
        throw Error(Format("light estimation: the normal equations of refinement level ", level,
                           " (", candidates, " voxels) may take ",
                           std::ceil(level_equation_bytes / 1e6), " MB, over the memory cap of ",
                           options.memory_cap,
                           " MB; lower lights refine_max_voxels or raise the lights memory_cap"));
      }
      // A growing pass traces only the voxels it adds, with the same keys: the paths are the same
      // (a vertex that connects to every enabled voxel draws no random number for it), so their
      // entries merge into the caches as if every candidate had been traced again.
      VoxelSplitting splitting;
      splitting.enabled = enabled;
      for (size_t f = 0; f < enabled.size(); ++f) splitting.enabled[f] = enabled[f] && !traced[f];
      traced = enabled;
      const int level_spp = options.refine_spp > 0 ? options.refine_spp : options.paths.spp;
      const uint64_t key = Mix64(seed + 0x5EF1 * level);
      if (pass == 0) {
        trace_halves(pixels, fine, splitting, level_spp, key, level_equation_bytes + coarser_bytes,
                     &second, &r);
      } else {
        LightCache held_first = std::move(last), held_second = std::move(second);
        trace_halves(pixels, fine, splitting, level_spp, key,
                     level_equation_bytes + coarser_bytes +
                         static_cast<double>(held_first.Bytes() + held_second.Bytes()),
                     &second, &r);
        held_first.Merge(last);
        held_second.Merge(second);
        last = std::move(held_first);
        second = std::move(held_second);
      }
      auto t = std::chrono::steady_clock::now();
      // A growing pass's caches hold the previous pass's entries: their part of G is kept.
      if (pass == 0) {
        total = NormalEquations::FromCaches(last, second, options.noise_correction);
      } else {
        const NormalEquations previous = std::move(total);
        total = NormalEquations::FromCaches(last, second, options.noise_correction, &previous);
      }
      r.gram_seconds = SecondsSince(t);
      t = std::chrono::steady_clock::now();
      LightEstimationOptions level_options = options;
      level_options.penalty_weight = options.penalty_weight * options.refine_penalty_scale;
      for (int j = 0; j < fine.VoxelCount();
           ++j) {  // every pass starts dark (the convex relaxation)
        fine.intensity[j].setZero();
        fine.weights[j] = {1, 1, 1, 1, 1, 1};
      }
      r.solve = SolveLights(total, level_options, &fine);
      r.solve_seconds = SecondsSince(t);
      r.active_voxels = static_cast<int>(fine.ActiveVoxels(options.active_fraction).size());
      out.rounds.push_back(r);
    }
    // The finer grid holds light only near the coarser lights (dark elsewhere) and a lighter
    // penalty: it should fit the pixels at least as well. When it does not (the coarser lights
    // stand in for light that no strong voxel holds, as with imperfect geometry and albedo: on
    // the demo chain at w 1e-4, data 0.020 coarse against 0.136 finer), the coarser result stands.
    // The coarser data term is the noisier (fewer paths per pixel), which favours the finer level.
    const double finer_data = out.rounds.back().solve.data;
    if (finer_data > coarser_data) {
      out.notes.push_back(Format("adaptive refinement level ", level,
                                 " fitted the pixels worse than the ", coarser.dims.x(),
                                 "^3 grid (data term ", finer_data, " against ", coarser_data,
                                 "): the coarser result stands"));
      second = LightCache();
      if (reestimate) {
        last = LightCache();
        coarse_rounds(pixels);
      } else {
        grid = std::move(coarser);
        last = std::move(coarser_cache);
      }
      break;
    }
    coarser_cache = LightCache();
    grid = std::move(fine);
  }
  const std::vector<Eigen::Vector3f> predicted = last.Predict(grid);
  double err = 0.0, ref = 0.0;
  for (size_t i = 0; i < last.pixels.size(); ++i) {
    err += (predicted[i] - last.pixels[i].observed).cast<double>().squaredNorm();
    ref += last.pixels[i].observed.cast<double>().squaredNorm();
  }
  out.train_rmse = ref > 0.0 ? std::sqrt(err / ref) : 0.0;
  out.active_voxels =
      static_cast<int>(grid.ActiveVoxels(options.active_fraction).size());  // of the result's grid
  out.seconds = SecondsSince(start);
  return out;
}

AmbientBaseline FitAmbientBaseline(const PathTracer& tracer, const std::vector<PosedImage>& views,
                                   const LightEstimationOptions& options) {
  // Per view: the valid pixels' first-hit albedo a and observed colour o.
  std::vector<std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>> samples(views.size());
  Eigen::Vector3d ao = Eigen::Vector3d::Zero(), aa = Eigen::Vector3d::Zero();
  for (size_t t = 0; t < views.size(); ++t) {
    const PosedImage& tv = views[t];
    const Image<uint8_t> valid = ValidPixels(tracer, tv, options);
    for (int v = 0; v < valid.height(); ++v) {
      for (int u = 0; u < valid.width(); ++u) {
        if (!valid(u, v)) continue;
        const auto hit = tracer.PixelCentreHit(tv.view, u, v);
        if (!hit) continue;
        const SceneMesh& mesh = tracer.scene().meshes[static_cast<size_t>(hit->mesh)];
        const Eigen::Vector3d a =
            mesh.albedo.Eval(mesh.mesh, hit->face, hit->b1, hit->b2).cast<double>();
        const Eigen::Vector3d o = tv.image(u, v).cast<double>();
        samples[t].emplace_back(a, o);
        ao += a.cwiseProduct(o);
        aa += a.cwiseProduct(a);
      }
    }
  }
  AmbientBaseline out;
  for (int c = 0; c < 3; ++c) out.radiance[c] = aa[c] > 0.0 ? ao[c] / aa[c] : 0.0;
  for (const auto& view : samples) {
    double err = 0.0, ref = 0.0;
    for (const auto& [a, o] : view) {
      err += (a.cwiseProduct(out.radiance) - o).squaredNorm();
      ref += o.squaredNorm();
    }
    out.rmse.push_back(ref > 0.0 ? std::sqrt(err / ref) : 0.0);
    out.mean_rmse += out.rmse.back() / static_cast<double>(samples.size());
  }
  return out;
}

ViewError CompareRender(const PathTracer& lit, const PosedImage& reference,
                        const LightEstimationOptions& options, int spp, uint64_t seed,
                        double reference_noise_rms, ImageRgb* render, int block) {
  GS_CHECK_GE(block, 1);
  const Image<uint8_t> valid = ValidPixels(lit, reference, options);
  RenderOptions paths = options.paths;
  paths.spp = spp;
  const RenderHalves halves =
      RenderInHalves(lit, reference.view, paths, seed, seed ^ 0xB5297A4D3F1E0C2Bull);
  ViewError e;
  double err = 0.0, ref = 0.0, noise = 0.0;
  const double reference_variance = 3.0 * reference_noise_rms * reference_noise_rms;  // per pixel
  for (int v0 = 0; v0 < valid.height(); v0 += block) {
    for (int u0 = 0; u0 < valid.width(); u0 += block) {
      // Sums over the tile's valid pixels; with block 1 this is the per-pixel comparison.
      Eigen::Vector3d sum_mean = Eigen::Vector3d::Zero(), sum_ref = Eigen::Vector3d::Zero();
      double render_variance = 0.0;
      size_t n = 0;
      for (int v = v0; v < std::min(v0 + block, valid.height()); ++v) {
        for (int u = u0; u < std::min(u0 + block, valid.width()); ++u) {
          if (!valid(u, v)) continue;
          const Eigen::Vector3d pa = halves.a(u, v).cast<double>(),
                                pb = halves.b(u, v).cast<double>();
          sum_mean += 0.5 * (pa + pb);
          sum_ref += reference.image(u, v).cast<double>();
          // Variance of the mean of two independent halves: |a - b|^2 / 4.
          render_variance += 0.25 * (pa - pb).squaredNorm();
          ++n;
        }
      }
      if (n == 0) continue;
      const double count = static_cast<double>(n);
      const Eigen::Vector3d mean = sum_mean / count, r = sum_ref / count;
      // Each tile weighs as its pixels; the noise of a tile mean is a pixel's over the count.
      err += count * (mean - r).squaredNorm();
      ref += count * r.squaredNorm();
      noise += (render_variance + count * reference_variance) / count;
      e.pixels += n;
    }
  }
  if (render) {
    *render = halves.mean;
  }
  if (ref > 0.0) {
    e.rmse = std::sqrt(err / ref);
    e.noise = std::sqrt(noise / ref);
    e.rmse_bias = std::sqrt(std::max(0.0, err - noise) / ref);
  }
  return e;
}

}  // namespace genscene::inverse
