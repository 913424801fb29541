// genscene-mesh as a user meets it: a workspace with tsdf.gsv gives mesh.ply and a summary; a
// missing or corrupt volume gives one error line naming the file, a non-zero exit and no mesh.
#include <gtest/gtest.h>

#include <algorithm>

#include "core/analytic_volume.h"
#include "core/ply_io.h"
#include "core/tsdf_volume.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

std::string LastLine(std::string text) {
  while (!text.empty() && text.back() == '\n') text.pop_back();
  const auto nl = text.find_last_of('\n');
  return nl == std::string::npos ? text : text.substr(nl + 1);
}

TEST(GensceneMesh, MeshesTheWorkspaceVolume) {
  test::TempDir dir;
  analytic::AnalyticVolumeSpec spec;
  spec.lo = Eigen::Vector3i::Constant(-12);
  spec.hi = Eigen::Vector3i::Constant(12);
  WriteTsdfVolume(dir / "tsdf.gsv",
                  analytic::MakeAnalyticVolume(spec, [](const Eigen::Vector3d& p) {
                    return analytic::SphereSdf(p, Eigen::Vector3d(0.003, 0.001, -0.002), 0.15);
                  }));
  const auto r = RunCommand(AppPath("genscene-mesh") + " " + dir.path().string() + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "triangles");
  const TriangleMesh mesh = ReadPly(dir / "mesh.ply");
  EXPECT_GT(mesh.faces.size(), 500u);
  EXPECT_EQ(mesh.normals.size(), mesh.vertices.size());
  EXPECT_EQ(mesh.vertex_colors.size(), mesh.vertices.size());
  const analytic::MeshTopology topology = analytic::AnalyseMesh(mesh);
  EXPECT_TRUE(topology.closed);
  EXPECT_EQ(topology.euler, 2);
  EXPECT_EQ(test::CountFilesContaining(dir.path(), ".tmp"), 0);

  const auto help = RunCommand(AppPath("genscene-mesh") + " --help");
  EXPECT_EQ(help.exit_code, 0);
  for (const char* flag : {"--iso-level", "--min-weight", "--min-component-triangles",
                           "--denoise-iterations", "--denoise-angle", "--denoise-max-offset",
                           "--decimate-max-error", "--threads", "--config"}) {
    EXPECT_CONTAINS(help.output, flag);
  }
}

TEST(GensceneMesh, MissingOrCorruptVolumeIsOneLineNamingTheFile) {
  test::TempDir dir;
  const std::string app = AppPath("genscene-mesh") + " " + dir.path().string();
  auto r = RunCommand(app);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(LastLine(r.output), "genscene-mesh: error: ");
  EXPECT_CONTAINS(LastLine(r.output), "tsdf.gsv");
  EXPECT_FALSE(fs::exists(dir / "mesh.ply"));

  test::WriteFile(dir / "tsdf.gsv", "GSTSDF01 but then nothing sensible");
  r = RunCommand(app);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(LastLine(r.output), "genscene-mesh: error: ");
  EXPECT_CONTAINS(LastLine(r.output), "tsdf.gsv");
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  EXPECT_FALSE(fs::exists(dir / "mesh.ply"));
  EXPECT_EQ(test::CountFilesContaining(dir.path(), "mesh"), 0);

  r = RunCommand(AppPath("genscene-mesh") + " " + (dir / "no-such-folder").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(LastLine(r.output), "no-such-folder");
  EXPECT_FALSE(fs::exists(dir / "no-such-folder"));
}

}  // namespace
}  // namespace genscene
