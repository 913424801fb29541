// The viewer's pure parts, without a display: the Mesh Colors tables the fragment shader reads,
// the OpenGL clip matrix against the OpenCV projection, camera names, light glyphs.
#include <gtest/gtest.h>

#include <random>

#include "core/mesh_colors.h"
#include "core/synthetic.h"
#include "tests/test_util.h"
#include "viewer/view_camera.h"
#include "viewer/view_data.h"

namespace genscene::viewer {
namespace {

// The shader's lookup (shaders.h SampleIndex) written once more in C++: the tables must give
// MeshColors::SampleIndex for every lattice point of every face, across mixed resolutions.
TEST(MeshColorsTables, GiveSampleIndexOfEveryLatticePoint) {
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 0}};
  mesh.faces = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
  const MeshColors colors(mesh, {8, 2, 1});
  const MeshColorsTables t = BuildMeshColorsTables(colors);
  ASSERT_EQ(t.face_table.size(), 6u);
  EXPECT_EQ(t.lattice_index.size(), 45u + 6u + 3u);
  EXPECT_EQ(t.rgba.size(), 4 * colors.SampleCount());
  EXPECT_EQ(t.labels, std::vector<int32_t>(colors.SampleCount(), -1));
  for (int f = 0; f < 3; ++f) {
    const int r = t.face_table[2 * f + 1];
    ASSERT_EQ(r, colors.FaceResolution(f));
    for (int j = 0; j <= r; ++j) {
      for (int i = 0; i + j <= r; ++i) {
        const int local = j * (r + 1) - j * (j - 1) / 2 + i;
        EXPECT_EQ(static_cast<uint32_t>(t.lattice_index[t.face_table[2 * f] + local]),
                  colors.SampleIndex(f, i, j))
            << "face " << f << " (" << i << ", " << j << ")";
      }
    }
  }
}

// A world point goes through ClipFromWorld and the viewport to the window pixel whose centre is
// CameraIntrinsics::Project's (u, v) with the row flipped: the screenshot matches the OpenCV
// camera of the path tracer pixel for pixel.
TEST(ViewCamera, ClipMatrixReproducesOpenCvProjection) {
  PosedView view;
  view.intrinsics.width = 64;
  view.intrinsics.height = 48;
  view.intrinsics.fx = 50.0;
  view.intrinsics.fy = 55.0;
  view.intrinsics.cx = 30.2;
  view.intrinsics.cy = 25.7;
  view.world_from_camera = LookAt({0.3, -2.0, 1.2}, {0.0, 0.1, 0.4});
  const ClipRange range{0.1, 20.0};
  const Eigen::Matrix4d clip = ClipFromWorld(view, range).cast<double>();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (int n = 0; n < 100; ++n) {
    const Eigen::Vector3d p(uni(rng), uni(rng), 0.4 + uni(rng));
    const Eigen::Vector4d c = clip * p.homogeneous();
    const Eigen::Vector3d ndc = c.head<3>() / c.w();
    // Window coordinates: pixel centres at half-integers, row 0 at the bottom.
    const double x_window = 0.5 * (ndc.x() + 1.0) * view.intrinsics.width;
    const double y_window = 0.5 * (ndc.y() + 1.0) * view.intrinsics.height;
    const auto uv = view.intrinsics.Project(view.world_from_camera.inverse() * p);
    ASSERT_TRUE(uv.has_value());
    EXPECT_NEAR(x_window - 0.5, uv->x(), 1e-3);
    EXPECT_NEAR(view.intrinsics.height - 0.5 - y_window, uv->y(), 1e-3);
    const double z = (view.world_from_camera.inverse() * p).z();
    EXPECT_NEAR(c.w(), z, 1e-5);
  }
  // Depth: the near plane maps to -1, the far plane to +1.
  const Eigen::Matrix4d k = ClipFromCamera(view.intrinsics, range).cast<double>();
  for (const auto& [z, expected] : {std::pair{0.1, -1.0}, std::pair{20.0, 1.0}}) {
    const Eigen::Vector4d c = k * Eigen::Vector4d(0.0, 0.0, z, 1.0);
    EXPECT_NEAR(c.z() / c.w(), expected, 1e-5);
  }
}

