#include "fusion/feature_align.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <vector>

#include "core/check.h"
#include "core/color.h"
#include "core/options.h"

namespace genscene::fusion {
namespace {

// 8-bit display-encoded luminance: ORB's FAST threshold and its binary tests are made for
// display-encoded images, not linear ones (whose dark half would hold few codes).
cv::Mat GrayImage(const ImageRgb& color) {
  cv::Mat gray(color.height(), color.width(), CV_8UC1);
  for (int v = 0; v < color.height(); ++v) {
    auto* row = gray.ptr<unsigned char>(v);
    for (int u = 0; u < color.width(); ++u) {
      const float l = Luminance(color(u, v));
      const float y = std::isfinite(l) ? LinearToSrgb(std::clamp(l, 0.0f, 1.0f)) : 0.0f;
      row[u] = static_cast<unsigned char>(std::lround(255.0f * y));
    }
  }
  return gray;
}

void Detect(const cv::Mat& gray, int max_features, std::vector<cv::KeyPoint>* keypoints,
            cv::Mat* descriptors) {
  cv::Ptr<cv::ORB> orb = cv::ORB::create(max_features);
  orb->detectAndCompute(gray, cv::noArray(), *keypoints, *descriptors);
}

// Lowe's ratio test in each direction; a pair is kept when each is the other's best.
std::vector<cv::DMatch> MutualRatioMatches(const cv::Mat& a, const cv::Mat& b, double ratio) {
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> ab, ba;
  matcher.knnMatch(a, b, ab, 2);
  matcher.knnMatch(b, a, ba, 2);
  std::vector<int> best_ba(static_cast<size_t>(b.rows), -1);
  for (const auto& m : ba) {
    if (m.size() == 2 && m[0].distance < ratio * m[1].distance)
      best_ba[static_cast<size_t>(m[0].queryIdx)] = m[0].trainIdx;
  }
  std::vector<cv::DMatch> out;
  for (const auto& m : ab) {
    if (m.size() == 2 && m[0].distance < ratio * m[1].distance &&
        best_ba[static_cast<size_t>(m[0].trainIdx)] == m[0].queryIdx) {
      out.push_back(m[0]);
    }
  }
  return out;
}

// Depth at a keypoint: the nearest pixel's, or nothing where it has none.
float DepthAt(const ImageDepth& depth, const cv::Point2f& p) {
  const int u = static_cast<int>(std::lround(p.x)), v = static_cast<int>(std::lround(p.y));
  if (u < 0 || v < 0 || u >= depth.width() || v >= depth.height()) return 0.0f;
  return depth(u, v);
}

}  // namespace

struct FeatureFrame::Data {
  std::vector<cv::KeyPoint> points;
  cv::Mat descriptors;
};

FeatureFrame::FeatureFrame(const ImageRgb& color, int max_features) {
  if (color.empty()) return;
  auto data = std::make_shared<Data>();
  Detect(GrayImage(color), max_features, &data->points, &data->descriptors);
  data_ = std::move(data);
}

void FeatureAlignOptions::Validate() const {
  RequireRange("feature_max", max_features, 50, 100000);
  RequireRange("feature_min_inliers", min_inliers, 6, 100000);
  // Not options a user sets (fixed in the struct).
  GS_CHECK(ratio > 0.0 && ratio <= 1.0);
  GS_CHECK(reprojection_error > 0.0);
}

std::optional<Eigen::Isometry3d> AlignByFeatures(
    const FeatureFrame& reference, const ImageDepth& reference_depth, const FeatureFrame& live,
    const CameraIntrinsics& k, const FeatureAlignOptions& options, FeatureAlignReport* report) {
  FeatureAlignReport local;
  FeatureAlignReport& r = report ? *report : local;
  r = FeatureAlignReport();
  if (reference.empty() || live.empty()) return std::nullopt;
  const std::vector<cv::KeyPoint>& ref_points = reference.data().points;
  const std::vector<cv::KeyPoint>& live_points = live.data().points;
  const cv::Mat& ref_descriptors = reference.data().descriptors;
  const cv::Mat& live_descriptors = live.data().descriptors;
  r.reference_keypoints = static_cast<int>(ref_points.size());
  r.live_keypoints = static_cast<int>(live_points.size());
  if (ref_points.size() < static_cast<size_t>(options.min_inliers) ||
      live_points.size() < static_cast<size_t>(options.min_inliers)) {
    return std::nullopt;
  }

  std::vector<cv::Point3f> object;  // reference camera frame, metres
  std::vector<cv::Point2f> image;   // live pixels
  for (const cv::DMatch& m : MutualRatioMatches(ref_descriptors, live_descriptors, options.ratio)) {
    const cv::Point2f p = ref_points[static_cast<size_t>(m.queryIdx)].pt;
    const float z = DepthAt(reference_depth, p);
    if (!(z > 0.0f) || !std::isfinite(z)) continue;
    const Eigen::Vector3d x = k.Unproject(p.x, p.y, z);
    object.emplace_back(static_cast<float>(x.x()), static_cast<float>(x.y()),
                        static_cast<float>(x.z()));
    image.push_back(live_points[static_cast<size_t>(m.trainIdx)].pt);
  }
  r.matches = static_cast<int>(object.size());
  if (object.size() < static_cast<size_t>(options.min_inliers)) return std::nullopt;

  const cv::Matx33d camera(k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  const bool found = cv::solvePnPRansac(
      object, image, camera, cv::noArray(), rvec, tvec, /*useExtrinsicGuess=*/false,
      /*iterationsCount=*/500, static_cast<float>(options.reprojection_error),
      /*confidence=*/0.999, inliers, cv::SOLVEPNP_EPNP);
  r.inliers = static_cast<int>(inliers.size());
  if (!found || inliers.size() < static_cast<size_t>(options.min_inliers)) return std::nullopt;
  // Refine on the inliers (Levenberg-Marquardt on the reprojection error).
  std::vector<cv::Point3f> object_in;
  std::vector<cv::Point2f> image_in;
  for (int i : inliers) {
    object_in.push_back(object[static_cast<size_t>(i)]);
    image_in.push_back(image[static_cast<size_t>(i)]);
  }
  cv::solvePnPRefineLM(object_in, image_in, camera, cv::noArray(), rvec, tvec);

  cv::Mat rotation;
  cv::Rodrigues(rvec, rotation);
  Eigen::Isometry3d live_from_reference = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) live_from_reference.linear()(i, j) = rotation.at<double>(i, j);
    live_from_reference.translation()(i) = tvec.at<double>(i);
  }
  if (!live_from_reference.matrix().allFinite()) return std::nullopt;
  return live_from_reference.inverse();
}

}  // namespace genscene::fusion
