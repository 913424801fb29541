#include "core/frame_source.h"

#include <gtest/gtest.h>

#include <fstream>

#include "core/check.h"
#include "core/image_io.h"
#include "core/sequence_writer.h"
#include "core/synthetic.h"
#include "core/trajectory_metrics.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;

struct DepthRange {
  double lo = 1e9, hi = 0.0;
  size_t valid = 0;
};

DepthRange RangeOf(const ImageDepth& d) {
  DepthRange r;
  for (float z : d.pixels()) {
    if (z <= 0.0f) continue;
    ++r.valid;
    r.lo = std::min<double>(r.lo, z);
    r.hi = std::max<double>(r.hi, z);
  }
  return r;
}

// Every frame: 640x480 depth, more than `min_valid` of it measured, within [lo, hi] meters, with a
// pose.
void ExpectKinectFrames(const std::vector<RgbdFrame>& frames, double min_valid, double lo,
                        double hi) {
  for (const RgbdFrame& f : frames) {
    EXPECT_EQ(f.depth.width(), 640) << f.depth_path;
    EXPECT_EQ(f.depth.height(), 480) << f.depth_path;
    EXPECT_TRUE(f.color.SameSize(f.depth)) << f.color_path;
    const DepthRange r = RangeOf(f.depth);
    EXPECT_GT(r.valid, min_valid * f.depth.size()) << f.depth_path;
    EXPECT_GT(r.lo, lo) << f.depth_path;
    EXPECT_LT(r.hi, hi) << f.depth_path;
    EXPECT_TRUE(f.world_from_camera.has_value()) << f.depth_path;
  }
}

TEST(FrameSourceReal, TumFr1Desk9Frames) {
  GS_REQUIRE_SHARED_DATA(data);
  const auto folder = data / "real/tum-fr1desk-9f";
  SourceOptions options;
  options.associations = (folder / "associate_9frames.txt").string();
  auto source = OpenFrameSource(folder.string(), options);
  EXPECT_EQ(source->FrameCount(), 9u);
  // Intrinsics guessed from the folder name: freiburg1.
  EXPECT_DOUBLE_EQ(source->Intrinsics().fx, 517.3);
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 9u);
  ExpectKinectFrames(frames, 0.5, 0.3, 6.0);  // Kinect v1 minimum range; a desk scene
  for (const RgbdFrame& f : frames) {
    // Ground truth at 100 Hz: every frame has a pose within 10 ms.
    const auto gt = source->KnownPoses().Nearest(f.timestamp, 0.010);
    ASSERT_TRUE(gt.has_value()) << f.timestamp;
    EXPECT_LE(std::abs(gt->timestamp - f.timestamp), 0.010);
    ASSERT_TRUE(f.world_from_camera.has_value());
    EXPECT_LT((f.world_from_camera->translation() - gt->world_from_camera.translation()).norm(),
              0.02);
  }
  EXPECT_DOUBLE_EQ(frames.front().timestamp, 1305031453.359684);
}

TEST(FrameSourceReal, TumExcerptReadsTheFramesThatAreThere) {
  GS_REQUIRE_SHARED_DATA(data);
  // rgb.txt and depth.txt of this excerpt list all 613 / 595 frames of fr1/desk; 9 pairs are
  // present: read with no options, they are the pairs associate_9frames.txt lists.
  const auto folder = data / "real/tum-fr1desk-9f";
  const test::LogCapture log;
  const auto frames = ReadAllFrames(*OpenFrameSource(folder.string(), SourceOptions()));
  SourceOptions listed;
  listed.associations = (folder / "associate_9frames.txt").string();
  const auto expected = ReadAllFrames(*OpenFrameSource(folder.string(), listed));
  ASSERT_EQ(frames.size(), 9u);
  ASSERT_EQ(expected.size(), 9u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].color_path, expected[i].color_path);
    EXPECT_EQ(frames[i].depth_path, expected[i].depth_path);
    EXPECT_DOUBLE_EQ(frames[i].timestamp, expected[i].timestamp);
  }
  EXPECT_NE(
      log.text().find(
          "an excerpt: rgb.txt and depth.txt list 613 and 595 frames, 9 and 9 of them are here"),
      std::string::npos)
      << log.text();
}