TEST(ViewCamera, OrbitFromPoseKeepsEyeAndViewingDirection) {
  const Eigen::Isometry3d pose = LookAt({1.0, -2.0, 1.5}, {0.0, 0.5, 0.5});
  const OrbitController orbit = OrbitController::FromPose(pose, 2.0);
  const Eigen::Isometry3d back = orbit.WorldFromCamera();
  EXPECT_LT((back.translation() - pose.translation()).norm(), 1e-9);
  EXPECT_LT((back.linear() - pose.linear()).norm(), 1e-9);  // LookAt has no roll
}

TEST(ViewCamera, ParsesCameraNamesAndRejectsOthers) {
  EXPECT_EQ(ParseCameraSpec("overview").kind, CameraSpec::Kind::kOverview);
  const CameraSpec key = ParseCameraSpec("keyframe:3");
  EXPECT_EQ(key.kind, CameraSpec::Kind::kKeyframe);
  EXPECT_EQ(key.keyframe, 3);
  const CameraSpec pose = ParseCameraSpec("1 2 3 0 0 0.7071068 0.7071068");
  EXPECT_EQ(pose.kind, CameraSpec::Kind::kPose);
  EXPECT_LT((pose.world_from_camera.translation() - Eigen::Vector3d(1, 2, 3)).norm(), 1e-12);
  EXPECT_LT((pose.world_from_camera.linear() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY())
                .norm(),
            1e-6);
  for (const char* bad :
       {"", "keyframe:", "keyframe:-1", "keyframe:2x", "1 2 3 0 0 0", "1 2 3 0 0 0 1 9", "top"}) {
    EXPECT_CONTAINS(test::ErrorOf([&] { ParseCameraSpec(bad); }), "is not 'overview'") << bad;
  }
  EXPECT_EQ(ParseSize("320x240"), Eigen::Vector2i(320, 240));
  EXPECT_CONTAINS(test::ErrorOf([] { ParseSize("320"); }), "--size '320'");
  EXPECT_CONTAINS(test::ErrorOf([] { ParseSize("8x8"); }), "[16, 8192]");
}

// The overview of a recording whose world has y down (a TUM-style first camera at the origin):
// the view keeps the cameras' up, looks from their side and from above, and frames the box: every
// corner inside the image, the box's outline at least half the image's narrower side.
TEST(Overview, FramesTheModelWithTheRecordingsUp) {
  Eigen::AlignedBox3d box(Eigen::Vector3d(-1.0, 0.2, 1.0), Eigen::Vector3d(1.0, 1.0, 3.0));
  std::vector<Eigen::Isometry3d> cameras;
  for (double yaw : {-0.2, 0.0, 0.2}) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
    cameras.push_back(pose);
  }
  EXPECT_GT(CamerasUp(cameras).dot(-Eigen::Vector3d::UnitY()), 0.9);
  const CameraIntrinsics k = DefaultIntrinsics(640, 480);
  const Eigen::Isometry3d pose = OverviewOrbit(box, k, cameras).WorldFromCamera();
  EXPECT_GT((-pose.linear().col(1)).dot(-Eigen::Vector3d::UnitY()), 0.7);  // image up = their up
  EXPECT_GT(pose.linear().col(2).dot(Eigen::Vector3d::UnitZ()), 0.3);      // looks their way
  EXPECT_GT(pose.linear().col(2).dot(Eigen::Vector3d::UnitY()), 0.3);      // and down on it
  Eigen::AlignedBox2d outline;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c));
    const auto uv = k.Project(pose.inverse() * corner);
    ASSERT_TRUE(uv.has_value()) << c;
    EXPECT_GE(uv->x(), 0.0);
    EXPECT_LT(uv->x(), k.width);
    EXPECT_GE(uv->y(), 0.0);
    EXPECT_LT(uv->y(), k.height);
    outline.extend(*uv);
  }
  EXPECT_GT(std::max(outline.sizes().x() / k.width, outline.sizes().y() / k.height), 0.5);
}

