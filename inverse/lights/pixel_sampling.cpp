#include "inverse/lights/pixel_sampling.h"

#include <algorithm>
#include <utility>

#include "core/check.h"
#include "core/color.h"
#include "core/rng.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on

namespace {

void CheckView(const PosedImage& tv, size_t index) {
  const CameraIntrinsics& k = tv.view.intrinsics;
  k.Validate(Format("view ", index));
  if (tv.image.width() != k.width || tv.image.height() != k.height) {
    throw Error(Format("view ", index, ": image ", tv.image.width(), "x", tv.image.height(),
                       " but intrinsics say ", k.width, "x", k.height));
  }
}

// Marks the pixels whose camera ray hits a reflecting surface and that are not saturated (1 in
// `valid`), counts the others, and lists the luminance of the marked ones in raster order.
void MaskMissedAndSaturated(const PathTracer& tracer, const PosedImage& tv,
                            const LightEstimationOptions& options, Image<uint8_t>* valid,
                            PixelMaskCounts* counts, std::vector<float>* luminance) {
  const CameraIntrinsics& k = tv.view.intrinsics;
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
        ++counts->miss;
      } else if (options.saturation > 0.0 && observed.maxCoeff() >= options.saturation) {
        ++counts->saturated;
      } else {
        (*valid)(u, v) = 1;
        luminance->push_back(Luminance(observed));
      }
    }
  }
}

// Emitters seen directly: far brighter (emitter_factor x the 95th percentile of `luminance`, the
// valid pixels') than anything the lit surfaces show. The box filter mixes an emitter into the
// pixels around it: those go too (8-neighbours).
void MaskEmittersSeenDirectly(const PosedImage& tv, const LightEstimationOptions& options,
                              const std::vector<float>& luminance, Image<uint8_t>* valid,
                              PixelMaskCounts* counts) {
  const CameraIntrinsics& k = tv.view.intrinsics;
  std::vector<float> sorted = luminance;
  const size_t at = static_cast<size_t>(0.95 * static_cast<double>(sorted.size() - 1));
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(at), sorted.end());
  const double limit = options.emitter_factor * std::max(0.0f, sorted[at]);
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
      if ((*valid)(u, v) && near) {
        (*valid)(u, v) = 0;
        ++counts->emitter;
      }
    }
  }
}

// Up to pixels_per_view of the valid pixels of view `i` (raster indices), drawn by a partial
// Fisher-Yates shuffle (the first n of a seeded shuffle), then in raster order.
std::vector<int> DrawPixels(const Image<uint8_t>& valid, const LightEstimationOptions& options,
                            uint64_t seed, size_t i) {
  std::vector<int> candidates;
  for (size_t p = 0; p < valid.size(); ++p) {
    if (valid.data()[p]) candidates.push_back(static_cast<int>(p));
  }
  const size_t n = std::min(candidates.size(), static_cast<size_t>(options.pixels_per_view));
  CounterRng rng(seed, 0x9E3779B97F4A7C15ull, i);
  for (size_t a = 0; a < n; ++a) {
    const size_t b = a + rng.UniformInt(static_cast<uint32_t>(candidates.size() - a));
    std::swap(candidates[a], candidates[b]);
  }
  candidates.resize(n);
  std::sort(candidates.begin(), candidates.end());
  return candidates;
}

}  // namespace

Image<uint8_t> ValidPixels(const PathTracer& tracer, const PosedImage& tv,
                           const LightEstimationOptions& options, PixelMaskCounts* counts) {
  const CameraIntrinsics& k = tv.view.intrinsics;
  Image<uint8_t> valid(k.width, k.height, 0);
  PixelMaskCounts local;
  std::vector<float> luminance;
  MaskMissedAndSaturated(tracer, tv, options, &valid, &local, &luminance);
  if (!luminance.empty()) MaskEmittersSeenDirectly(tv, options, luminance, &valid, &local);
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
    const int width = views[i].image.width();
    for (int p : DrawPixels(valid, options, seed, i)) {
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
        "an emitter or is saturated)");
  }
  return out;
}

}  // namespace genscene::inverse
