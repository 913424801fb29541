// Fusion on real Kinect frames with motion-capture ground truth (../shared/data/real).
#include "core/frame_source.h"
#include "core/trajectory_metrics.h"
#include "fusion/kinect_fusion.h"
#include "tests/test_util.h"

namespace genscene::fusion {
namespace {

// Acceptance 2: TUM fr1/desk, 9 frames 640x480, ATE <= 2 cm against the mocap ground truth.
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
    std::cout << "frame " << r.index << ": " << ToString(r.status) << " inliers " << r.icp.inlier_ratio
              << " rms " << r.icp.rms_residual << " m condition " << r.icp.condition << " " << r.reason << "\n";
  }
  EXPECT_EQ(tracked, 8);
  const AteResult ate = ComputeAte(fusion.trajectory(), source->KnownPoses());
  std::cout << "TUM fr1/desk 9 frames: ATE RMSE " << 100 * ate.rmse << " cm, max " << 100 * ate.max
            << " cm over " << ate.pairs << " poses\n";
  EXPECT_EQ(ate.pairs, 9u);
  EXPECT_LE(ate.rmse, 0.02);
}

}  // namespace
}  // namespace genscene::fusion