TEST(FrameSourceReal, Open3dRedwoodFolder) {
  GS_REQUIRE_SHARED_DATA(data);
  auto source = OpenFrameSource((data / "real/open3d-testdata-rgbd").string(), SourceOptions());
  EXPECT_EQ(source->FrameCount(), 5u);
  EXPECT_DOUBLE_EQ(source->Intrinsics().fx, 525.0);  // camera_primesense.json
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 5u);
  ExpectKinectFrames(frames, 0.5, 0.2, 6.0);  // millimetres decoded: a living room
  // odometry.log: frame 0 at (2, 2, -0.3).
  EXPECT_TRUE(frames[0].world_from_camera->translation().isApprox(Eigen::Vector3d(2, 2, -0.3)));
}

// Poses given per frame (odometry.log) carry their frame's time stamp, so that the estimated
// trajectory (stamped by frame time) pairs with every one of them for the ATE.
TEST(FrameSourceReal, Open3dPosesByIndexPairWithTheirFramesByTime) {
  GS_REQUIRE_SHARED_DATA(data);
  auto source = OpenFrameSource((data / "real/open3d-testdata-rgbd").string(), SourceOptions());
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(source->KnownPoses().size(), 5u);
  Trajectory estimated;
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_DOUBLE_EQ(source->KnownPoses().poses()[i].timestamp, frames[i].timestamp);
    estimated.Add(frames[i].timestamp, *frames[i].world_from_camera);
  }
  const AteResult ate = ComputeAte(estimated, source->KnownPoses());
  EXPECT_EQ(ate.pairs, 5u);
  EXPECT_LT(ate.rmse, 1e-9);
}

// The native 7-Scenes layout: 50 frames with 4x4 poses and the 3x3 camera matrix.
TEST(FrameSourceReal, SevenScenesNativeLayout) {
  GS_REQUIRE_SHARED_DATA(data);
  auto source = OpenFrameSource((data / "real/7scenes-redkitchen-50f").string(), SourceOptions());
  EXPECT_EQ(source->FrameCount(), 50u);
  EXPECT_DOUBLE_EQ(source->Intrinsics().fx, 585.0);
  EXPECT_DOUBLE_EQ(source->Intrinsics().cy, 240.0);
  EXPECT_EQ(source->Intrinsics().width, 640);
  EXPECT_EQ(source->KnownPoses().size(), 50u);
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 50u);
  ExpectKinectFrames(frames, 0.5, 0.3, 8.0);  // 65535 (no data) decoded as 0, not 65.5 m
  // frame-000150.pose.txt: translation (-0.91287065, -0.34388667, 0.75986093).
  EXPECT_TRUE(frames[0].world_from_camera->translation().isApprox(
      Eigen::Vector3d(-0.91287065, -0.34388667, 0.75986093), 1e-7));
  EXPECT_NE(frames[49].depth_path.find("frame-000199.depth.png"), std::string::npos);
}

// A 7-Scenes folder written here: frames, poses, camera matrix; and what is wrong with one.
TEST(FrameSource, SevenScenesLayoutAndItsBadInputs) {
  test::TempDir dir;
  const fs::path frames = dir / "seq-01";
  fs::create_directories(frames);
  ImageDepth depth(8, 6, 1.5f);
  depth(2, 3) = 65.535f;  // raw 65535 at millimetres: the dataset's "no data"
  ImageRgb color(8, 6, Eigen::Vector3f(0.2f, 0.4f, 0.6f));
  for (int i = 0; i < 3; ++i) {
    const std::string stem = Format("frame-", std::string(5, '0'), i);
    WriteDepthPng(frames / (stem + ".depth.png"), depth, 1000.0);
    WritePng(frames / (stem + ".color.png"), color);
    test::WriteFile(frames / (stem + ".pose.txt"),
                    Format("1 0 0 ", 0.1 * i, "\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"));
  }
  test::WriteFile(dir / "camera-intrinsics.txt", "6 0 3.5\n0 6 2.5\n0 0 1\n");
  {
    auto source = OpenFrameSource(frames.string(), SourceOptions());
    EXPECT_EQ(source->Intrinsics().width, 8);
    EXPECT_DOUBLE_EQ(source->Intrinsics().cx, 3.5);
    const auto read = ReadAllFrames(*source);
    ASSERT_EQ(read.size(), 3u);
    EXPECT_FLOAT_EQ(read[0].depth(0, 0), 1.5f);
    EXPECT_EQ(read[0].depth(2, 3), 0.0f);
    EXPECT_NEAR(read[2].world_from_camera->translation().x(), 0.2, 1e-12);
    EXPECT_DOUBLE_EQ(read[1].timestamp, 1.0 / 30.0);
  }
  fs::remove(frames / "frame-000001.pose.txt");
  EXPECT_CONTAINS(test::ErrorOf([&] { OpenFrameSource(frames.string(), SourceOptions()); }),
                  "2 of 3 frames have a .pose.txt");
  fs::remove(frames / "frame-000000.pose.txt");
  fs::remove(frames / "frame-000002.pose.txt");
  fs::remove(frames / "frame-000002.color.png");
  EXPECT_CONTAINS(test::ErrorOf([&] { OpenFrameSource(frames.string(), SourceOptions()); }),
                  "frame-000002.depth.png: no colour image");
  fs::remove(frames / "frame-000002.depth.png");
  test::WriteFile(dir / "camera-intrinsics.txt", "6 0 3.5\n0 6 2.5\n");
  EXPECT_CONTAINS(test::ErrorOf([&] { OpenFrameSource(frames.string(), SourceOptions()); }),
                  "expected a 3x3 camera matrix (9 values), got 6");
  fs::remove(dir / "camera-intrinsics.txt");
  EXPECT_CONTAINS(test::ErrorOf([&] { OpenFrameSource(frames.string(), SourceOptions()); }),
                  "no camera-intrinsics.txt");
}

