// Fusion on real Kinect frames with motion-capture ground truth (../shared/data/real).
#include "core/frame_source.h"
#include "core/parallel.h"
#include "core/se3.h"
#include "core/trajectory_metrics.h"
#include "fusion/kinect_fusion.h"
#include "tests/test_util.h"

namespace genscene::fusion {
namespace {

// TUM fr1/desk, 9 frames 640x480, ATE <= 2 cm against the mocap ground truth.
TEST(FusionReal, TumFr1DeskNineFramesWithinTwoCentimetres) {
  GS_REQUIRE_SHARED_DATA(data);
  const auto folder = data / "real" / "tum-fr1desk-9f";
  SourceOptions source_options;
  source_options.intrinsics = "tum1";
  source_options.associations = (folder / "associate_9frames.txt").string();
  auto source = OpenFrameSource(folder.string(), source_options);
  KinectFusion fusion(FusionOptions(), source->Intrinsics());
  int tracked = 0;
  while (auto frame = source->Next()) {
    const FrameReport r = fusion.ProcessFrame(*frame);
    tracked += r.status == FrameStatus::kTracked;
    std::cout << "frame " << r.index << ": " << ToString(r.status) << " inliers "
              << r.icp.inlier_ratio << " rms " << r.icp.rms_residual << " m condition "
              << r.icp.condition << " " << r.reason << "\n";
  }
  EXPECT_EQ(tracked, 8);
  const AteResult ate = ComputeAte(fusion.trajectory(), source->KnownPoses());
  std::cout << "TUM fr1/desk 9 frames: ATE RMSE " << 100 * ate.rmse << " cm, max " << 100 * ate.max
            << " cm over " << ate.pairs << " poses\n";
  EXPECT_EQ(ate.pairs, 9u);
  EXPECT_LE(ate.rmse, 0.02);
}

// slambook joinMap: 5 real Kinect frames of a dining room, 0.3-0.7 m and 15-25 deg apart. ICP
// from the last pose loses every frame after the first; started from ORB features matched
// against the last fused frame, ICP tracks all five, close to the book's own (estimated) poses.
TEST(FusionReal, SlambookFramesFarApartAreTrackedFromFeatures) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  test::WriteFile(dir / "k.txt", "518.0 519.0 325.5 253.5 640 480\n");  // ch5/joinMap/joinMap.cpp
  SourceOptions source_options;
  source_options.intrinsics = (dir / "k.txt").string();
  const auto folder = (data / "real" / "slambook-joinmap-5f").string();
  for (const bool features : {false, true}) {
    auto source = OpenFrameSource(folder, source_options);
    FusionOptions options;
    options.feature_tracking = features;
    KinectFusion fusion(options, source->Intrinsics());
    int lost = 0, from_features = 0;
    while (auto frame = source->Next()) {
      const FrameReport r = fusion.ProcessFrame(*frame);
      lost += r.status == FrameStatus::kLost;
      from_features += r.feature_start;
      std::cout << "features " << features << " frame " << r.index << ": " << ToString(r.status)
                << " ORB inliers " << r.features.inliers << " of " << r.features.matches
                << ", ICP inliers " << r.icp.inlier_ratio << " " << r.reason << "\n";
    }
    if (!features) {
      EXPECT_EQ(lost, 4);
      continue;
    }
    EXPECT_EQ(lost, 0);
    EXPECT_EQ(from_features, 4);
    const AteResult ate = ComputeAte(fusion.trajectory(), source->KnownPoses());
    std::cout << "slambook joinMap, feature starts: ATE " << 100 * ate.rmse << " cm, max "
              << 100 * ate.max << " cm\n";
    EXPECT_EQ(ate.pairs, 5u);
    EXPECT_LE(ate.rmse, 0.03);
  }
}

// A recording that starts over (a revisit): slambook's five frames, then its first two again. The
// last fused frame, 2 m from the first, shares no features with it: the camera is found against
// the first keyframe (relocalisation), at the pose of the first visit; the frame after it follows
// from the features of the frame before, as on the first visit.
struct Revisit {
  std::vector<RgbdFrame> frames;
  std::vector<FrameReport> reports;
  std::vector<std::string> pose_bytes;  // each fused pose's 16 doubles, bit for bit
};

Revisit RunRevisit(const std::filesystem::path& data, const std::filesystem::path& dir) {
  test::WriteFile(dir / "k.txt", "518.0 519.0 325.5 253.5 640 480\n");
  SourceOptions source_options;
  source_options.intrinsics = (dir / "k.txt").string();
  auto source = OpenFrameSource((data / "real" / "slambook-joinmap-5f").string(), source_options);
  Revisit run;
  while (auto frame = source->Next()) run.frames.push_back(*frame);
  if (run.frames.size() != 5u) return run;
  for (int i : {0, 1}) {
    RgbdFrame again = run.frames[static_cast<size_t>(i)];
    again.timestamp = run.frames.back().timestamp + 1.0 / 30.0;
    run.frames.push_back(again);
  }
  KinectFusion fusion(FusionOptions(), source->Intrinsics());
  for (const RgbdFrame& f : run.frames) {
    run.reports.push_back(fusion.ProcessFrame(f));
    const FrameReport& r = run.reports.back();
    std::cout << "frame " << r.index << ": " << ToString(r.status)
              << " relocalised against t = " << r.relocalised_against.value_or(-1.0)
              << ", ORB inliers " << r.features.inliers << " " << r.reason << "\n";
    std::string bytes;
    if (r.world_from_camera) {
      const Eigen::Matrix4d m = r.world_from_camera->matrix();
      bytes.assign(reinterpret_cast<const char*>(m.data()), sizeof(double) * 16);
    }
    run.pose_bytes.push_back(bytes);
  }
  return run;
}

TEST(FusionReal, ARecordingThatStartsOverIsRelocalisedAgainstTheFirstKeyframe) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  const Revisit run = RunRevisit(data, dir.path());
  ASSERT_EQ(run.frames.size(), 7u);
  const std::vector<FrameReport>& reports = run.reports;
  for (const FrameReport& r : reports) EXPECT_TRUE(r.world_from_camera) << r.index;
  const FrameReport& back = reports[5];
  EXPECT_EQ(back.status, FrameStatus::kTracked) << back.reason;
  EXPECT_TRUE(back.feature_start);
  EXPECT_EQ(back.relocalised_against, std::optional<double>(run.frames[0].timestamp));
  ASSERT_TRUE(back.world_from_camera && reports[0].world_from_camera);
  const Eigen::Isometry3d first_from_back =
      reports[0].world_from_camera->inverse() * *back.world_from_camera;
  std::cout << "the revisit's pose against the first visit's: "
            << 100.0 * first_from_back.translation().norm() << " cm, "
            << RotationAngle(first_from_back) * 180.0 / M_PI << " deg\n";
  EXPECT_LT(first_from_back.translation().norm(), 0.01);
  EXPECT_LT(RotationAngle(first_from_back) * 180.0 / M_PI, 1.0);
  EXPECT_EQ(reports[6].status, FrameStatus::kTracked) << reports[6].reason;
  EXPECT_FALSE(reports[6].relocalised_against);
  ASSERT_TRUE(reports[6].world_from_camera && reports[1].world_from_camera);
  EXPECT_LT(
      (reports[6].world_from_camera->translation() - reports[1].world_from_camera->translation())
          .norm(),
      0.02);
}

// Feature starts and the relocalisation (ORB, PnP RANSAC, ICP) give the same poses, bit for bit,
// with one worker thread and with two.
TEST(FusionReal, RelocalisationGivesTheSamePosesWithOneAndTwoThreads) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  std::vector<Revisit> runs;
  for (int threads : {1, 2}) {
    SetThreadCount(threads);
    runs.push_back(RunRevisit(data, dir.path()));
  }
  SetThreadCount(0);
  ASSERT_EQ(runs[0].reports.size(), 7u);
  ASSERT_EQ(runs[1].reports.size(), 7u);
  EXPECT_EQ(runs[0].reports[5].relocalised_against, runs[1].reports[5].relocalised_against);
  EXPECT_TRUE(runs[0].reports[5].relocalised_against) << "frame 5 was not relocalised";
  for (size_t i = 0; i < 7; ++i) {
    EXPECT_FALSE(runs[0].pose_bytes[i].empty()) << "frame " << i << " has no pose";
    EXPECT_TRUE(runs[0].pose_bytes[i] == runs[1].pose_bytes[i])
        << "frame " << i << "'s pose differs between 1 and 2 threads";
  }
}

}  // namespace
}  // namespace genscene::fusion
