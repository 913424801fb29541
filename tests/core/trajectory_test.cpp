#include "core/trajectory.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/check.h"
#include "core/rng.h"
#include "core/se3.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

Trajectory RandomTrajectory(int n) {
  CounterRng rng(7, 8);
  Trajectory trajectory;
  for (int i = 0; i < n; ++i) {
    Vector6d xi;
    for (int k = 0; k < 6; ++k) xi[k] = 2.0 * rng.UniformDouble() - 1.0;
    trajectory.Add(1305031453.359684 + i * 0.033, ExpSE3(xi));
  }
  return trajectory;
}

TEST(Trajectory, TumRoundTrip) {
  test::TempDir dir;
  const Trajectory original = RandomTrajectory(20);
  WriteTumTrajectory(dir / "t.txt", original);
  const Trajectory back = ReadTumTrajectory(dir / "t.txt");
  ASSERT_EQ(back.size(), original.size());
  for (size_t i = 0; i < back.size(); ++i) {
    // Timestamps to the microsecond (TUM's 6 decimals), poses to 9 significant digits.
    EXPECT_NEAR(back.poses()[i].timestamp, original.poses()[i].timestamp, 1e-6);
    EXPECT_LT((back.poses()[i].world_from_camera.matrix() -
               original.poses()[i].world_from_camera.matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-8);
  }
  EXPECT_EQ(test::CountFilesContaining(dir.path(), ".tmp-"), 0);
}

TEST(Trajectory, NearestAndInterpolate) {
  Trajectory t;
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity(), b = Eigen::Isometry3d::Identity();
  b.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);
  t.Add(10.0, a);
  t.Add(10.1, b);
  ASSERT_TRUE(t.Nearest(10.04, 0.05).has_value());
  EXPECT_EQ(t.Nearest(10.04, 0.05)->timestamp, 10.0);
  EXPECT_EQ(t.Nearest(10.06, 0.05)->timestamp, 10.1);
  EXPECT_FALSE(t.Nearest(10.3, 0.05).has_value());
  const auto mid = t.Interpolate(10.025, 0.2);
  ASSERT_TRUE(mid.has_value());
  EXPECT_NEAR(mid->translation().x(), 0.25, 1e-9);
  EXPECT_FALSE(t.Interpolate(10.025, 0.05).has_value());  // gap 0.1 s > 0.05 s
  EXPECT_FALSE(t.Interpolate(9.0, 1.0).has_value());      // before the first pose
}

TEST(Trajectory, MalformedLinesNameFileAndLine) {
  test::TempDir dir;
  const std::vector<std::string> bad = {"1.0 0 0 0 0 0 0",                        // 7 values
                                        "1.0 0 0 0 0 0 0 x",                      // not a number
                                        "1.0 0 0 0 0 0 0 0",                      // zero quaternion
                                        "1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1"};  // duplicate stamp
  for (const auto& text : bad) {
    std::ofstream(dir / "gt.txt") << "# header\n" << text << "\n";
    try {
      ReadTumTrajectory(dir / "gt.txt");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("gt.txt"), std::string::npos) << e.what();
    }
  }
}

TEST(Trajectory, ReadsRedwoodLog) {
  GS_REQUIRE_SHARED_DATA(data);
  const Trajectory t = ReadRedwoodLog(data / "real/open3d-testdata-rgbd/odometry.log");
  ASSERT_EQ(t.size(), 5u);
  // First block: identity rotation, translation (2, 2, -0.3).
  EXPECT_TRUE(t.poses()[0].world_from_camera.translation().isApprox(Eigen::Vector3d(2, 2, -0.3)));
  EXPECT_TRUE(t.poses()[0].world_from_camera.rotation().isIdentity(1e-9));
}

TEST(Trajectory, TumGroundTruthCoversFr1DeskFramesWithin10ms) {
  GS_REQUIRE_SHARED_DATA(data);
  const Trajectory gt = ReadTumTrajectory(data / "real/tum-fr1desk-9f/groundtruth.txt");
  EXPECT_EQ(gt.size(), 2335u);
}

}  // namespace
}  // namespace genscene
