#include "inverse/lights/light_metrics.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "core/check.h"
#include "inverse/lights/pixel_sampling.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on

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
