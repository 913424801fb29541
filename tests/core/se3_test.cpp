#include "core/se3.h"

#include <gtest/gtest.h>

#include "core/check.h"
#include "core/rng.h"

namespace genscene {
namespace {

Vector6d RandomTwist(CounterRng& rng, double scale) {
  Vector6d xi;
  for (int i = 0; i < 6; ++i) xi[i] = scale * (2.0 * rng.UniformDouble() - 1.0);
  return xi;
}

TEST(Se3, ExpLogAreInverse) {
  CounterRng rng(1, 2);
  for (int i = 0; i < 100; ++i) {
    const Vector6d xi = RandomTwist(rng, i < 50 ? 1.0 : 1e-6);
    const Vector6d back = LogSE3(ExpSE3(xi));
    EXPECT_LT((back - xi).norm(), 1e-9 * std::max(1.0, xi.norm())) << xi.transpose();
  }
}

TEST(Se3, ExpOfPureTranslation) {
  Vector6d xi = Vector6d::Zero();
  xi.head<3>() << 1.0, 2.0, 3.0;
  const Eigen::Isometry3d t = ExpSE3(xi);
  EXPECT_TRUE(t.rotation().isIdentity(1e-12));
  EXPECT_TRUE(t.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
}

TEST(Se3, TranslationQuaternionRoundTripWithPositiveW) {
  CounterRng rng(3, 4);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Isometry3d pose = ExpSE3(RandomTwist(rng, 3.0));
    Eigen::Vector3d t;
    Eigen::Quaterniond q;
    ToTranslationQuaternion(pose, &t, &q);
    EXPECT_GE(q.w(), 0.0);
    const Eigen::Isometry3d back = PoseFromTranslationQuaternion(t, q);
    EXPECT_TRUE(back.matrix().isApprox(pose.matrix(), 1e-12));
  }
}

TEST(Se3, RejectsZeroQuaternion) {
  EXPECT_THROW(PoseFromTranslationQuaternion({0, 0, 0}, Eigen::Quaterniond(0, 0, 0, 0)), Error);
}

TEST(Se3, InterpolationHalfwayHalvesAngleAndTranslation) {
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d b = Eigen::Isometry3d::Identity();
  b.linear() = Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  b.translation() = Eigen::Vector3d(2.0, 0.0, -4.0);
  const Eigen::Isometry3d mid = InterpolatePose(a, b, 0.5);
  EXPECT_NEAR(RotationAngle(mid), 0.4, 1e-12);
  EXPECT_TRUE(mid.translation().isApprox(Eigen::Vector3d(1.0, 0.0, -2.0)));
}

TEST(Se3, ValidRigidTransformCheck) {
  Eigen::Matrix4d m = ExpSE3(Vector6d::Constant(0.3)).matrix();
  EXPECT_TRUE(IsValidRigidTransform(m));
  m(0, 0) += 0.1;
  EXPECT_FALSE(IsValidRigidTransform(m));
}

}  // namespace
}  // namespace genscene
