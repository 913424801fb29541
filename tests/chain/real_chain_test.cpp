// `genscene run` on every real recording of ../shared/data/real/, with the flags the README names
// for it and reduced light and refinement settings: the chain finishes, every warning reaches
// the console and the summary, and what each recording needed is in what it made. Labelled
// "slow" (CI runs it under ASan + UBSan).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "core/frame_source.h"
#include "core/ply_io.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

constexpr const char* kReduced =
    " --lights-pixels-per-view 300 --lights-rounds 1 --lights-refine-levels 0"
    " --lights-albedo-iterations 1"
    " --refine-iterations 1 --refine-pixels-per-view 200 --refine-spp 4"
    " --preview-lights-spp 2 --preview-refine-spp 0";

struct ChainRun {
  test::CommandResult result;
  nlohmann::json summary;
};

ChainRun RunOn(const fs::path& recording, const fs::path& ws, const std::string& flags) {
  ChainRun run;
  run.result = RunCommand(AppPath("genscene") + " run --input " + recording.string() + " --out " +
                              ws.string() + " " + flags + kReduced,
                          1100);
  if (fs::exists(ws / "summary.json"))
    run.summary = nlohmann::json::parse(ReadTextFile(ws / "summary.json"));
  return run;
}

std::string StageResult(const nlohmann::json& summary, const std::string& stage) {
  for (const auto& row : summary["stages"]) {
    if (row["stage"] == stage) return row["result"].get<std::string>();
  }
  return "<no " + stage + " row>";
}

// Every stage ran (evaluate when frames were held out) and the model was exported.
void ExpectCompleteModel(const ChainRun& run, const fs::path& ws, bool evaluated = false) {
  ASSERT_EQ(run.result.exit_code, 0) << run.result.output;
  std::vector<std::string> ran;
  for (const auto& row : run.summary["stages"]) {
    if (!row["skipped"].get<bool>()) ran.push_back(row["stage"].get<std::string>());
  }
  std::vector<std::string> all = {"ingest", "fusion", "meshing", "texturing",
                                  "albedo", "lights", "refine",  "export"};
  if (evaluated) all.push_back("evaluate");
  EXPECT_EQ(ran, all);
  EXPECT_GT(ReadPly(ws / "mesh_refined.ply").faces.size(), 1000u);
  EXPECT_FALSE(ReadPly(ws / "mesh_refined.ply").vertex_colors.empty())
      << "the refined mesh keeps its colours";
  EXPECT_TRUE(fs::exists(ws / "export" / "model.ply"));
  EXPECT_TRUE(fs::exists(ws / "export" / "model.xml"));
}

TEST(RealChain, TumFr1DeskExcerptWithDefaults) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  // The excerpt's rgb.txt and depth.txt list all of fr1/desk: the nine pairs present are read,
  // with a warning that says so.
  const ChainRun run = RunOn(data / "real/tum-fr1desk-9f", dir / "ws", "");
  ExpectCompleteModel(run, dir / "ws");
  EXPECT_CONTAINS(StageResult(run.summary, "ingest"), "9 frames");
  EXPECT_CONTAINS(run.result.output, "an excerpt: rgb.txt and depth.txt list 613 and 595 frames");
  // The intrinsics guessed from the folder name are a warning on the console and in the summary.
  EXPECT_CONTAINS(run.result.output, "[warning]");
  EXPECT_CONTAINS(run.result.output, "using tum1 from the folder name");
  EXPECT_CONTAINS(run.result.output, "warnings:\n");
  // Nine frames within 0.3 s still give min_keyframes views.
  EXPECT_CONTAINS(StageResult(run.summary, "fusion"), "3 keyframes");
  EXPECT_CONTAINS(StageResult(run.summary, "fusion"), "ATE");
}

TEST(RealChain, Open3dFolderWithPosesByIndex) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  // A 2 cm volume keeps the sanitizer run short (6505 triangles; simplified to 1 cm as well it
  // would keep under a thousand).
  const ChainRun run =
      RunOn(data / "real/open3d-testdata-rgbd", dir / "ws", "--voxel-size 0.02 --truncation 0.06");
  ExpectCompleteModel(run, dir / "ws");
  // The poses of odometry.log pair with all five frames: an ATE, no abort.
  EXPECT_CONTAINS(StageResult(run.summary, "fusion"), "ATE");
  EXPECT_EQ(run.result.output.find("no trajectory error"), std::string::npos) << run.result.output;
}

