// report.html: Markdown turned into HTML, base64, the page without a 3D view, and the page opened
// by headless Chromium (Debian's chromium): no console message, the model loaded, and a
// screenshot whose 3D view shows the model's albedo.
#include "apps/report_html.h"

#include <gtest/gtest.h>

#include <sstream>

#include "core/file_util.h"
#include "core/image_io.h"
#include "render/formats/gltf_export.h"
#include "tests/test_util.h"

namespace genscene::apps {
namespace {

namespace fs = std::filesystem;

TEST(ReportHtml, Base64MatchesRfc4648) {
  // RFC 4648, section 10.
  EXPECT_EQ(Base64(""), "");
  EXPECT_EQ(Base64("f"), "Zg==");
  EXPECT_EQ(Base64("fo"), "Zm8=");
  EXPECT_EQ(Base64("foo"), "Zm9v");
  EXPECT_EQ(Base64("foob"), "Zm9vYg==");
  EXPECT_EQ(Base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(Base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(Base64(std::string("\xff\x00\x80", 3)), "/wCA");
}

TEST(ReportHtml, MarkdownTablesAndImagesBecomeHtml) {
  const std::string html = MarkdownToHtml(
      "# Title\n\n| stage | seconds |\n|---|---:|\n| fusion | 1.5 |\n\n![plot](a_b.png) "
      "`x < y`\n");
  EXPECT_CONTAINS(html, "<h1>Title</h1>");
  EXPECT_CONTAINS(html, "<table>");
  EXPECT_CONTAINS(html, "<th>stage</th>");
  EXPECT_CONTAINS(html, "<td align=\"right\">1.5</td>");
  EXPECT_CONTAINS(html, "<code>x &lt; y</code>");
  EXPECT_CONTAINS(html, "<img src=\"");
}

TEST(ReportHtml, WithoutThreeJsOrModelThePageSaysWhy) {
  test::TempDir dir;
  test::WriteFile(dir / "model.glb", "glTF");
  const auto warnings =
      WriteReportHtml(dir.path(), {"# r\n\ntext\n", dir / "model.glb", dir / "none"});
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_CONTAINS(warnings[0], "libjs-three");
  const std::string page = ReadTextFile(dir / "report.html");
  EXPECT_CONTAINS(page, "No 3D view: ");
  EXPECT_CONTAINS(page, "<p>text</p>");
  EXPECT_EQ(page.find("<script"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "model_glb.js"));
  const auto no_model =
      WriteReportHtml(dir.path(), {"# r\n", dir / "missing.glb", kDebianThreeDir});
  ASSERT_EQ(no_model.size(), 1u);
  EXPECT_CONTAINS(no_model[0], "no export/model.glb");
}

// A red quad seen square-on by one camera, as a .glb.
void WriteQuadGlb(const fs::path& path) {
  TriangleMesh mesh;
  mesh.vertices = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  mesh.faces = {{0, 2, 1}, {0, 3, 2}};  // facing -z, towards the camera
  mesh.ComputeVertexNormals();
  MeshColors albedo(mesh, {2, 2});
  for (Eigen::Vector3f& c : albedo.colors()) c = Eigen::Vector3f(0.8f, 0.1f, 0.05f);
  PosedView view;
  view.intrinsics = CameraIntrinsics::Centered(640, 480, 500.0);
  view.world_from_camera.translation() = Eigen::Vector3d(0, 0, -2.5);  // looking along +z
  render::ExportGltf(path, mesh, albedo, nullptr, nullptr, {view});
}

struct Browser {
  test::CommandResult run;
  std::string console;  // the page's console messages, one per line
};

// Headless Chromium on `page` with Mesa-free WebGL (SwiftShader), `what` = "--dump-dom" or
// "--screenshot=FILE".
Browser OpenInChromium(const fs::path& page, const fs::path& profile, const std::string& what) {
  Browser b;
  b.run = test::RunCommand(
      "timeout 60 chromium --headless=new --no-sandbox --user-data-dir=" + profile.string() +
          " --use-angle=swiftshader --enable-unsafe-swiftshader"
          " --window-size=1000,900 --virtual-time-budget=10000"
          " --enable-logging=stderr --v=0 " +
          what + " file://" + page.string() + " 2>&1",
      90);
  std::istringstream lines(b.run.output);
  for (std::string line; std::getline(lines, line);) {
    if (line.find(":CONSOLE") != std::string::npos) b.console += line + "\n";
  }
  return b;
}

TEST(ReportHtml, ChromiumShowsTheModelIn3d) {
  if (test::RunCommand("command -v chromium").exit_code != 0) {
    if (test::InCi()) FAIL() << "chromium not found: CI=true needs it (install_deps.sh)";
    GTEST_SKIP() << "chromium not found (Debian package chromium); skipping the browser check";
  }
  if (!fs::exists(fs::path(kDebianThreeDir) / "three.min.js")) {
    if (test::InCi()) FAIL() << "libjs-three not found: CI=true needs it (install_deps.sh)";
    GTEST_SKIP() << "libjs-three not installed; skipping the browser check";
  }
  test::TempDir dir;
  WriteQuadGlb(dir / "model.glb");
  const auto warnings = WriteReportHtml(
      dir / "report", {"# genscene report\n\nA page.\n", dir / "model.glb", kDebianThreeDir});
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  const fs::path page = dir / "report" / "report.html";

  const Browser dom = OpenInChromium(page, dir / "profile", "--dump-dom");
  ASSERT_EQ(dom.run.exit_code, 0) << dom.run.output;
  EXPECT_CONTAINS(dom.run.output, "<body data-model=\"loaded\">");
  EXPECT_EQ(dom.console, "") << "console messages";

  const Browser shot =
      OpenInChromium(page, dir / "profile", "--screenshot=" + (dir / "shot.png").string());
  ASSERT_EQ(shot.run.exit_code, 0) << shot.run.output;
  const ImageRgb image = ReadColorImage(dir / "shot.png", CameraResponse());
  ASSERT_EQ(image.width(), 1000);
  // The 3D view spans the page's width under the two titles (y 130-600 at this window size):
  // the quad fills its middle in the albedo's red, lit.
  int red = 0, total = 0;
  for (int v = 200; v < 550; v += 2) {
    for (int u = 300; u < 700; u += 2) {
      const Eigen::Vector3f c = image(u, v);
      red += c.x() > 0.1f && c.x() > 4.0f * c.y() && c.x() > 4.0f * c.z();
      ++total;
    }
  }
  std::printf("[ browser  ] %d of %d pixels of the view's middle show the red albedo\n", red,
              total);
  EXPECT_GT(red, total / 2);
}

}  // namespace
}  // namespace genscene::apps