// The distant light: one arrow (a shaft and a two-segment barb) per weighted direction, from
// outside the box in to the centre of its side, as long as half the diagonal at the top weight.
TEST(LightGlyphs, TheDistantLightComesInFromOutsideTheBox) {
  LightGlyph sky;
  sky.power = {2.0f, 2.0f, 1.0f};
  sky.weights = {0, 0, 0, 0.5f, 1.0f, 0};  // from -y (half) and from +z
  const Eigen::AlignedBox3d box(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(2, 4, 4));
  Overlay overlay;
  AddDistantGlyph(sky, box, &overlay);
  ASSERT_EQ(overlay.lines.size(), 2u * 3 * 2 * 6);  // 2 arrows of 3 segments
  const auto point = [&](int vertex) {
    const float* v = &overlay.lines[static_cast<size_t>(vertex) * 6];
    return Eigen::Vector3d(v[0], v[1], v[2]);
  };
  // -y first: from (1, -1.5, 2) in to the side's centre (1, 0, 2); then +z: from (1, 2, 7).
  EXPECT_LT((point(0) - Eigen::Vector3d(1, -1.5, 2)).norm(), 1e-6);
  EXPECT_LT((point(1) - Eigen::Vector3d(1, 0, 2)).norm(), 1e-6);
  EXPECT_LT((point(6) - Eigen::Vector3d(1, 2, 7)).norm(), 1e-6);
  EXPECT_LT((point(7) - Eigen::Vector3d(1, 2, 4)).norm(), 1e-6);
  EXPECT_FLOAT_EQ(overlay.lines[3], 1.0f);  // colour = power / max channel
  EXPECT_FLOAT_EQ(overlay.lines[5], 0.5f);
  Overlay none;
  sky.power.setZero();
  AddDistantGlyph(sky, box, &none);
  EXPECT_TRUE(none.lines.empty());
}

// Glyphs: one octahedron (8 triangles) per lit light, radius growing as the cube root of the
// power up to `scale` for the strongest, coloured by the power's chromaticity; spokes as long as
// the directional weights say.
TEST(LightGlyphs, SizeAndSpokesFollowPowerAndWeights) {
  LightGlyph dim, bright;
  dim.position = {0, 0, 1};
  dim.power = {1.0f, 0.5f, 0.25f};
  dim.weights = {1, 0, 0, 0, 0, 0.5f};
  bright = dim;
  bright.position = {5, 0, 1};
  bright.power *= 8.0f;
  LightGlyph dark = dim;
  dark.power.setZero();
  Overlay overlay;
  AddLightGlyphs({dim, bright, dark}, 0.1, &overlay);
  ASSERT_EQ(overlay.triangles.size(), 2u * 8 * 3 * 6);  // dark has no glyph
  ASSERT_EQ(overlay.lines.size(), 2u * 2 * 2 * 6);      // two non-zero weights each
  auto extent = [&](int light) {
    double r = 0.0;
    for (int k = 0; k < 24; ++k) {
      const float* v = &overlay.triangles[(24 * light + k) * 6];
      r = std::max(r, (Eigen::Vector3d(v[0], v[1], v[2]) - (light ? bright : dim).position).norm());
    }
    return r;
  };
  EXPECT_NEAR(extent(1) / extent(0), 2.0, 1e-5);  // 8x the power, 2x the radius
  EXPECT_NEAR(extent(1), 0.1, 1e-5);              // the strongest light's radius is `scale`
  // Brighter lights do not make bigger glyphs: the sizes are relative to the strongest.
  Overlay brighter;
  dim.power *= 1000.0f;
  bright.power *= 1000.0f;
  AddLightGlyphs({dim, bright}, 0.1, &brighter);
  ASSERT_EQ(brighter.triangles.size(), 2u * 8 * 3 * 6);
  for (size_t i = 0; i < brighter.triangles.size(); i += 6) {
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(brighter.triangles[i + c], overlay.triangles[i + c], 1e-5);
  }
  EXPECT_FLOAT_EQ(overlay.triangles[3], 1.0f);  // colour = power / max channel
  EXPECT_FLOAT_EQ(overlay.triangles[4], 0.5f);
  // Spokes of the dim light: +x as long as 3 radii, -z half of that.
  const float* s = overlay.lines.data();
  EXPECT_NEAR(s[6] - s[0], 3.0 * extent(0), 1e-5);
  EXPECT_NEAR(s[12 + 8] - s[12 + 2], -1.5 * extent(0), 1e-5);
}

}  // namespace
}  // namespace genscene::viewer
