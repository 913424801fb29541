#include "render/render_compare.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "core/check.h"
#include "core/color.h"

namespace genscene::render {

namespace {

// True when the pixel and its 8 neighbours all see the same non-emitting mesh.
bool Interior(const Image<int>& object, int u, int v, const std::vector<bool>& emitter_meshes) {
  const int id = object(u, v);
  if (id < 0 || emitter_meshes[id]) return false;
  for (int dv = -1; dv <= 1; ++dv) {
    for (int du = -1; du <= 1; ++du) {
      const int x = u + du, y = v + dv;
      if (x < 0 || y < 0 || x >= object.width() || y >= object.height()) return false;
      if (object(x, y) != id) return false;
    }
  }
  return true;
}

}  // namespace

Eigen::Vector3d RegionComparison::RelativeBias() const {
  return (mean_ours - mean_reference).cwiseAbs().cwiseQuotient(mean_reference);
}

ImageComparison CompareWithReference(const RenderOutput& a, const RenderOutput& b,
                                     const ImageRgb& reference,
                                     const std::vector<bool>& emitter_meshes,
                                     size_t min_region_pixels) {
  if (!a.radiance.SameSize(reference) || !b.radiance.SameSize(reference)) {
    throw Error(Format("render ", a.radiance.width(), "x", a.radiance.height(), " vs reference ",
                       reference.width(), "x", reference.height()));
  }
  struct Pixel {
    double reference_luminance, relative_difference, relative_noise;
  };
  std::map<int, RegionComparison> regions;
  std::vector<Pixel> pixels;
  for (int v = 0; v < reference.height(); ++v) {
    for (int u = 0; u < reference.width(); ++u) {
      if (!Interior(a.object, u, v, emitter_meshes)) continue;
      const Eigen::Vector3d x = a.radiance(u, v).cast<double>(),
                            y = b.radiance(u, v).cast<double>();
      const Eigen::Vector3d ours = 0.5 * (x + y), ref = reference(u, v).cast<double>();
      RegionComparison& r = regions[a.object(u, v)];
      r.mesh = a.object(u, v);
      ++r.pixels;
      r.mean_ours += ours;
      r.mean_reference += ref;
      const double lum = Luminance(ref);
      if (lum > 0.0) {
        // The mean of two independent renders has half the variance of one: noise = |x - y| / 2.
        pixels.push_back({lum, (Luminance(ours) - lum) / lum, Luminance(x - y) / (2.0 * lum)});
      }
    }
  }
  ImageComparison result;
  for (auto& [mesh, r] : regions) {
    if (r.pixels < min_region_pixels) continue;
    r.mean_ours /= static_cast<double>(r.pixels);
    r.mean_reference /= static_cast<double>(r.pixels);
    result.regions.push_back(r);
  }
  // Brighter half by reference luminance, as the reference's own noise figures are measured.
  std::sort(pixels.begin(), pixels.end(), [](const Pixel& p, const Pixel& q) {
    return p.reference_luminance > q.reference_luminance;
  });
  pixels.resize(pixels.size() / 2);
  double diff2 = 0.0, noise2 = 0.0;
  for (const Pixel& p : pixels) {
    diff2 += p.relative_difference * p.relative_difference;
    noise2 += p.relative_noise * p.relative_noise;
  }
  result.pixels = pixels.size();
  if (!pixels.empty()) {
    result.rms_relative_difference = std::sqrt(diff2 / pixels.size());
    result.ours_relative_noise = std::sqrt(noise2 / pixels.size());
  }
  return result;
}

}  // namespace genscene::render
