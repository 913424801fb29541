// Fusion end to end through the apps: a genscene-synth room sequence (150 frames, 320x240,
// path-traced colour), fused by genscene-fuse; ATE as TUM's evaluate_ate.
// Slow (about a minute per sequence on 2 cores): label "slow".
#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

double FuseSynthAte(const std::string& noise) {
  test::TempDir dir;
  auto r = test::RunCommand(test::AppPath("genscene-synth") +
                                " --scene room --frames 150 --size 320x240 --spp 1"
                                " --max-depth 2 --noise " +
                                noise + " --out " + (dir / "seq").string(),
                            600);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = test::RunCommand(test::AppPath("genscene-fuse") + " --input " + (dir / "seq").string() + " " +
                           (dir / "ws").string(),
                       600);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const auto report = nlohmann::json::parse(ReadTextFile(dir / "ws" / "fusion.json"));
  const auto& summary = report["summary"];
  std::cout << "room 150x 320x240, noise " << noise << ": ATE RMSE "
            << 100 * summary["ate"]["rmse_m"].get<double>() << " cm, max "
            << 100 * summary["ate"]["max_m"].get<double>() << " cm; " << summary["blocks"]
            << " blocks (" << summary["megabytes"] << " MB); statuses "
            << summary["status_counts"].dump() << "\n";
  EXPECT_EQ(summary["ate"]["pairs"], 150);
  return summary["ate"]["rmse_m"].get<double>();
}

TEST(FusionSequence, SynthRoomExactDepthWithinOneCentimetre) {
  EXPECT_LE(FuseSynthAte("none"), 0.01);
}

TEST(FusionSequence, SynthRoomKinectNoiseWithinTwoCentimetres) {
  EXPECT_LE(FuseSynthAte("kinect"), 0.02);
}

}  // namespace
}  // namespace genscene
