// genscene-texture and genscene-albedo as a user meets them: a workspace with mesh.ply and
// keyframes/ gives texture.mcol/.ply, then albedo.mcol/.ply/.json; missing or mismatched inputs
// give one error line naming the file, a non-zero exit and no output.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "core/mesh_colors.h"
#include "core/ply_io.h"
#include "core/sequence_writer.h"
#include "core/synthetic.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

// The Cornell-like synthetic room under ambient light, its exact mesh and six posed keyframes.
void MakeWorkspace(const fs::path& ws) {
  SyntheticScene scene = MakeCornellScene();
  scene.ambient = 1.0;
  WritePly(ws / "mesh.ply", scene.ToMesh());
  const CameraIntrinsics k = CameraIntrinsics::Centered(120, 90, 100.0);
  std::vector<RgbdFrame> frames;
  const Trajectory orbit = MakeOrbitTrajectory({0.0, 0.0, 0.7}, 0.6, 1.0, 120.0, 6);
  for (const StampedPose& pose : orbit.poses()) {
    frames.push_back(RenderSyntheticFrame(scene, k, pose.world_from_camera, pose.timestamp));
  }
  WriteTumSequence(ws / "keyframes", frames);
}

TEST(GensceneTexture, TexturesAndClustersAWorkspace) {
  test::TempDir dir;
  MakeWorkspace(dir.path());
  const auto t =
      RunCommand(AppPath("genscene-texture") + " " + dir.path().string() + " --texel-spacing 0.05");
  ASSERT_EQ(t.exit_code, 0) << t.output;
  EXPECT_CONTAINS(t.output, "texels/s");
  const TriangleMesh mesh = ReadPly(dir / "mesh.ply");
  const MeshColors texture = ReadMeshColors(dir / "texture.mcol", mesh);
  EXPECT_EQ(texture.labels().size(), texture.SampleCount());
  const TriangleMesh ply = ReadPly(dir / "texture.ply");
  EXPECT_EQ(ply.vertices.size(), texture.SampleCount());
  EXPECT_EQ(ply.vertex_colors.size(), texture.SampleCount());

  const auto a = RunCommand(AppPath("genscene-albedo") + " " + dir.path().string());
  ASSERT_EQ(a.exit_code, 0) << a.output;
  const MeshColors albedo = ReadMeshColors(dir / "albedo.mcol", mesh);
  EXPECT_EQ(albedo.labels().size(), albedo.SampleCount());
  std::ifstream in(dir / "albedo.json");
  const nlohmann::json report = nlohmann::json::parse(in);
  // Red walls, green walls, white everything else: three albedos, seen under ambient light.
  EXPECT_GE(report["clusters"].size(), 3u);
  EXPECT_LE(report["clusters"].size(), 4u);
  for (const auto& c : report["clusters"]) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(c["albedo"][k].get<double>(), 0.0);
      EXPECT_LE(c["albedo"][k].get<double>(), 1.0);
    }
  }
  EXPECT_EQ(test::CountFilesContaining(dir.path(), ".tmp"), 0);

  for (const char* app : {"genscene-texture", "genscene-albedo"}) {
    const auto help = RunCommand(AppPath(app) + " --help");
    EXPECT_EQ(help.exit_code, 0) << app;
    EXPECT_CONTAINS(help.output, "--threads");
  }
  EXPECT_CONTAINS(RunCommand(AppPath("genscene-texture") + " --help").output, "--texel-spacing");
  EXPECT_CONTAINS(RunCommand(AppPath("genscene-albedo") + " --help").output, "--chroma-bandwidth");
}

TEST(GensceneTexture, MissingAndMismatchedInputsAreClearErrors) {
  test::TempDir dir;
  const std::string ws = dir.path().string();
  auto r = RunCommand(AppPath("genscene-texture") + " " + ws + "/nowhere");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "no such workspace folder");

  r = RunCommand(AppPath("genscene-texture") + " " + ws);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "mesh.ply: missing");

  MakeWorkspace(dir.path());
  fs::remove_all(dir / "keyframes");
  r = RunCommand(AppPath("genscene-texture") + " " + ws);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "no keyframes folder");

  r = RunCommand(AppPath("genscene-albedo") + " " + ws);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "texture.mcol: missing");

  // A texture made for another mesh.
  MakeWorkspace(dir.path());
  ASSERT_EQ(RunCommand(AppPath("genscene-texture") + " " + ws + " --texel-spacing 0.1").exit_code,
            0);
  TriangleMesh other = ReadPly(dir / "mesh.ply");
  other.faces.pop_back();
  other.face_colors.pop_back();
  WritePly(dir / "mesh.ply", other);
  r = RunCommand(AppPath("genscene-albedo") + " " + ws);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "texture.mcol: made for a mesh of");
  EXPECT_FALSE(fs::exists(dir / "albedo.mcol"));
  EXPECT_FALSE(fs::exists(dir / "albedo.ply"));

  // An empty mesh.
  TriangleMesh empty;
  empty.vertices = {Eigen::Vector3f::Zero()};
  WritePly(dir / "mesh.ply", empty);
  r = RunCommand(AppPath("genscene-texture") + " " + ws);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "has no faces");
  EXPECT_EQ(test::CountFilesContaining(dir.path(), ".tmp"), 0);
}

}  // namespace
}  // namespace genscene
