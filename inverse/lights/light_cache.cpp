#include "inverse/lights/light_cache.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <utility>

#include "core/check.h"
#include "core/parallel.h"
#include "core/rng.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on

namespace {

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

// One pixel's row of the cache, as its trace leaves it (packed into the cache after the trace).
struct CacheRow {
  std::vector<int32_t> index;
  std::vector<Eigen::Vector3f> coefficient;
  RayCounts rays;
};

constexpr size_t kEntryBytes = sizeof(int32_t) + sizeof(Eigen::Vector3f);

// The rows live twice for a moment (per row, then packed): they count twice against the cap.
// `fixed`: the bytes of the rows without their entries.
void CheckCacheBytes(size_t fixed, size_t pixels, double cap_bytes) {
  if (cap_bytes > 0.0 && 2.0 * fixed > cap_bytes) {
    throw Error(Format("light estimation: the path-coefficient cache of ", pixels,
                       " pixels needs more than", " the memory cap of ", cap_bytes / 1e6,
                       " MB; lower lights pixels_per_view or raise the", " lights memory_cap"));
  }
}

void CheckEntryBytes(size_t held, size_t fixed, size_t pixels, double cap_bytes) {
  if (cap_bytes > 0.0 && 2.0 * static_cast<double>(held * kEntryBytes + fixed) > cap_bytes) {
    throw Error(Format("light estimation: the path-coefficient cache outgrew the memory cap of ",
                       cap_bytes / 1e6, " MB (", held, " coefficients so far, ", pixels,
                       " pixels); lower lights ",
                       "pixels_per_view, spp or grid, or raise the lights memory_cap"));
  }
}

// One pixel's coefficients, summed in a dense accumulator over the parameters (one per chunk of
// pixels, reused from pixel to pixel). The voxels a pixel touches are listed (first touch:
// `stamp` differs from the pixel's) and their parameters collected and reset after the pixel.
class RowAccumulator {
 public:
  RowAccumulator(int parameters, int voxels)
      : sum_(static_cast<size_t>(parameters), Eigen::Vector3f::Zero()),
        stamp_(static_cast<size_t>(voxels), SIZE_MAX) {}

  void Begin() { touched_.clear(); }

  // The connections of one path vertex of pixel `i`, times `scale`: voxel j's face k gets
  // base x |w_axis| for the face of each axis that w points along.
  void Add(const VoxelConnections& to, float scale, size_t i) {
    for (int c = 0; c < to.count; ++c) {
      const int j = to.voxel[c];
      if (stamp_[j] != i) {
        stamp_[j] = i;
        touched_.push_back(j);
      }
      Eigen::Vector3f* faces = &sum_[6 * static_cast<size_t>(j)];
      for (int axis = 0; axis < 3; ++axis) {
        const float w = to.w[c][axis];
        if (w != 0.0f) faces[VoxelFace(axis, w)] += (to.base[c] * std::abs(w)) * scale;
      }
    }
  }

  // The pixel's non-zero parameters, sorted, into `row`; the accumulator is left zero.
  void Collect(CacheRow* row) {
    std::sort(touched_.begin(), touched_.end());
    for (int32_t j : touched_) {
      for (int32_t p = 6 * j; p < 6 * j + 6; ++p) {
        if (sum_[p].maxCoeff() > 0.0f) {
          row->index.push_back(p);
          row->coefficient.push_back(sum_[p]);
        }
        sum_[p].setZero();
      }
    }
  }

 private:
  std::vector<Eigen::Vector3f> sum_;
  std::vector<size_t> stamp_;
  std::vector<int32_t> touched_;
};

// The rows, in pixel order, as one cache.
LightCache PackRows(const std::vector<CacheRow>& rows, int parameters,
                    const std::vector<SampledPixel>& pixels) {
  LightCache cache;
  cache.parameters = parameters;
  cache.pixels = pixels;
  cache.row_begin.push_back(0);
  for (const CacheRow& row : rows) {
    cache.index.insert(cache.index.end(), row.index.begin(), row.index.end());
    cache.coefficient.insert(cache.coefficient.end(), row.coefficient.begin(),
                             row.coefficient.end());
    cache.row_begin.push_back(cache.index.size());
    cache.rays.intersect += row.rays.intersect;
    cache.rays.occluded += row.rays.occluded;
  }
  return cache;
}

}  // namespace

size_t LightCache::Bytes() const {
  return index.capacity() * sizeof(int32_t) + coefficient.capacity() * sizeof(Eigen::Vector3f) +
         row_begin.capacity() * sizeof(size_t) + pixels.capacity() * sizeof(SampledPixel);
}

LightCache TraceLightCache(const PathTracer& tracer, const VoxelLightGrid& grid,
                           const VoxelSplitting& splitting, const std::vector<PosedImage>& views,
                           const std::vector<SampledPixel>& pixels,
                           const LightEstimationOptions& options, uint64_t seed, double cap_bytes) {
  const RenderOptions paths = options.paths;
  const int parameters = 6 * grid.LightCount();
  const size_t fixed = pixels.size() * (sizeof(CacheRow) + sizeof(size_t) + sizeof(SampledPixel));
  CheckCacheBytes(fixed, pixels.size(), cap_bytes);
  VoxelSplitting prepared = splitting;
  prepared.Prepare(grid);
  std::atomic<size_t> entries{0};
  std::vector<CacheRow> rows(pixels.size());
  ParallelForChunks(0, pixels.size(), 8, [&](size_t begin, size_t end) {
    RowAccumulator accumulator(parameters, grid.LightCount());
    for (size_t i = begin; i < end; ++i) {
      const SampledPixel& pixel = pixels[i];
      GS_CHECK_LT(static_cast<size_t>(pixel.view), views.size());
      accumulator.Begin();
      WalkPixel(
          tracer, grid, prepared, pixel, views[pixel.view].view, paths, options.direct_paths, seed,
          [&](const VoxelConnections& to, float scale) { accumulator.Add(to, scale, i); },
          &rows[i].rays);
      CacheRow& row = rows[i];
      accumulator.Collect(&row);
      const size_t held = entries.fetch_add(row.index.size()) + row.index.size();
      CheckEntryBytes(held, fixed, pixels.size(), cap_bytes);
    }
  });
  return PackRows(rows, parameters, pixels);
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
            radiance += c.cwiseProduct(grid.IntensityOf(j)) * grid.WeightsOf(j)[VoxelFace(axis, w)];
          }
        }
      },
      nullptr);
  return radiance;
}

std::vector<Eigen::Vector3f> LightCache::Predict(const VoxelLightGrid& grid) const {
  GS_CHECK_EQ(grid.LightCount() * 6, parameters);
  std::vector<Eigen::Vector3f> out(pixels.size(), Eigen::Vector3f::Zero());
  ParallelFor(0, pixels.size(), [&](size_t i) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (size_t e = row_begin[i]; e < row_begin[i + 1]; ++e) {
      const int j = index[e] / 6, k = index[e] % 6;
      sum += coefficient[e].cwiseProduct(grid.IntensityOf(j)) * grid.WeightsOf(j)[k];
    }
    out[i] = sum;
  });
  return out;
}

}  // namespace genscene::inverse
