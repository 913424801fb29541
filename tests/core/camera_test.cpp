#include "core/camera.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/check.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

CameraIntrinsics MakeCamera() {
  CameraIntrinsics k;
  k.fx = 500.0, k.fy = 480.0, k.cx = 319.5, k.cy = 239.5, k.width = 640, k.height = 480;
  return k;
}

TEST(Camera, UnprojectThenProjectIsIdentity) {
  const CameraIntrinsics k = MakeCamera();
  for (double u : {0.0, 100.25, 639.0}) {
    for (double v : {0.0, 240.5, 479.0}) {
      const auto uv = k.Project(k.Unproject(u, v, 2.5));
      ASSERT_TRUE(uv.has_value());
      EXPECT_NEAR(uv->x(), u, 1e-9);
      EXPECT_NEAR(uv->y(), v, 1e-9);
    }
  }
}

TEST(Camera, RayThroughPixelCentreFollowsConvention) {
  const CameraIntrinsics k = MakeCamera();
  // DESIGN.md §1: direction ((u - cx) / fx, (v - cy) / fy, 1); the centred image has cx = (W-1)/2.
  const Eigen::Vector3d d = k.RayDirection(419.5, 239.5);
  EXPECT_DOUBLE_EQ(d.x(), 100.0 / 500.0);
  EXPECT_DOUBLE_EQ(d.y(), 0.0);
  EXPECT_DOUBLE_EQ(d.z(), 1.0);
  EXPECT_FALSE(k.Project({0.0, 0.0, -1.0}).has_value());
}

TEST(Camera, ScaledKeepsPixelCentres) {
  const CameraIntrinsics k = MakeCamera();
  const CameraIntrinsics half = k.Scaled(0.5);
  EXPECT_EQ(half.width, 320);
  EXPECT_EQ(half.height, 240);
  // The centre of the full image maps to the centre of the half image.
  EXPECT_DOUBLE_EQ(half.cx, (half.width - 1) / 2.0);
  EXPECT_DOUBLE_EQ(half.cy, (half.height - 1) / 2.0);
  // A 3D point lands at the same place in both, in the coordinates of each image:
  // a half-image pixel i covers full pixels 2i and 2i + 1, centred at 2i + 0.5.
  const Eigen::Vector3d p(0.3, -0.2, 1.7);
  const auto full = *k.Project(p);
  const auto small = *half.Project(p);
  EXPECT_NEAR(full.x(), 2.0 * small.x() + 0.5, 1e-9);
  EXPECT_NEAR(full.y(), 2.0 * small.y() + 0.5, 1e-9);
}

TEST(Camera, IntrinsicsFileRoundTrip) {
  test::TempDir dir;
  CameraIntrinsics k = MakeCamera();
  k.fx = 517.306408;
  k.distortion = {0.262383, -0.953104, -0.005358, 0.002628, 1.163314};
  WriteIntrinsicsFile(dir / "k.txt", k);
  const CameraIntrinsics back = ReadIntrinsicsFile(dir / "k.txt");
  EXPECT_EQ(back.fx, k.fx);
  EXPECT_EQ(back.fy, k.fy);
  EXPECT_EQ(back.cx, k.cx);
  EXPECT_EQ(back.cy, k.cy);
  EXPECT_EQ(back.width, k.width);
  EXPECT_EQ(back.height, k.height);
  EXPECT_EQ(back.distortion, k.distortion);
}

TEST(Camera, RejectsAbsurdIntrinsics) {
  test::TempDir dir;
  const std::vector<std::string> bad = {
      "0 500 319.5 239.5 640 480",     "500 500 319.5 239.5 0 480",
      "500 500 319.5 239.5 99999 480", "nan 500 319.5 239.5 640 480",
      "500 500 5000 239.5 640 480",    "500 500 319.5 239.5 640",
      "500 500 319.5 abc 640 480",     ""};
  for (const auto& line : bad) {
    std::ofstream(dir / "k.txt") << line << "\n";
    try {
      ReadIntrinsicsFile(dir / "k.txt");
      ADD_FAILURE() << "accepted '" << line << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("k.txt"), std::string::npos) << e.what();
    }
  }
}

TEST(Camera, NamedIntrinsics) {
  const auto tum1 = NamedIntrinsics("tum1");
  ASSERT_TRUE(tum1.has_value());
  EXPECT_DOUBLE_EQ(tum1->fx, 517.3);
  EXPECT_DOUBLE_EQ(tum1->cy, 255.3);
  EXPECT_TRUE(NamedIntrinsics("tum2").has_value());
  EXPECT_TRUE(NamedIntrinsics("tum3").has_value());
  EXPECT_FALSE(NamedIntrinsics("tum4").has_value());
  EXPECT_THROW(ResolveIntrinsics("no-such-file-or-name"), Error);
}

// Fuzzing found "height": 4.8e101 converted to int with undefined behaviour (UBSan); a size must be
// an integer that fits, and every other malformation names the file.
TEST(Camera, RejectsMalformedOpen3dJson) {
  test::TempDir dir;
  const std::string matrix = R"("intrinsic_matrix": [525, 0, 0, 0, 525, 0, 319.5, 239.5, 1])";
  const std::vector<std::pair<std::string, std::string>> bad = {
      {R"({"width": 640, "height": 4.8e101, )" + matrix + "}",
       "height: expected an integer, got 4.8e+101"},
      {R"({"width": 640.5, "height": 480, )" + matrix + "}",
       "width: expected an integer, got 640.5"},
      {R"({"width": 640, "height": 1099511627776, )" + matrix + "}",
       "height: 1099511627776 is out of range"},
      {R"({"width": 640, "height": -4294967296, )" + matrix + "}",
       "height: -4294967296 is out of range"},
      {R"({"width": 640, "height": 480, "intrinsic_matrix": [525, 0]})",
       "intrinsic_matrix must have 9 numbers"},
      {R"({"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, "x", 0, 319.5, 239.5, 1]})",
       "not an Open3D camera intrinsic file"}};
  for (const auto& [text, message] : bad) {
    std::ofstream(dir / "camera.json") << text << "\n";
    const std::string error = test::ErrorOf([&] { ReadIntrinsicsFile(dir / "camera.json"); });
    EXPECT_CONTAINS(error, "camera.json: ");
    EXPECT_CONTAINS(error, message);
  }
}

TEST(Camera, ReadsOpen3dCameraJson) {
  GS_REQUIRE_SHARED_DATA(data);
  const CameraIntrinsics k =
      ReadIntrinsicsFile(data / "real/open3d-testdata-rgbd/camera_primesense.json");
  EXPECT_EQ(k.width, 640);
  EXPECT_EQ(k.height, 480);
  EXPECT_DOUBLE_EQ(k.fx, 525.0);
  EXPECT_DOUBLE_EQ(k.fy, 525.0);
  EXPECT_DOUBLE_EQ(k.cx, 319.5);
  EXPECT_DOUBLE_EQ(k.cy, 239.5);
}

}  // namespace
}  // namespace genscene