TEST(FrameSourceReal, SlambookJoinMapFolder) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  {
    std::ofstream(dir / "k.txt") << "518.0 519.0 325.5 253.5 640 480\n";  // joinMap.cpp
  }
  SourceOptions options;
  options.intrinsics = (dir / "k.txt").string();
  auto source = OpenFrameSource((data / "real/slambook-joinmap-5f").string(), options);
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 5u);
  ExpectKinectFrames(frames, 1.0 / 3.0, 0.2, 10.0);
  // pose.txt line 1: tx = -0.228993.
  EXPECT_NEAR(frames[0].world_from_camera->translation().x(), -0.228993, 1e-9);
  // Natural order: 1.png .. 5.png.
  EXPECT_NE(frames[4].color_path.find("5.png"), std::string::npos);
}

TEST(FrameSourceReal, CornellViewSet) {
  GS_REQUIRE_SHARED_DATA(data);
  auto source = OpenFrameSource((data / "cbox-cycles/views/train").string(), SourceOptions());
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].color.width(), 160);
  EXPECT_EQ(frames[0].color.height(), 120);
  ASSERT_TRUE(frames[0].world_from_camera.has_value());
  EXPECT_NEAR(frames[0].world_from_camera->translation().y(), -2.1, 1e-9);
  // Linear EXR radiance is taken as it is (no sRGB decode): some pixels are far above 1 (the
  // light).
  float brightest = 0.0f;
  for (const auto& p : frames[0].color.pixels()) brightest = std::max(brightest, p.maxCoeff());
  EXPECT_GT(brightest, 1.0f);
}

// A small synthetic sequence written and read back through the TUM reader.
class SyntheticSequence : public ::testing::Test {
 protected:
  void SetUp() override {
    k_.width = 32, k_.height = 24, k_.fx = k_.fy = 30.0, k_.cx = 15.5, k_.cy = 11.5;
    const SyntheticScene scene = MakeCornellScene();
    const Trajectory orbit = MakeOrbitTrajectory({0, 0, 0.6}, 0.9, 1.0, 40.0, 4);
    for (const auto& p : orbit.poses())
      frames_.push_back(RenderSyntheticFrame(scene, k_, p.world_from_camera, p.timestamp));
    WriteTumSequence(dir_ / "seq", frames_);
  }
  test::TempDir dir_;
  CameraIntrinsics k_;
  std::vector<RgbdFrame> frames_;
};

TEST_F(SyntheticSequence, RoundTripThroughTumFolder) {
  auto source = OpenFrameSource((dir_ / "seq").string(), SourceOptions());
  const auto back = ReadAllFrames(*source);
  ASSERT_EQ(back.size(), frames_.size());
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_NEAR(back[i].timestamp, frames_[i].timestamp, 1e-6);
    for (size_t p = 0; p < back[i].depth.size(); ++p) {
      EXPECT_NEAR(back[i].depth.pixels()[p], frames_[i].depth.pixels()[p], 0.5 / 5000 + 1e-6);
    }
    ASSERT_TRUE(back[i].world_from_camera.has_value());
    EXPECT_LT((back[i].world_from_camera->matrix() - frames_[i].world_from_camera->matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-8);
  }
  EXPECT_EQ(test::CountFilesContaining(dir_.path(), ".tmp-"), 0);
}

