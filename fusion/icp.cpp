#include "fusion/icp.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <optional>

#include "core/options.h"
#include "core/parallel.h"
#include "core/se3.h"

namespace genscene::fusion {

void IcpOptions::Validate() const {
  RequireRange("icp_iterations_fine", iterations_fine, 0, 100);
  RequireRange("icp_iterations_middle", iterations_middle, 0, 100);
  RequireRange("icp_iterations_coarse", iterations_coarse, 0, 100);
  RequireRange("icp_max_distance", max_distance, 1e-4, 10.0);
  RequireRange("icp_max_angle", max_angle, 1.0, 90.0);
  RequireRange("icp_huber_delta", huber_delta, 1e-5, 10.0);
  RequireRange("icp_min_step", min_step, 0.0, 1e-2);
  RequireRange("degenerate_eigen_ratio", degenerate_eigen_ratio, 0.0, 0.5);
  RequireRange("min_inlier_ratio", min_inlier_ratio, 0.0, 1.0);
  RequireRange("max_rms_residual", max_rms_residual, 1e-5, 10.0);
  RequireRange("max_translation", max_translation, 1e-3, 1e4);
  RequireRange("max_rotation", max_rotation, 0.1, 180.0);
  RequireRange("icp_color_weight", color_weight, 0.0, 10.0);
  RequireRange("icp_color_huber", color_huber, 1e-4, 1.0);
}

namespace {

// Normal equations of the point-to-plane residuals of a set of rows.
struct NormalEquations {
  Matrix6d jtj = Matrix6d::Zero();
  Vector6d jtr = Vector6d::Zero();
  double squared_residuals = 0.0;  // unweighted
  double squared_ranges = 0.0;     // |q|^2, for the rotation scale
  size_t inliers = 0;
  size_t valid = 0;            // live pixels with vertex and normal
  double squared_color = 0.0;  // unweighted brightness differences
  size_t color_pixels = 0;