TEST(RealChain, SlambookSparseViewsTrackedFromFeatures) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  const fs::path slambook = data / "real/slambook-joinmap-5f";
  test::WriteFile(dir / "k.txt", "518.0 519.0 325.5 253.5 640 480\n");  // ch5/joinMap/joinMap.cpp
  // Frames 0.3-0.7 m apart: ICP starts from ORB features for every frame after the first. A
  // 2 cm volume and a mesh simplified to 1 cm (reduced settings) keep the sanitizer run short.
  const ChainRun run = RunOn(slambook, dir / "ws",
                             "--intrinsics " + (dir / "k.txt").string() +
                                 " --voxel-size 0.02 --truncation 0.06 --decimate-max-error 0.01");
  ExpectCompleteModel(run, dir / "ws");
  EXPECT_CONTAINS(StageResult(run.summary, "fusion"), "ATE");
  const auto fusion = nlohmann::json::parse(ReadTextFile(dir / "ws" / "fusion.json"));
  int fused = 0, from_features = 0;
  for (const auto& frame : fusion["frames"]) {
    fused += frame["fused"].get<bool>();
    from_features += frame["feature_start"].get<bool>();
  }
  EXPECT_GE(fused, 4) << fusion["summary"].dump();
  EXPECT_GE(from_features, 3) << fusion["summary"].dump();
}

// 15 of the 50 frames in a 2 cm volume, the model's renders of the held-out frames at 4 spp
// (reduced settings: the sanitizer run stays short).
TEST(RealChain, SevenScenesNativeLayout) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  const ChainRun run = RunOn(data / "real/7scenes-redkitchen-50f", dir / "ws",
                             "--max-frames 15 --holdout 5 --voxel-size 0.02 --truncation 0.06"
                             " --decimate-max-error 0.01 --evaluate-model-spp 4");
  ExpectCompleteModel(run, dir / "ws", true);
  EXPECT_CONTAINS(StageResult(run.summary, "ingest"), "15 frames 640x480");
  EXPECT_CONTAINS(StageResult(run.summary, "fusion"), "ATE");
  // The unregistered colour camera is said once in the summary's warnings.
  EXPECT_CONTAINS(run.result.output, "warnings:\n  ingest: ");
  EXPECT_CONTAINS(run.result.output, "unregistered cameras");
  // Frames 4, 9, 14 held out: the model is judged on them beside both baselines.
  EXPECT_CONTAINS(StageResult(run.summary, "fusion"), "3 held out");
  const auto holdout =
      nlohmann::json::parse(ReadTextFile(dir / "ws" / "evaluation" / "holdout.json"));
  ASSERT_EQ(holdout["frames"].size(), 3u);
  for (const char* key : {"model", "texture_unlit", "albedo_ambient"}) {
    const double rmse = holdout["mean"][key]["relative_rmse"].get<double>(),
                 ssim = holdout["mean"][key]["ssim"].get<double>();
    EXPECT_TRUE(rmse > 0.0 && rmse < 10.0) << key << " " << rmse;
    EXPECT_TRUE(ssim > -1.0 && ssim <= 1.0) << key << " " << ssim;
  }
  // The unlit texture is the colour the frames show: on frames it never saw it still beats a flat
  // albedo under ambient light.
  EXPECT_LT(holdout["mean"]["texture_unlit"]["relative_rmse"].get<double>(),
            holdout["mean"]["albedo_ambient"]["relative_rmse"].get<double>());
  for (const char* image :
       {"holdout_00_real.png", "holdout_00_model.png", "holdout_02_error.png"}) {
    EXPECT_TRUE(fs::exists(dir / "ws" / "evaluation" / image)) << image;
  }
  const auto report = RunCommand(AppPath("genscene") + " report " + (dir / "ws").string());
  ASSERT_EQ(report.exit_code, 0) << report.output;
  EXPECT_CONTAINS(ReadTextFile(dir / "ws" / "report" / "report.md"), "## Held-out frames");
}

}  // namespace
}  // namespace genscene
