// genscene-refine as a user meets it: a scene file with posed images gives mesh_refined.ply, the
// per-iteration renders and report.json; bad input gives one error line, a non-zero exit and no
// mesh_refined.ply.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "core/ply_io.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

constexpr const char* kSmall = " --iterations 1 --spp 2 --render-spp 2 --pixels-per-view 300";

// A 2-view Cornell box sequence in DIR/seq, refined (from its true scene) into DIR/ws.
test::CommandResult SynthAndRefine(const test::TempDir& dir) {
  const auto synth = RunCommand(AppPath("genscene-synth") +
                                " --scene cornell --frames 2 --size 40x30 --spp 8 --out " +
                                (dir / "seq").string());
  if (synth.exit_code != 0) return synth;
  return RunCommand(AppPath("genscene-refine") + " " + (dir / "ws").string() + " --scene " +
                    (dir / "seq" / "scene.json").string() + " --views " + (dir / "seq").string() +
                    kSmall);
}

TEST(GensceneRefine, RefinesASceneAgainstASynthSequence) {
  test::TempDir dir;
  const auto r = SynthAndRefine(dir);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "iteration 1:");
  EXPECT_CONTAINS(r.output, "image RMSE");
  const TriangleMesh refined = ReadPly(dir / "ws" / "mesh_refined.ply");
  const TriangleMesh original = ReadPly(dir / "seq" / "mesh_gt.ply");
  EXPECT_EQ(refined.faces.size(), original.faces.size());
  for (const char* f : {"iter_00.png", "iter_00_shading.png", "iter_01.png", "report.json"}) {
    EXPECT_TRUE(fs::exists(dir / "ws" / "refine" / f)) << f;
  }
  const auto report = nlohmann::json::parse(ReadTextFile(dir / "ws" / "refine" / "report.json"));
  ASSERT_EQ(report["iterations"].size(), 2u);
  EXPECT_GT(report["iterations"][1]["jacobian_nonzeros_per_pixel"].get<double>(), 0.0);
}

// A forced bad fit: refinement started at the true mesh can only move away from it, and here it
// fits the noise of 300 pixels at 2 samples each; on fresh pixels the refined mesh is worse, so the
// stage keeps the unrefined one, says so on the console and in report.json.
TEST(GensceneRefine, ARefinedMeshWorseOnFreshPixelsIsNotKept) {
  test::TempDir dir;
  const auto r = SynthAndRefine(dir);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(
      r.output, "warning: the refined mesh fits 600 held-out pixels worse than the unrefined one");
  EXPECT_CONTAINS(r.output, "(unrefined mesh kept)");
  const auto report = nlohmann::json::parse(ReadTextFile(dir / "ws" / "refine" / "report.json"));
  EXPECT_TRUE(report["held_out"]["kept_unrefined"].get<bool>());
  EXPECT_GT(report["held_out"]["image_rmse_refined"].get<double>(),
            report["held_out"]["image_rmse_unrefined"].get<double>());
  // The written mesh is the input's, vertex for vertex.
  const TriangleMesh written = ReadPly(dir / "ws" / "mesh_refined.ply");
  const TriangleMesh truth = ReadPly(dir / "seq" / "mesh_gt.ply");
  ASSERT_EQ(written.vertices.size(), truth.vertices.size());
  double moved = 0.0;
  for (size_t v = 0; v < truth.vertices.size(); ++v)
    moved = std::max(moved, double((written.vertices[v] - truth.vertices[v]).norm()));
  EXPECT_LT(moved, 1e-6);
}