  NormalEquations& operator+=(const NormalEquations& o) {
    jtj += o.jtj;
    jtr += o.jtr;
    squared_residuals += o.squared_residuals;
    squared_ranges += o.squared_ranges;
    inliers += o.inliers;
    valid += o.valid;
    squared_color += o.squared_color;
    color_pixels += o.color_pixels;
    return *this;
  }
};

// The brightness of the model's frame at the live level (bilinear, with its gradient).
struct ColorLevel {
  const IntensityLevel* live = nullptr;
  const IntensityLevel* model = nullptr;
  double noise = 0.0;  // of the brightness difference's images at this level
};

NormalEquations Accumulate(const PyramidLevel& live, const RaycastResult& model,
                           const CameraIntrinsics& mk, const Eigen::Isometry3d& model_from_live,
                           const IcpOptions& options, const ColorLevel& color = ColorLevel()) {
  const Eigen::Matrix3f r = model_from_live.linear().cast<float>();
  const Eigen::Vector3f t = model_from_live.translation().cast<float>();
  const float fx = static_cast<float>(mk.fx), fy = static_cast<float>(mk.fy);
  const float cx = static_cast<float>(mk.cx), cy = static_cast<float>(mk.cy);
  const float max_distance = static_cast<float>(options.max_distance);
  const float min_cos = static_cast<float>(std::cos(options.max_angle * M_PI / 180.0));
  const float huber = static_cast<float>(options.huber_delta);
  const int w = live.vertices.width();
  const float mwf = static_cast<float>(mk.width), mhf = static_cast<float>(mk.height);
  const size_t rows = static_cast<size_t>(live.vertices.height());
  // The photometric term projects into the model frame's image at this level.
  const bool with_color = color.live && color.model && options.color_weight > 0.0;
  const CameraIntrinsics& lk = live.intrinsics;
  const float lfx = static_cast<float>(lk.fx), lfy = static_cast<float>(lk.fy);
  const float lcx = static_cast<float>(lk.cx), lcy = static_cast<float>(lk.cy);
  // Brightness noise above kColorNoiseFloor (path-traced frames at 1 sample a pixel: 0.09 at
  // full resolution; real cameras 0.002-0.004) scales the term down as the residual's standard
  // deviation scales up, so that noise does not outweigh the geometry.
  constexpr double kColorNoiseFloor = 0.01;
  const double weight = options.color_weight * std::min(1.0, kColorNoiseFloor / color.noise);
  const float lambda = static_cast<float>(weight);
  // The Huber threshold in the scaled residual's units at the unscaled weight: in brightness it
  // is color_huber on clean frames and grows with the noise beyond the floor (a few of its
  // standard deviations either way).
  const float color_huber = static_cast<float>(options.color_weight * options.color_huber);
  const int iw = with_color ? color.model->intensity.width() : 0;
  const int ih = with_color ? color.model->intensity.height() : 0;
  return DeterministicReduce(
      rows, 4, NormalEquations(),
      [&](size_t row_begin, size_t row_end) {
        NormalEquations ne;
        for (size_t row = row_begin; row < row_end; ++row) {
          const int v = static_cast<int>(row);
          // One row's sums in float, as the outer products w j (j, r) of rows of 8 (j, the
          // residual r, a zero) that the compiler turns into SIMD; the rows' sums are added in
          // double. A row is at most a few hundred terms (measured on the synthetic room: ATE 0.514
          // against 0.513 cm with double sums).
          Eigen::Matrix<float, 8, 6> sums =
              Eigen::Matrix<float, 8, 6>::Zero();  // column a: w j_a (j, r, 0)
          float squared_residuals = 0.0f, squared_ranges = 0.0f, squared_color = 0.0f;
          for (int u = 0; u < w; ++u) {
            const Eigen::Vector3f& p = live.vertices(u, v);
            const Eigen::Vector3f& n = live.normals(u, v);
            if (p.z() <= 0.0f || n.isZero()) continue;
            ++ne.valid;
            const Eigen::Vector3f q = r * p + t;
            if (q.z() <= 0.0f) continue;
            const float inv_z = 1.0f / q.z();
            const float uf = fx * q.x() * inv_z + cx + 0.5f, vf = fy * q.y() * inv_z + cy + 0.5f;
            if (!(uf >= 0.0f && vf >= 0.0f && uf < mwf && vf < mhf)) continue;
            const int mu = static_cast<int>(uf), mv = static_cast<int>(vf);
            const Eigen::Vector3f& m = model.points(mu, mv);
            const Eigen::Vector3f& nm = model.normals(mu, mv);
            if (m.z() <= 0.0f || nm.isZero()) continue;
            const Eigen::Vector3f d = q - m;
            if (d.squaredNorm() > max_distance * max_distance) continue;
            if ((r * n).dot(nm) < min_cos) continue;
            const float residual = nm.dot(d);
            const Eigen::Vector3f c = q.cross(nm);
            Eigen::Matrix<float, 8, 1> j;
            j << nm, c, residual, 0.0f;
            const float abs_r = std::abs(residual);
            const float weight = abs_r <= huber ? 1.0f : huber / abs_r;
            for (int a = 0; a < 6; ++a) sums.col(a) += (weight * j[a]) * j;
            squared_residuals += residual * residual;
            squared_ranges += q.squaredNorm();
            ++ne.inliers;
            if (!with_color) continue;
            // Photometric: r = I_model(pi(q)) - I_live(u, v); d r / d xi = [a; q x a] with
            // a = J_pi(q)^T grad I_model (xi moves q by v + w x q, as the geometric term).
            const float x = lfx * q.x() * inv_z + lcx, y = lfy * q.y() * inv_z + lcy;
            // Inside the pixels with a gradient (the border row and column have none).
            if (!(x >= 1.0f && y >= 1.0f && x < static_cast<float>(iw - 2) &&
                  y < static_cast<float>(ih - 2))) {
              continue;
            }
            const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
            const float fx1 = x - static_cast<float>(x0), fy1 = y - static_cast<float>(y0);
            auto bilinear = [&](const ImageGray& image) {
              return (1.0f - fy1) * ((1.0f - fx1) * image(x0, y0) + fx1 * image(x0 + 1, y0)) +
                     fy1 * ((1.0f - fx1) * image(x0, y0 + 1) + fx1 * image(x0 + 1, y0 + 1));
            };
            const float color_residual =
                bilinear(color.model->intensity) - color.live->intensity(u, v);
            const float gu = bilinear(color.model->grad_u), gv = bilinear(color.model->grad_v);
            const Eigen::Vector3f a(
                lambda * gu * lfx * inv_z, lambda * gv * lfy * inv_z,
                -lambda * (gu * lfx * q.x() + gv * lfy * q.y()) * inv_z * inv_z);
            const float rc = lambda * color_residual;
            const Eigen::Vector3f qa = q.cross(a);
            Eigen::Matrix<float, 8, 1> jc;
            jc << a.x(), a.y(), a.z(), qa.x(), qa.y(), qa.z(), rc, 0.0f;
            const float abs_rc = std::abs(rc);
            const float wc = abs_rc <= color_huber ? 1.0f : color_huber / abs_rc;
            for (int k = 0; k < 6; ++k) sums.col(k) += (wc * jc[k]) * jc;
            squared_color += color_residual * color_residual;
            ++ne.color_pixels;
          }
          for (int a = 0; a < 6; ++a) {
            for (int b = a; b < 6; ++b) ne.jtj(a, b) += sums(b, a);  // upper triangle only
            ne.jtr[a] += sums(6, a);
          }
          ne.squared_residuals += squared_residuals;
          ne.squared_ranges += squared_ranges;
          ne.squared_color += squared_color;
        }
        return ne;
      },
      [](NormalEquations a, const NormalEquations& b) { return a += b; });
}

struct Step {
  Vector6d xi = Vector6d::Zero();
  double condition = 0.0;
  int constrained = 0;
};

// Solves J^T J xi = -J^T r in the eigen-directions the data constrains (rotation scaled to metres
// at the RMS range so that eigenvalues compare like with like).
Step SolveConstrained(const NormalEquations& ne, double ratio) {
  Step step;
  const double range = std::sqrt(ne.squared_ranges / static_cast<double>(ne.inliers));
  Vector6d scale;
  scale << 1, 1, 1, 1 / range, 1 / range, 1 / range;
  Matrix6d jtj = ne.jtj.selfadjointView<Eigen::Upper>();
  jtj = scale.asDiagonal() * jtj * scale.asDiagonal();
  const Vector6d jtr = scale.asDiagonal() * ne.jtr;
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(jtj);
  const Vector6d lambda = eig.eigenvalues();  // ascending
  const double largest = lambda[5];
  if (!(largest > 0.0)) return step;
  step.condition = lambda[0] > 0.0 ? largest / lambda[0] : std::numeric_limits<double>::infinity();
  Vector6d scaled_xi = Vector6d::Zero();
  for (int i = 0; i < 6; ++i) {
    if (lambda[i] < ratio * largest || lambda[i] <= 0.0) continue;
    const Vector6d e = eig.eigenvectors().col(i);
    scaled_xi -= (e.dot(jtr) / lambda[i]) * e;
    ++step.constrained;
  }
  step.xi = scale.asDiagonal() * scaled_xi;
  return step;
}

}  // namespace

IcpReport TrackFrameToModel(const std::vector<PyramidLevel>& live, const RaycastResult& model,
                            const CameraIntrinsics& model_intrinsics, const IcpOptions& options,
                            Eigen::Isometry3d* model_from_live,
                            const std::vector<IntensityLevel>* live_intensity,
                            const std::vector<IntensityLevel>* model_intensity) {
  GS_CHECK(!live.empty());
  const bool with_color = live_intensity && model_intensity && !live_intensity->empty() &&
                          !model_intensity->empty() && options.color_weight > 0.0;
  if (with_color) {
    GS_CHECK_EQ(live_intensity->size(), live.size());
    GS_CHECK_EQ(model_intensity->size(), live.size());
  }
  auto color_at = [&](size_t level) {
    ColorLevel c;
    if (with_color) {
      c.live = &(*live_intensity)[level];
      c.model = &(*model_intensity)[level];
      GS_CHECK(
          c.live->intensity.SameSize(live[level].vertices.width(), live[level].vertices.height()));
      GS_CHECK(c.model->intensity.SameSize(c.live->intensity));
      c.noise = std::max(c.live->noise, c.model->noise);
    }
    return c;
  };
  GS_CHECK(model.points.SameSize(model_intrinsics.width, model_intrinsics.height));
  const int per_level[3] = {options.iterations_fine, options.iterations_middle,
                            options.iterations_coarse};
  IcpReport report;
  Eigen::Isometry3d pose = *model_from_live;
  // The full-resolution sums of the final pose, when the last iteration left it (nearly) there.
  std::optional<NormalEquations> final_ne;
  for (int level = static_cast<int>(live.size()) - 1; level >= 0; --level) {
    const int iterations = per_level[std::min(level, 2)];
    for (int it = 0; it < iterations; ++it) {
      NormalEquations ne = Accumulate(live[static_cast<size_t>(level)], model, model_intrinsics,
                                      pose, options, color_at(static_cast<size_t>(level)));
      // The level stops when too few inliers or no constrained direction leave no step, or when
      // the step was below min_step.
      bool stop = ne.inliers < 6;
      if (!stop) {
        const Step step = SolveConstrained(ne, options.degenerate_eigen_ratio);
        stop = step.constrained == 0;
        if (!stop) {
          pose = ExpSE3(step.xi) * pose;
          ++report.iterations;
          stop = step.xi.norm() < options.min_step;
        }
      }
      if (stop) {
        // The pose moved by less than min_step since these sums (or not at all), which then
        // serve as the quality figures at full resolution (saves a pass on most frames).
        if (level == 0) final_ne = std::move(ne);
        break;
      }
    }
  }
  // Quality figures of the final pose at full resolution.
  const NormalEquations ne =
      final_ne ? *final_ne
               : Accumulate(live[0], model, model_intrinsics, pose, options, color_at(0));
  report.valid_pixels = ne.valid;
  report.inliers = ne.inliers;
  report.inlier_ratio =
      ne.valid > 0 ? static_cast<double>(ne.inliers) / static_cast<double>(ne.valid) : 0.0;
  if (ne.inliers >= 6) {
    report.rms_residual = std::sqrt(ne.squared_residuals / static_cast<double>(ne.inliers));
    constexpr double kMinSigma = 1e-3;  // m
    const double sigma = std::max(report.rms_residual, kMinSigma);
    report.information = Matrix6d(ne.jtj.selfadjointView<Eigen::Upper>()) / (sigma * sigma);
    const Step step = SolveConstrained(ne, options.degenerate_eigen_ratio);
    report.condition = step.condition;
    report.constrained_directions = step.constrained;
  }
  report.degenerate = report.constrained_directions < 6;
  report.color_pixels = ne.color_pixels;
  if (ne.color_pixels > 0)
    report.color_rms = std::sqrt(ne.squared_color / static_cast<double>(ne.color_pixels));
  *model_from_live = pose;
  return report;
}

}  // namespace genscene::fusion
