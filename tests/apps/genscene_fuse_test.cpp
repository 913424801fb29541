// genscene-fuse as a user meets it: a sequence folder in, a workspace out; bad input gives one
// error line naming the problem, a non-zero exit and no outputs.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "core/trajectory.h"
#include "core/tsdf_volume.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

nlohmann::json FusionReport(const fs::path& ws) {
  return nlohmann::json::parse(ReadTextFile(ws / "fusion.json"));
}

// The 12-frame 96x72 Cornell sequence (one path per pixel) the fusion tests track.
::testing::AssertionResult SynthSequence(const fs::path& out) {
  const auto r =
      RunCommand(AppPath("genscene-synth") +
                 " --scene cornell --frames 12 --size 96x72 --spp 1 --out " + out.string());
  if (r.exit_code == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << r.output;
}

TEST(GensceneFuse, FusesASynthSequenceIntoAWorkspace) {
  test::TempDir dir;
  ASSERT_TRUE(SynthSequence(dir / "seq"));
  auto r = RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                      (dir / "ws").string() + " --voxel-size 0.02 --truncation 0.08");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "ATE:");
  EXPECT_EQ(ReadTumTrajectory(dir / "ws" / "trajectory.txt").size(), 12u);
  const TsdfVolume volume = ReadTsdfVolume(dir / "ws" / "tsdf.gsv");
  EXPECT_GT(volume.num_blocks(), 10u);
  EXPECT_TRUE(fs::exists(dir / "ws" / "keyframes" / "rgb.txt"));
  EXPECT_TRUE(fs::exists(dir / "ws" / "keyframes" / "groundtruth.txt"));
  const auto report = FusionReport(dir / "ws");
  EXPECT_EQ(report["summary"]["frames"], 12);
  EXPECT_LT(report["summary"]["ate"]["rmse_m"].get<double>(), 0.01);
}

TEST(GensceneFuse, BadInputIsOneClearLineAndNoOutput) {
  test::TempDir dir;
  auto r = RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "nothing").string() + " " +
                      (dir / "ws").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "nothing");
  EXPECT_FALSE(fs::exists(dir / "ws" / "tsdf.gsv"));
  r = RunCommand(AppPath("genscene-synth") + " --frames 3 --size 32x24 --spp 1 --out " +
                 (dir / "seq").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                 (dir / "ws").string() + " --voxel-size 0.0005");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "voxel_size = 0.0005 is not in");
  r = RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                 (dir / "ws").string() + " --voxel-size 0.002 --truncation 0.006 --memory-cap 1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "memory cap of 1 MB exceeded");
  EXPECT_FALSE(fs::exists(dir / "ws" / "tsdf.gsv"));
  EXPECT_FALSE(fs::exists(dir / "ws" / "trajectory.txt"));
}

// When ICP loses most frames the stage stops before writing anything and says what to try.
TEST(GensceneFuse, TrackingLostOnMostFramesStopsWithAdvice) {
  test::TempDir dir;
  ASSERT_TRUE(SynthSequence(dir / "seq"));
  // Every frame moves farther than 1 mm or turns more than 0.1 degrees: every tracked frame is
  // lost.
  auto r =
      RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                 (dir / "ws").string() +
                 " --voxel-size 0.02 --truncation 0.08 --max-translation 0.001 --max-rotation 0.1");
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "ICP tracking failed on 11 of 12 frames");
  EXPECT_CONTAINS(r.output, "--tracking known");
  EXPECT_CONTAINS(r.output, "--intrinsics");
  EXPECT_FALSE(fs::exists(dir / "ws" / "tsdf.gsv"));
  EXPECT_FALSE(fs::exists(dir / "ws" / "trajectory.txt"));
}

// The trajectory error is an optional figure: known poses that pair with no frame give a warning
// and the stage finishes.
TEST(GensceneFuse, AnAteThatCannotBeComputedIsAWarningNotAnError) {
  test::TempDir dir;
  ASSERT_TRUE(SynthSequence(dir / "seq"));
  Trajectory shifted;
  const Trajectory truth = ReadTumTrajectory(dir / "seq" / "groundtruth.txt");
  for (const StampedPose& p : truth.poses()) {
    shifted.Add(
        p.timestamp + 0.5,
        p.world_from_camera);  // 12 frames span 0.37 s: every frame misses its pose by > 0.1 s
  }
  WriteTumTrajectory(dir / "seq" / "groundtruth.txt", shifted);
  const auto r = RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                            (dir / "ws").string() + " --voxel-size 0.02 --truncation 0.08");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "no trajectory error against the recording's poses");
  EXPECT_TRUE(fs::exists(dir / "ws" / "tsdf.gsv"));
}

// --holdout 3: frames 2, 5, 8, 11 are tracked for their poses only: not fused, not keyframes,
// written to WS/holdout/ with their estimated poses.
TEST(GensceneFuse, HeldOutFramesAreTrackedButNotFused) {
  test::TempDir dir;
  ASSERT_TRUE(SynthSequence(dir / "seq"));
  auto r = RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                      (dir / "ws").string() + " --voxel-size 0.02 --truncation 0.08 --holdout 3");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "held out:   4 frames");
  const auto report = FusionReport(dir / "ws");
  std::vector<int> held;
  for (const auto& f : report["frames"]) {
    if (f["status"] == "held_out") {
      held.push_back(f["index"].get<int>());
      EXPECT_FALSE(f["fused"].get<bool>());
    }
  }
  EXPECT_EQ(held, (std::vector<int>{2, 5, 8, 11}));
  const Trajectory held_poses = ReadTumTrajectory(dir / "ws" / "holdout" / "groundtruth.txt");
  const Trajectory truth = ReadTumTrajectory(dir / "seq" / "groundtruth.txt");
  ASSERT_EQ(held_poses.size(), 4u);
  for (const StampedPose& p : held_poses.poses()) {
    const auto t = truth.Nearest(p.timestamp, 1e-6);
    ASSERT_TRUE(t.has_value()) << p.timestamp;
    EXPECT_LT((t->world_from_camera.translation() - p.world_from_camera.translation()).norm(), 0.02)
        << p.timestamp;
    EXPECT_FALSE(ReadTumTrajectory(dir / "ws" / "keyframes" / "groundtruth.txt")
                     .Nearest(p.timestamp, 1e-6)
                     .has_value())
        << "a held-out frame is no keyframe";
    EXPECT_FALSE(
        ReadTumTrajectory(dir / "ws" / "trajectory.txt").Nearest(p.timestamp, 1e-6).has_value());
  }
  r = RunCommand(AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                 (dir / "ws2").string() + " --holdout 1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "holdout = 1 is not 0 (none) or in [2, 100000]");
}

}  // namespace
}  // namespace genscene
