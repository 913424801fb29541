// genscene-lights as a user meets it: a scene's geometry and albedo with posed images give
// lights.json, renders and a Mitsuba scene; bad input gives one error line, a non-zero exit and
// no lights.json.
#include <gtest/gtest.h>

#include "core/light_set.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

constexpr const char* kSmall =
    " --grid 3 --pixels-per-view 200 --spp 4 --rounds 2 --render-spp 4 --saturation 0.99";

TEST(GensceneLights, EstimatesLightsFromASynthSequence) {
  test::TempDir dir;
  const auto synth = RunCommand(AppPath("genscene-synth") +
                                " --scene cornell --frames 3 --size 48x36 --spp 16 --out " +
                                (dir / "seq").string());
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const std::string ws = (dir / "ws").string();
  const auto r = RunCommand(AppPath("genscene-lights") + " " + ws + " --scene " +
                            (dir / "seq" / "scene.json").string() + " --views " +
                            (dir / "seq").string() + kSmall);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The 3^3 grid refined once (the default): a 6^3 grid, dark outside the candidates.
  EXPECT_CONTAINS(r.output, "active voxels of 216");
  const VoxelLightGrid lights = ReadLightsJson(dir / "ws" / "lights.json");
  EXPECT_EQ(lights.VoxelCount(), 216);
  EXPECT_FALSE(lights.ActiveVoxels().empty());
  // The synth light hangs under the ceiling: the strongest voxel is in the top layer.
  int strongest = 0;
  for (int j = 0; j < lights.VoxelCount(); ++j) {
    if (lights.Power(j).sum() > lights.Power(strongest).sum()) strongest = j;
  }
  EXPECT_GT(lights.VoxelCenter(strongest).z(), 1.3) << "voxel " << strongest;
  for (const char* f : {"train_00.exr", "train_00.png", "train_02.png", "scene.xml"}) {
    EXPECT_TRUE(fs::exists(dir / "ws" / "lights" / f)) << f;
  }
  // The estimate beats its baseline here: no warning. The counts agree with lights.json's.
  EXPECT_CONTAINS(r.output, "ambient baseline");
  EXPECT_EQ(r.output.find("worse than a constant ambient light"), std::string::npos) << r.output;
  EXPECT_CONTAINS(r.output, Format(lights.ActiveVoxels().size(), " active voxels of 216"));
}

// A forced bad fit (a penalty that leaves every voxel dark) finishes, and says it is worse than
// the ambient baseline on the console.
TEST(GensceneLights, AFitWorseThanTheAmbientBaselineIsAWarning) {
  test::TempDir dir;
  const auto synth = RunCommand(AppPath("genscene-synth") +
                                " --scene cornell --frames 3 --size 48x36 --spp 16 --out " +
                                (dir / "seq").string());
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const auto r =
      RunCommand(AppPath("genscene-lights") + " " + (dir / "ws").string() + " --scene " +
                 (dir / "seq" / "scene.json").string() + " --views " + (dir / "seq").string() +
                 kSmall + " --penalty-weight 1e6 --refine-levels 0");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(
      r.output,
      "warning: the voxel lights fit the training views worse than a constant ambient light");
}

TEST(GensceneLights, BadInputIsOneLineAndWritesNothing) {
  test::TempDir dir;
  const std::string ws = (dir / "ws").string();
  const auto missing = RunCommand(AppPath("genscene-lights") + " " + ws + " --views " +
                                  (dir / "nope").string() + kSmall);
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_CONTAINS(missing.output, "mesh.ply: no such mesh");
  EXPECT_FALSE(fs::exists(dir / "ws" / "lights.json"));
  const auto odd = RunCommand(AppPath("genscene-lights") + " " + ws + " --spp 3");
  EXPECT_NE(odd.exit_code, 0);
  EXPECT_CONTAINS(odd.output, "spp = 3 must be even");
}

}  // namespace
}  // namespace genscene
