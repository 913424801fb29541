// The held-out judge's scores (apps/holdout.h) on images with known answers.
#include "apps/holdout.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace genscene::apps {
namespace {

ImageRgb Pattern(int w, int h) {
  ImageRgb image(w, h);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      image(u, v) = Eigen::Vector3f(0.3f + 0.2f * std::sin(0.3f * u),
                                    0.4f + 0.2f * std::cos(0.2f * v), 0.25f);
    }
  }
  return image;
}

// A prediction off by an exposure and white balance scores as the reference itself: the gain takes
// the scale out (2, 0.5, 1 -> 0.5, 2, 1), the error is 0 and SSIM 1, pixels outside the mask
// left out whatever they hold.
TEST(HeldOutScore, GainTakesOutExposureAndWhiteBalance) {
  const ImageRgb reference = Pattern(40, 30);
  ImageRgb prediction = reference;
  Image<uint8_t> mask(40, 30, 1);
  for (size_t i = 0; i < prediction.size(); ++i)
    prediction.data()[i] = prediction.data()[i].cwiseProduct(Eigen::Vector3f(2, 0.5f, 1));
  for (int v = 0; v < 30; ++v) mask(0, v) = 0, prediction(0, v) = Eigen::Vector3f(100, 100, 100);
  const HeldOutScore s = ScorePrediction(prediction, reference, mask);
  EXPECT_NEAR(s.gain.x(), 0.5, 1e-6);
  EXPECT_NEAR(s.gain.y(), 2.0, 1e-6);
  EXPECT_NEAR(s.gain.z(), 1.0, 1e-6);
  EXPECT_LT(s.rmse, 1e-6);
  EXPECT_NEAR(s.ssim, 1.0, 1e-4);
}

// Noise raises the error by its relative size and lowers SSIM; an unrelated image scores far worse.
TEST(HeldOutScore, NoiseAndUnrelatedImagesScoreWorse) {
  const ImageRgb reference = Pattern(40, 30);
  const Image<uint8_t> mask(40, 30, 1);
  std::mt19937 rng(3);
  std::normal_distribution<float> n(0.0f, 0.05f);
  ImageRgb noisy = reference, flat(40, 30, Eigen::Vector3f::Constant(0.3f));
  double ref = 0.0;
  for (size_t i = 0; i < noisy.size(); ++i) {
    noisy.data()[i] += Eigen::Vector3f(n(rng), n(rng), n(rng));
    ref += reference.data()[i].cast<double>().squaredNorm();
  }
  const HeldOutScore s = ScorePrediction(noisy, reference, mask);
  const double expected =
      0.05 * std::sqrt(3.0 * reference.size() / ref);  // noise over the reference's RMS
  EXPECT_NEAR(s.rmse, expected, 0.2 * expected);
  EXPECT_LT(s.ssim, 0.95);
  EXPECT_GT(s.ssim, 0.3);
  const HeldOutScore f = ScorePrediction(flat, reference, mask);
  EXPECT_GT(f.rmse, 1.5 * s.rmse);
  EXPECT_LT(f.ssim, s.ssim);
  EXPECT_NEAR(MaskedSsim(reference, reference, mask), 1.0, 1e-6);
}

}  // namespace
}  // namespace genscene::apps
