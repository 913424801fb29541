#include "core/synthetic.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/parallel.h"

namespace genscene {
namespace {

TEST(Synthetic, SphereDepthMatchesClosedForm) {
  SyntheticScene scene;
  scene.spheres.push_back({Eigen::Vector3d(0.0, 0.0, 3.0), 1.0, Eigen::Vector3f::Ones()});
  CameraIntrinsics k;
  k.width = 41, k.height = 31, k.fx = k.fy = 40.0, k.cx = 20.0, k.cy = 15.0;
  const RgbdFrame frame = RenderSyntheticFrame(scene, k, Eigen::Isometry3d::Identity(), 0.0);
  // The ray through the principal point hits the sphere at z = 2.
  EXPECT_NEAR(frame.depth(20, 15), 2.0f, 1e-6);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Eigen::Vector3d d = k.RayDirection(u, v);
      // |t d - c|^2 = 1 with c = (0, 0, 3): (d.d) t^2 - 6 t + 8 = 0.
      const double a = d.squaredNorm(), disc = 36.0 - 32.0 * a;
      const float z = frame.depth(u, v);
      if (disc < 0.0) {
        EXPECT_EQ(z, 0.0f);
      } else {
        EXPECT_NEAR(z, (6.0 - std::sqrt(disc)) / (2.0 * a), 1e-5) << u << "," << v;
      }
    }
  }
}

TEST(Synthetic, CornellRoomIsClosedAndMeshMatchesRays) {
  const SyntheticScene scene = MakeCornellScene();
  CameraIntrinsics k;
  k.width = 64, k.height = 48, k.fx = k.fy = 40.0, k.cx = 31.5, k.cy = 23.5;
  const Eigen::Isometry3d pose = LookAt({0.0, -0.9, 1.0}, {0.0, 0.0, 0.6});
  const RgbdFrame frame = RenderSyntheticFrame(scene, k, pose, 0.0);
  for (float z : frame.depth.pixels()) EXPECT_GT(z, 0.0f);  // closed room: every ray hits
  const TriangleMesh mesh = scene.ToMesh(2);
  EXPECT_NO_THROW(mesh.Validate("cornell"));
  EXPECT_EQ(mesh.face_colors.size(), mesh.faces.size());
  // Every vertex lies on the surface the ray caster sees: inside or on the room box.
  const Eigen::AlignedBox3f room(Eigen::Vector3f(-1, -1, 0), Eigen::Vector3f(1, 1, 2));
  for (const auto& v : mesh.vertices) EXPECT_TRUE(room.exteriorDistance(v) < 1e-6f);
  // The left wall (-x) is red, the right wall green.
  const int left = 0, right = 2;  // faces 0-1: wall -x, faces 2-3: wall +x
  EXPECT_GT(mesh.face_colors[left].x(), mesh.face_colors[left].y());
  EXPECT_GT(mesh.face_colors[right].y(), mesh.face_colors[right].x());
  // Room walls face inwards: the -x wall's normal points to +x.
  EXPECT_GT(mesh.FaceNormalScaled(left).x(), 0.0f);
  EXPECT_LT(mesh.FaceNormalScaled(right).x(), 0.0f);
}

TEST(Synthetic, LookAtUsesOpenCvAxes) {
  const Eigen::Isometry3d pose = LookAt({0, -2, 0}, {0, 0, 0});
  EXPECT_TRUE(pose.linear().col(2).isApprox(Eigen::Vector3d(0, 1, 0)));   // z forward
  EXPECT_TRUE(pose.linear().col(0).isApprox(Eigen::Vector3d(1, 0, 0)));   // x right
  EXPECT_TRUE(pose.linear().col(1).isApprox(Eigen::Vector3d(0, 0, -1)));  // y down
  EXPECT_NEAR(pose.linear().determinant(), 1.0, 1e-12);
}

TEST(Synthetic, KinectNoiseIsSeededAndThreadIndependent) {
  ImageDepth a(50, 40, 2.0f), b(50, 40, 2.0f), c(50, 40, 2.0f);
  a(0, 0) = b(0, 0) = c(0, 0) = 0.0f;
  SetThreadCount(1);
  AddKinectDepthNoise(a, 7, 3);
  SetThreadCount(2);
  AddKinectDepthNoise(b, 7, 3);
  SetThreadCount(0);
  AddKinectDepthNoise(c, 8, 3);
  EXPECT_EQ(a.pixels(), b.pixels());
  EXPECT_NE(a.pixels(), c.pixels());
  EXPECT_EQ(a(0, 0), 0.0f);  // invalid stays invalid
}

TEST(Synthetic, KinectNoiseLevelAndQuantisation) {
  // On a flat wall at 2 m: no edges inside, so only the border of the invalid pixel can drop.
  ImageDepth depth(120, 100, 2.0f);
  AddKinectDepthNoise(depth, 1, 0);
  const double fb = 580.0 * 0.075, step = 2.0 * 2.0 / (8.0 * fb);  // dz = z^2 / (8 f b)
  double sum2 = 0.0;
  size_t n = 0;
  for (float z : depth.pixels()) {
    ASSERT_GT(z, 0.0f);
    // Every value is a quantisation level f b / (k / 8).
    const double k = 8.0 * fb / z;
    EXPECT_NEAR(k, std::round(k), 1e-3 * k);
    sum2 += (z - 2.0) * (z - 2.0);
    ++n;
  }
  const double sigma = 0.0012 + 0.0019 * 1.6 * 1.6;
  const double expected = std::sqrt(sigma * sigma + step * step / 12.0);
  EXPECT_NEAR(std::sqrt(sum2 / n), expected, 0.1 * expected);
}

TEST(Synthetic, KinectDropoutsOnlyAtDepthEdges) {
  ImageDepth depth(60, 40, 1.0f);
  for (int v = 0; v < 40; ++v) {
    for (int u = 30; u < 60; ++u) depth(u, v) = 2.0f;  // a step edge between columns 29 and 30
  }
  AddKinectDepthNoise(depth, 3, 0);
  int dropped_at_edge = 0;
  for (int v = 0; v < 40; ++v) {
    for (int u = 0; u < 60; ++u) {
      if (u == 29 || u == 30) {
        dropped_at_edge += depth(u, v) == 0.0f;
      } else {
        EXPECT_GT(depth(u, v), 0.0f) << u << "," << v;
      }
    }
  }
  // 80 edge pixels, each lost with probability 0.5.
  EXPECT_GT(dropped_at_edge, 20);
  EXPECT_LT(dropped_at_edge, 60);
}

}  // namespace
}  // namespace genscene
