#include "fusion/preprocess.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/color.h"
#include "core/options.h"
#include "core/parallel.h"

namespace genscene::fusion {

void PreprocessOptions::Validate() const {
  RequireRange("range_min", min_depth, 0.0, 100.0);
  RequireRange("range_max", max_depth, min_depth, 1000.0);
  RequireRange("bilateral_radius", bilateral_radius, 0, 10);
  RequireRange("bilateral_sigma_space", bilateral_sigma_space, 0.1, 20.0);
  RequireRange("bilateral_sigma_depth", bilateral_sigma_depth, 1e-4, 1.0);
  RequireRange("levels", levels, 1, 5);
}

ImageDepth MaskInvalidDepth(const ImageDepth& depth, double min_depth, double max_depth,
                            MaskStats* stats) {
  ImageDepth out(depth.width(), depth.height());
  MaskStats s;
  for (size_t i = 0; i < depth.size(); ++i) {
    const float z = depth.pixels()[i];
    if (z == 0.0f) {
      ++s.zero;
    } else if (!std::isfinite(z)) {
      ++s.non_finite;
    } else if (z < min_depth || z > max_depth) {
      ++s.out_of_range;
    } else {
      out.pixels()[i] = z;
      ++s.valid;
    }
  }
  if (stats) *stats = s;
  return out;
}

ImageDepth BilateralFilterDepth(const ImageDepth& depth, int radius, double sigma_space,
                                double sigma_depth) {
  if (radius <= 0) return depth;
  const int w = depth.width(), h = depth.height();
  ImageDepth out(w, h);
  // Spatial weights per offset, and the range weight tabulated over |diff| in [0, 3 sigma]
  // (neighbours beyond 3 sigma do not contribute), 1/256 of 3 sigma apart.
  const int side = 2 * radius + 1;
  std::vector<float> spatial(static_cast<size_t>(side * side));
  for (int dv = -radius; dv <= radius; ++dv) {
    for (int du = -radius; du <= radius; ++du) {
      spatial[static_cast<size_t>((dv + radius) * side + du + radius)] =
          static_cast<float>(std::exp(-0.5 * (du * du + dv * dv) / (sigma_space * sigma_space)));
    }
  }
  constexpr int kRangeSteps = 256;
  const float max_diff = static_cast<float>(3.0 * sigma_depth);
  const float range_scale = kRangeSteps / max_diff;
  std::vector<float> range(kRangeSteps + 1);
  for (int i = 0; i <= kRangeSteps; ++i) {
    const double d = static_cast<double>(i) / range_scale;
    range[static_cast<size_t>(i)] =
        static_cast<float>(std::exp(-0.5 * d * d / (sigma_depth * sigma_depth)));
  }
  ParallelFor(
      0, static_cast<size_t>(h),
      [&](size_t row) {
        const int v = static_cast<int>(row);
        for (int u = 0; u < w; ++u) {
          const float z0 = depth(u, v);
          if (z0 <= 0.0f) continue;
          float sum = 0.0f, weight_sum = 0.0f;
          for (int dv = -radius; dv <= radius; ++dv) {
            const int vv = v + dv;
            if (vv < 0 || vv >= h) continue;
            const float* spatial_row = &spatial[static_cast<size_t>((dv + radius) * side + radius)];
            for (int du = -radius; du <= radius; ++du) {
              const int uu = u + du;
              if (uu < 0 || uu >= w) continue;
              const float z = depth(uu, vv);
              const float diff = std::abs(z - z0);
              if (z <= 0.0f || diff > max_diff) continue;
              const float wgt =
                  spatial_row[du] * range[static_cast<size_t>(diff * range_scale + 0.5f)];
              sum += wgt * z;
              weight_sum += wgt;
            }
          }
          out(u, v) = sum / weight_sum;  // the centre itself has weight 1
        }
      },
      8);
  return out;
}

ImageDepth DownsampleDepth(const ImageDepth& depth, double sigma_depth) {
  const int w = depth.width() / 2, h = depth.height() / 2;
  ImageDepth out(w, h);
  const float max_diff = static_cast<float>(3.0 * sigma_depth);
  ParallelFor(
      0, static_cast<size_t>(h),
      [&](size_t row) {
        const int v = static_cast<int>(row);
        for (int u = 0; u < w; ++u) {
          float reference = 0.0f, sum = 0.0f;
          int count = 0;
          for (int k = 0; k < 4; ++k) {
            const float z = depth(2 * u + (k & 1), 2 * v + (k >> 1));
            if (z <= 0.0f) continue;
            if (reference == 0.0f) reference = z;
            if (std::abs(z - reference) > max_diff) continue;
            sum += z;
            ++count;
          }
          if (count > 0) out(u, v) = sum / static_cast<float>(count);
        }
      },
      16);
  return out;
}

PointImage ComputeVertexMap(const ImageDepth& depth, const CameraIntrinsics& k) {
  PointImage out(depth.width(), depth.height());
  const float fx = static_cast<float>(k.fx), fy = static_cast<float>(k.fy);
  const float cx = static_cast<float>(k.cx), cy = static_cast<float>(k.cy);
  ParallelFor(
      0, static_cast<size_t>(depth.height()),
      [&](size_t row) {
        const int v = static_cast<int>(row);
        for (int u = 0; u < depth.width(); ++u) {
          const float z = depth(u, v);
          if (z > 0.0f) out(u, v) = Eigen::Vector3f((u - cx) / fx * z, (v - cy) / fy * z, z);
        }
      },
      16);
  return out;
}

PointImage ComputeNormalMap(const PointImage& vertices, double max_jump, int step) {
  const int w = vertices.width(), h = vertices.height();
  PointImage out(w, h);
  const float jump = static_cast<float>(max_jump);
  const int s = step;
  if (h <= 2 * s) return out;
  ParallelFor(
      static_cast<size_t>(s), static_cast<size_t>(h - s),
      [&](size_t row) {
        const int v = static_cast<int>(row);
        for (int u = s; u + s < w; ++u) {
          const Eigen::Vector3f& c = vertices(u, v);
          if (c.z() <= 0.0f) continue;
          const Eigen::Vector3f& l = vertices(u - s, v);
          const Eigen::Vector3f& r = vertices(u + s, v);
          const Eigen::Vector3f& t = vertices(u, v - s);
          const Eigen::Vector3f& b = vertices(u, v + s);
          if (l.z() <= 0.0f || r.z() <= 0.0f || t.z() <= 0.0f || b.z() <= 0.0f) continue;
          // A jump larger than max_jump per metre of depth marks a discontinuity, not a surface.
          const float limit = jump * c.z() * static_cast<float>(s);
          if (std::abs(l.z() - c.z()) > limit || std::abs(r.z() - c.z()) > limit ||
              std::abs(t.z() - c.z()) > limit || std::abs(b.z() - c.z()) > limit) {
            continue;
          }
          Eigen::Vector3f n = (r - l).cross(b - t);
          const float norm = n.norm();
          if (!(norm > 0.0f)) continue;
          n /= norm;
          if (n.dot(c) > 0.0f) n = -n;  // face the camera
          out(u, v) = n;
        }
      },
      8);
  return out;
}

std::vector<PyramidLevel> BuildPyramid(const ImageDepth& masked_depth,
                                       const CameraIntrinsics& intrinsics,
                                       const PreprocessOptions& options, int subsample) {
  GS_CHECK(subsample >= 1 && (subsample & (subsample - 1)) == 0);
  std::vector<PyramidLevel> levels(static_cast<size_t>(options.levels));
  levels[0].intrinsics = intrinsics;
  ImageDepth reduced;
  for (int s = subsample; s > 1; s /= 2) {
    reduced =
        DownsampleDepth(reduced.empty() ? masked_depth : reduced, options.bilateral_sigma_depth);
    levels[0].intrinsics = levels[0].intrinsics.Scaled(0.5);
  }
  // A reduced first level is smoothed by its 2x2 means alone: the bilateral filter on top of them
  // made tracking worse (preprocess.h).
  levels[0].depth = subsample > 1 ? std::move(reduced)
                                  : BilateralFilterDepth(masked_depth, options.bilateral_radius,
                                                         options.bilateral_sigma_space,
                                                         options.bilateral_sigma_depth);
  for (size_t l = 1; l < levels.size(); ++l) {
    levels[l].intrinsics = levels[l - 1].intrinsics.Scaled(0.5);
    levels[l].depth = DownsampleDepth(levels[l - 1].depth, options.bilateral_sigma_depth);
  }
  for (PyramidLevel& level : levels) {
    level.vertices = ComputeVertexMap(level.depth, level.intrinsics);
    level.normals = ComputeNormalMap(level.vertices);
  }
  return levels;
}

std::vector<IntensityLevel> BuildIntensityPyramid(const ImageRgb& color, int levels,
                                                  int subsample) {
  GS_CHECK(subsample >= 1 && (subsample & (subsample - 1)) == 0);
  std::vector<IntensityLevel> out;
  if (color.empty()) return out;
  int skipped = 0;  // the full-resolution levels below the first one returned
  while ((1 << skipped) < subsample) ++skipped;
  out.resize(static_cast<size_t>(levels + skipped));
  const int w0 = color.width(), h0 = color.height();
  out[0].intensity = ImageGray(w0, h0, 0.0f);
  const float* srgb = SrgbTable();  // the sRGB curve through a table, not a pow per pixel
  ParallelFor(0, static_cast<size_t>(h0), [&](size_t v) {
    for (int u = 0; u < w0; ++u) {
      out[0].intensity(u, static_cast<int>(v)) =
          srgb[SrgbTableIndex(Luminance(color(u, static_cast<int>(v))))];
    }
  });
  for (size_t l = 1; l < out.size(); ++l) {
    const ImageGray& fine = out[l - 1].intensity;
    const int w = fine.width() / 2, h = fine.height() / 2;
    out[l].intensity = ImageGray(w, h, 0.0f);
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        out[l].intensity(u, v) = 0.25f * (fine(2 * u, 2 * v) + fine(2 * u + 1, 2 * v) +
                                          fine(2 * u, 2 * v + 1) + fine(2 * u + 1, 2 * v + 1));
      }
    }
  }
  {
    // Noise at full resolution: the mask's response has standard deviation 6 sigma under white
    // noise; its median absolute value (0.6745 of that) over every other pixel ignores the minority
    // of pixels on edges. Each 2x2 mean halves it.
    const ImageGray& full = out[0].intensity;
    std::vector<float> response;
    response.reserve(static_cast<size_t>(w0) * static_cast<size_t>(h0) / 4 + 1);
    for (int v = 1; v + 1 < h0; v += 2) {
      for (int u = 1; u + 1 < w0; u += 2) {
        response.push_back(std::abs(full(u - 1, v - 1) - 2.0f * full(u, v - 1) +
                                    full(u + 1, v - 1) - 2.0f * full(u - 1, v) + 4.0f * full(u, v) -
                                    2.0f * full(u + 1, v) + full(u - 1, v + 1) -
                                    2.0f * full(u, v + 1) + full(u + 1, v + 1)));
      }
    }
    if (!response.empty()) {
      auto middle = response.begin() + static_cast<std::ptrdiff_t>(response.size() / 2);
      std::nth_element(response.begin(), middle, response.end());
      out[0].noise = *middle / (0.6745 * 6.0);
    }
  }
  for (size_t l = 1; l < out.size(); ++l) out[l].noise = 0.5 * out[l - 1].noise;
  out.erase(out.begin(), out.begin() + skipped);
  for (IntensityLevel& level : out) {
    const ImageGray& i = level.intensity;
    const int w = i.width(), h = i.height();
    level.grad_u = ImageGray(w, h, 0.0f);
    level.grad_v = ImageGray(w, h, 0.0f);
    ParallelFor(1, static_cast<size_t>(std::max(1, h - 1)), [&](size_t row) {
      const int v = static_cast<int>(row);
      for (int u = 1; u + 1 < w; ++u) {
        level.grad_u(u, v) = 0.5f * (i(u + 1, v) - i(u - 1, v));
        level.grad_v(u, v) = 0.5f * (i(u, v + 1) - i(u, v - 1));
      }
    });
  }
  return out;
}

}  // namespace genscene::fusion