TEST_F(SyntheticSequence, FrameSelection) {
  SourceOptions options;
  options.first_frame = 1;
  options.stride = 2;
  auto source = OpenFrameSource((dir_ / "seq").string(), options);
  const auto back = ReadAllFrames(*source);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_NEAR(back[0].timestamp, frames_[1].timestamp, 1e-6);
  EXPECT_NEAR(back[1].timestamp, frames_[3].timestamp, 1e-6);
  options.first_frame = 10;
  EXPECT_THROW(OpenFrameSource((dir_ / "seq").string(), options), Error);
}

void ExpectOpenOrReadFails(const std::string& folder, const std::string& needle) {
  try {
    auto source = OpenFrameSource(folder, SourceOptions());
    ReadAllFrames(*source);
    ADD_FAILURE() << "no error, expected '" << needle << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST_F(SyntheticSequence, EmptyListIsAnError) {
  std::ofstream(dir_ / "seq/rgb.txt") << "# timestamp filename\n";
  ExpectOpenOrReadFails((dir_ / "seq").string(), "empty list");
}

// The files of the listed frames, in the order of the list.
std::vector<fs::path> ListedFiles(const fs::path& list) {
  std::vector<fs::path> out;
  std::ifstream in(list);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    out.push_back(list.parent_path() / line.substr(line.find(' ') + 1));
  }
  return out;
}

TEST_F(SyntheticSequence, MissingImageBetweenPresentOnesIsAnError) {
  const auto depth = ListedFiles(dir_ / "seq/depth.txt");
  ASSERT_EQ(depth.size(), 4u);
  fs::remove(depth[1]);
  ExpectOpenOrReadFails((dir_ / "seq").string(),
                        "depth.txt: lists " + depth[1].string() + " which does not exist");
}

TEST_F(SyntheticSequence, ExcerptOfTheListsReadsThePresentStretchWithAWarning) {
  const auto rgb = ListedFiles(dir_ / "seq/rgb.txt");
  const auto depth = ListedFiles(dir_ / "seq/depth.txt");
  ASSERT_EQ(rgb.size(), 4u);
  fs::remove(rgb[3]);    // the lists run on past the excerpt ...
  fs::remove(depth[0]);  // ... and begin before it
  const test::LogCapture log;
  const auto back = ReadAllFrames(*OpenFrameSource((dir_ / "seq").string(), SourceOptions()));
  ASSERT_EQ(back.size(), 2u);
  EXPECT_NEAR(back[0].timestamp, frames_[1].timestamp, 1e-6);
  EXPECT_NEAR(back[1].timestamp, frames_[2].timestamp, 1e-6);
  EXPECT_NE(log.text().find(
                "an excerpt: rgb.txt and depth.txt list 4 and 4 frames, 3 and 3 of them are here"),
            std::string::npos)
      << log.text();
}

TEST_F(SyntheticSequence, ListWhoseFilesAreAllMissingIsAnError) {
  for (const fs::path& f : ListedFiles(dir_ / "seq/rgb.txt")) fs::remove(f);
  ExpectOpenOrReadFails((dir_ / "seq").string(), "rgb.txt: lists 4 files and none exists");
}

TEST_F(SyntheticSequence, DepthIntrinsicsSizeMismatchIsAnError) {
  std::ofstream(dir_ / "seq/intrinsics.txt") << "30 30 7.5 5.5 16 12\n";
  ExpectOpenOrReadFails((dir_ / "seq").string(), "but intrinsics say 16x12");
}

TEST_F(SyntheticSequence, NanDepthIsAnError) {
  // Replace the depth list with a float EXR holding one NaN.
  ImageDepth depth = frames_[0].depth;
  depth(2, 3) = std::numeric_limits<float>::quiet_NaN();
  WriteDepthExr(dir_ / "seq/depth/bad.exr", depth);
  std::ofstream(dir_ / "seq/depth.txt") << std::fixed << frames_[0].timestamp << " depth/bad.exr\n";
  ExpectOpenOrReadFails((dir_ / "seq").string(), "bad.exr");
}

// Lens distortion is taken out at ingest: a view of a smooth pattern, written as a camera with
// TUM freiburg1's distortion sees it (each distorted pixel samples the pattern where its
// undistorted ray points), reads back as the pattern seen by the same camera without distortion.
TEST(FrameSource, LensDistortionIsTakenOutAtIngest) {
  CameraIntrinsics k = CameraIntrinsics::Centered(160, 120, 130.0);
  k.distortion = {0.262383, -0.953104, -0.005358, 0.002628, 1.163314};
  // The pattern over normalised image coordinates (x, y), smooth at the pixel scale.
  const auto pattern = [](double x, double y) {
    return Eigen::Vector3f(0.5f + 0.4f * std::sin(20.0 * x), 0.5f + 0.4f * std::cos(18.0 * y),
                           0.5f + 0.3f * x * y);
  };
  // Undistorts a distorted normalised point by fixed-point iteration (the inverse of the model).
  const auto undistort = [&](double xd, double yd) {
    const auto& d = k.distortion;
    double x = xd, y = yd;
    for (int i = 0; i < 50; ++i) {
      const double r2 = x * x + y * y, radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
      const double dx = 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x),
                   dy = d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
      x = (xd - dx) / radial;
      y = (yd - dy) / radial;
    }
    return Eigen::Vector2d(x, y);
  };
  RgbdFrame frame;
  frame.timestamp = 1.0;
  frame.intrinsics = k;
  frame.color = ImageRgb(k.width, k.height);
  frame.depth = ImageDepth(k.width, k.height, 1.25f);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Eigen::Vector2d p = undistort((u - k.cx) / k.fx, (v - k.cy) / k.fy);
      frame.color(u, v) = pattern(p.x(), p.y());
    }
  }
  test::TempDir dir;
  WriteTumSequence(dir / "seq", {frame});  // intrinsics.txt with the distortion
  auto source = OpenFrameSource((dir / "seq").string(), SourceOptions());
  EXPECT_EQ(source->Intrinsics().distortion, (std::array<double, 5>{}));
  EXPECT_NE(source->Describe().find("undistorted"), std::string::npos);
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 1u);
  double err = 0.0, before = 0.0;
  size_t n = 0;
  for (int v = 10; v < k.height - 10; ++v) {
    for (int u = 10; u < k.width - 10; ++u) {
      const Eigen::Vector3f truth = pattern((u - k.cx) / k.fx, (v - k.cy) / k.fy);
      err += (frames[0].color(u, v) - truth).squaredNorm();
      before += (frame.color(u, v) - truth).squaredNorm();
      EXPECT_FLOAT_EQ(frames[0].depth(u, v), 1.25f) << u << ", " << v;
      ++n;
    }
  }
  // The distortion moves the pattern by 0.046 RMS; what is left is resampling and 8-bit rounding.
  EXPECT_GT(std::sqrt(before / n), 0.04);
  EXPECT_LT(std::sqrt(err / n), 0.25 * std::sqrt(before / n));
  std::printf("pattern error: %.4f distorted, %.4f undistorted\n", std::sqrt(before / n),
              std::sqrt(err / n));
  EXPECT_EQ(frames[0].intrinsics.distortion, (std::array<double, 5>{}));
}