// The fit gate: a workspace whose lights fit the keyframes worse than a constant ambient light (as
// the light stage judged them, in lights.json) is not refined: the unrefined mesh is written, the
// console and report.json say why; --no-fit-gate refines it anyway.
TEST(GensceneRefine, AWorkspaceWhoseLightsFitWorseThanAmbientIsNotRefined) {
  test::TempDir dir;
  const auto synth = RunCommand(AppPath("genscene-synth") +
                                " --scene cornell --frames 2 --size 40x30 --spp 8 --out " +
                                (dir / "seq").string());
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const std::string ws = (dir / "ws").string(), seq = (dir / "seq").string();
  const auto lights = RunCommand(AppPath("genscene-lights") + " " + ws + " --mesh " + seq +
                                 "/mesh_gt.ply --views " + seq +
                                 " --grid 3 --pixels-per-view 200 --refine-levels 0");
  ASSERT_EQ(lights.exit_code, 0) << lights.output;
  const std::string refine = AppPath("genscene-refine") + " " + ws + " --mesh " + seq +
                             "/mesh_gt.ply --views " + seq + kSmall;
  // The same lights judged worse than an ambient light of error 0.01.
  auto j = nlohmann::json::parse(ReadTextFile(dir / "ws" / "lights.json"));
  j["estimate"]["ambient_baseline"]["train_relative_rmse"] = 0.01;
  WriteTextFileAtomically(dir / "ws" / "lights.json", j.dump());
  auto r = RunCommand(refine);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output,
                  "warning: refinement skipped: the lights fit the training views worse than a "
                  "constant ambient light");
  EXPECT_CONTAINS(r.output, "against 0.01 without render noise");
  EXPECT_EQ(r.output.find("iteration 1:"), std::string::npos) << r.output;
  const auto report = nlohmann::json::parse(ReadTextFile(dir / "ws" / "refine" / "report.json"));
  EXPECT_CONTAINS(report["skipped"].get<std::string>(), "worse than a constant ambient light");
  const TriangleMesh written = ReadPly(dir / "ws" / "mesh_refined.ply");
  const TriangleMesh start = ReadPly(dir / "seq" / "mesh_gt.ply");
  ASSERT_EQ(written.vertices.size(), start.vertices.size());
  for (size_t v = 0; v < start.vertices.size(); ++v)
    ASSERT_EQ(written.vertices[v], start.vertices[v]) << "vertex " << v;
  r = RunCommand(refine + " --no-fit-gate");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "iteration 1:");
  EXPECT_FALSE(nlohmann::json::parse(ReadTextFile(dir / "ws" / "refine" / "report.json"))
                   .contains("skipped"));
}

TEST(GensceneRefine, BadInputIsOneLineAndWritesNothing) {
  test::TempDir dir;
  const auto synth = RunCommand(AppPath("genscene-synth") +
                                " --scene cornell --frames 1 --size 24x18 --spp 2 --out " +
                                (dir / "seq").string());
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const std::string ws = (dir / "ws").string();
  const std::string scene = " --scene " + (dir / "seq" / "scene.json").string();
  const auto unknown = RunCommand(AppPath("genscene-refine") + " " + ws + scene + " --views " +
                                  (dir / "seq").string() + " --refine sofa" + kSmall);
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_CONTAINS(unknown.output,
                  "--refine sofa: no such non-emitting mesh in the scene (meshes: cornell, light)");
  const auto no_views = RunCommand(AppPath("genscene-refine") + " " + ws + scene + " --views " +
                                   (dir / "nope").string() + kSmall);
  EXPECT_NE(no_views.exit_code, 0);
  EXPECT_CONTAINS(no_views.output, "no such view set folder");
  const auto no_lights = RunCommand(AppPath("genscene-refine") + " " + ws + " --mesh " +
                                    (dir / "seq" / "mesh_gt.ply").string() + " --views " +
                                    (dir / "seq").string() + kSmall);
  EXPECT_NE(no_lights.exit_code, 0);
  EXPECT_CONTAINS(no_lights.output,
                  "lights.json: no lights (run genscene-lights, or give --lights)");
  EXPECT_FALSE(fs::exists(dir / "ws" / "mesh_refined.ply"));
}

}  // namespace
}  // namespace genscene