TEST(FrameSource, UnknownSourcesAreErrors) {
  test::TempDir dir;
  ExpectOpenOrReadFails((dir / "nope").string(), "no such file or folder");
  ExpectOpenOrReadFails(dir.path().string(), "not a recognised sequence");
  ExpectOpenOrReadFails("openni2", "opened by the capture library");
}

TEST(FrameSource, AssociationFollowsTumRule) {
  // rgb at 0.000, 0.030, 0.055; depth at 0.010, 0.040, 0.200 (max difference 0.02 s). Candidates by
  // difference: (0.030, 0.040) 0.010, (0.000, 0.010) 0.010, (0.055, 0.040) 0.015, (0.030, 0.010)
  // 0.020 (not < 0.02). Greedy: 0.040 goes to 0.030, the closer one, so 0.055 stays unmatched.
  test::TempDir dir;
  ImageRgb color(4, 4, Eigen::Vector3f::Constant(0.5f));
  ImageDepth depth(4, 4, 1.0f);
  std::ofstream rgb(dir / "rgb.txt"), dep(dir / "depth.txt");
  for (const char* t : {"0.000", "0.030", "0.055"}) {
    WritePng(dir / (std::string("c") + t + ".png"), color);
    rgb << t << " c" << t << ".png\n";
  }
  for (const char* t : {"0.010", "0.040", "0.200"}) {
    WriteDepthPng(dir / (std::string("d") + t + ".png"), depth);
    dep << t << " d" << t << ".png\n";
  }
  rgb.close();
  dep.close();
  std::ofstream(dir / "intrinsics.txt") << "4 4 1.5 1.5 4 4\n";
  auto source = OpenFrameSource(dir.path().string(), SourceOptions());
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_NE(frames[0].depth_path.find("d0.010"), std::string::npos);
  EXPECT_NE(frames[1].color_path.find("c0.030"), std::string::npos);
  EXPECT_NE(frames[1].depth_path.find("d0.040"), std::string::npos);
}

}  // namespace
}  // namespace genscene
