// genscene-view as a user runs it: screenshots under Xvfb + Mesa (llvmpipe) read back and checked,
// and the messages for missing pieces and a missing display.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "core/color.h"
#include "core/image_io.h"
#include "core/light_set.h"
#include "core/mesh_colors.h"
#include "core/ply_io.h"
#include "core/se3.h"
#include "core/synthetic.h"
#include "core/trajectory.h"
#include "render/path_tracer.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

// "tx ty tz qx qy qz qw" of a pose, for --camera and groundtruth.txt.
std::string PoseText(const Eigen::Isometry3d& pose) {
  Eigen::Vector3d t;
  Eigen::Quaterniond q;
  ToTranslationQuaternion(pose, &t, &q);
  return Format(t.x(), " ", t.y(), " ", t.z(), " ", q.x(), " ", q.y(), " ", q.z(), " ", q.w());
}

// Runs genscene-view with `args` under xvfb-run -a; fails the test when xvfb-run is missing.
test::CommandResult RunViewer(const std::string& args) {
  if (RunCommand("command -v xvfb-run").exit_code != 0) {
    ADD_FAILURE() << "xvfb-run not found: the viewer tests need a display; install xvfb and xauth "
                     "(scripts/install_deps.sh)";
    return {};
  }
  return RunCommand("xvfb-run -a " + AppPath("genscene-view") + " " + args, 120);
}

// Mean linear colour of pixels [u0, u1) x [v0, v1).
Eigen::Vector3f MeanOver(const ImageRgb& image, int u0, int u1, int v0, int v1) {
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  for (int v = v0; v < v1; ++v) {
    for (int u = u0; u < u1; ++u) sum += image(u, v);
  }
  return sum / static_cast<float>((u1 - u0) * (v1 - v0));
}

// Every sample of `colors` takes the value f(face containing it).
template <typename F>
void FillByFace(MeshColors* colors, F&& f) {
  for (size_t s = 0; s < colors->SampleCount(); ++s) {
    int face = 0;
    double b1 = 0.0, b2 = 0.0;
    colors->SampleFacePoint(s, &face, &b1, &b2);
    colors->colors()[s] = f(face);
  }
}

// The Cornell box (core/synthetic.h) as a workspace whose albedo.mcol carries the
// face colours (faces unshared, so no sample sits between two walls), texture.mcol half of it,
// cluster labels per wall; seen through the front wall (culled: it faces into the room), red wall
// left, green wall right, in every mode.
TEST(ViewerApp, CornellBoxScreenshotShowsRedLeftGreenRight) {
  test::TempDir ws;
  const TriangleMesh shared = MakeCornellScene().ToMesh(1);
  TriangleMesh mesh;
  for (size_t f = 0; f < shared.faces.size(); ++f) {
    const int base = static_cast<int>(mesh.vertices.size());
    for (int k = 0; k < 3; ++k) mesh.vertices.push_back(shared.vertices[shared.faces[f][k]]);
    mesh.faces.emplace_back(base, base + 1, base + 2);
  }
  WritePly(ws / "mesh.ply", mesh);
  MeshColors albedo(mesh, std::vector<int>(mesh.faces.size(), 2));
  FillByFace(&albedo, [&](int face) { return shared.face_colors[face]; });
  albedo.labels().resize(albedo.SampleCount());
  for (size_t s = 0; s < albedo.SampleCount(); ++s) {
    const Eigen::Vector3f c = albedo.colors()[s];
    albedo.labels()[s] = c.x() > 0.5f && c.y() < 0.2f ? 1 : c.y() > 0.4f && c.x() < 0.2f ? 2 : 0;
  }
  WriteMeshColors(ws / "albedo.mcol", albedo);
  MeshColors observed = albedo;
  observed.labels().clear();
  for (Eigen::Vector3f& c : observed.colors()) c *= 0.5f;
  WriteMeshColors(ws / "texture.mcol", observed);

  const std::string camera = PoseText(LookAt({0.0, -3.0, 1.0}, {0.0, 0.0, 1.0}));
  const std::string common =
      ws.path().string() + " --size 160x120 --cull-back-faces --camera \"" + camera + "\"";
  for (const char* mode : {"albedo", "color", "shading", "clusters"}) {
    const fs::path png = ws / (std::string(mode) + ".png");
    const auto r = RunViewer(common + " --mode " + mode + " --screenshot " + png.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_CONTAINS(r.output, "trajectory.txt: missing");
    const ImageRgb image = ReadColorImage(png, CameraResponse());
    ASSERT_TRUE(image.SameSize(160, 120));
    const Eigen::Vector3f left = MeanOver(image, 16, 40, 30, 70);
    const Eigen::Vector3f right = MeanOver(image, 120, 144, 30, 70);
    const Eigen::Vector3f red(0.63f, 0.065f, 0.05f), green(0.14f, 0.45f, 0.091f);
    const std::string m = mode;
    SCOPED_TRACE(m + ": left " + Format(left.transpose()) + ", right " + Format(right.transpose()));
    if (m == "albedo" || m == "color") {
      const float scale = m == "albedo" ? 1.0f : 0.5f;  // observed = albedo / 2
      EXPECT_LT((left - scale * red).cwiseAbs().maxCoeff(), 0.01f);
      EXPECT_LT((right - scale * green).cwiseAbs().maxCoeff(), 0.01f);
      // The yellow sphere on the floor, centre at pixel (59.7, 91.7): the rows are not flipped.
      const Eigen::Vector3f sphere = MeanOver(image, 57, 62, 89, 94);
      EXPECT_LT((sphere - scale * Eigen::Vector3f(0.8f, 0.75f, 0.3f)).cwiseAbs().maxCoeff(), 0.01f)
          << sphere.transpose();
    } else if (m == "shading") {  // observed / albedo = 1/2 everywhere
      EXPECT_LT((left - Eigen::Vector3f::Constant(0.5f)).cwiseAbs().maxCoeff(), 0.01f);
      EXPECT_LT((right - Eigen::Vector3f::Constant(0.5f)).cwiseAbs().maxCoeff(), 0.01f);
    } else {  // clusters: each wall one false colour, the two walls different
      EXPECT_LT((image(16, 30) - image(39, 69)).norm(), 1e-3f);
      EXPECT_GT((left - right).norm(), 0.05f);
    }
  }
}

// Lights: a lights.json with one lit voxel under the ceiling (as genscene-lights
// writes it) draws a glyph there: the pixels that change against the same view without lights
// sit around the voxel's projection, above the image centre.
TEST(ViewerApp, LightGlyphsAppearWhereTheLightsAre) {
  test::TempDir ws;
  WritePly(ws / "mesh.ply", MakeCornellScene().ToMesh(1));
  const std::string camera = PoseText(LookAt({0.0, -3.0, 1.0}, {0.0, 0.0, 1.0}));
  const std::string common =
      ws.path().string() + " --size 320x240 --cull-back-faces --camera \"" + camera + "\"";
  const auto before = RunViewer(common + " --screenshot " + (ws / "before.png").string());
  ASSERT_EQ(before.exit_code, 0) << before.output;
  EXPECT_CONTAINS(before.output, "lights.json: missing");
  VoxelLightGrid grid;
  grid.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 2));
  grid.dims = Eigen::Vector3i(5, 5, 5);
  grid.intensity.assign(125, Eigen::Vector3f::Zero());
  grid.weights.assign(125, {0.1f, 0.1f, 0.1f, 0.1f, 0.0f, 1.0f});
  const int top = 2 + 5 * 2 + 25 * 4;  // centre column, top layer: (0, 0, 1.8)
  grid.intensity[top] = Eigen::Vector3f(30.0f, 24.0f, 18.0f);
  WriteLightsJson(ws / "lights.json", grid);
  const auto after = RunViewer(common + " --screenshot " + (ws / "after.png").string());
  ASSERT_EQ(after.exit_code, 0) << after.output;
  const ImageRgb a = ReadColorImage(ws / "before.png", CameraResponse());
  const ImageRgb b = ReadColorImage(ws / "after.png", CameraResponse());
  ASSERT_TRUE(a.SameSize(b.width(), b.height()));
  double su = 0.0, sv = 0.0;
  int changed = 0;
  for (int v = 0; v < a.height(); ++v) {
    for (int u = 0; u < a.width(); ++u) {
      if ((a(u, v) - b(u, v)).cwiseAbs().maxCoeff() > 0.05f) su += u, sv += v, ++changed;
    }
  }
  ASSERT_GT(changed, 10) << "no glyph drawn";
  // (0, 0, 1.8) seen from (0, -3, 1) looking at (0, 0, 1): on the vertical centre line, above
  // the centre row.
  EXPECT_NEAR(su / changed, 159.5, 16.0);
  EXPECT_LT(sv / changed, 100.0);
}

// A camera 1.2 m above the unit quad, looking down at it (96 x 96 pixels), written as the
// workspace's keyframe 0; and the quad path-traced from it under a point light above, with
// pixel-centre rays: that radiance over the radiance with albedo 1 is the albedo image (exact: a
// delta light, one sample per pixel).
PosedView QuadView() {
  PosedView view;
  view.intrinsics.width = view.intrinsics.height = 96;
  view.intrinsics.fx = view.intrinsics.fy = 110.0;
  view.intrinsics.cx = view.intrinsics.cy = 47.5;
  view.world_from_camera = LookAt({0.5, 0.45, 1.2}, {0.5, 0.5, 0.0});
  return view;
}

void WriteKeyframeCamera(const test::TempDir& ws, const PosedView& view) {
  test::WriteFile(ws / "keyframes" / "intrinsics.txt", view.intrinsics.ToString() + "\n");
  test::WriteFile(ws / "keyframes" / "groundtruth.txt",
                  "0 " + PoseText(view.world_from_camera) + "\n");
}

render::RenderOutput RenderQuad(const TriangleMesh& quad, const PosedView& view,
                                render::SurfaceAlbedo albedo) {
  render::RenderOptions options;
  options.spp = 1;
  options.filter = "center";
  options.max_depth = 2;
  render::Scene scene;
  render::SceneMesh m;
  m.mesh = quad;
  m.albedo = std::move(albedo);
  scene.meshes.push_back(m);
  scene.point_lights.push_back({Eigen::Vector3d(0.5, 0.5, 1.5), Eigen::Vector3f::Constant(5.0f)});
  return render::PathTracer(scene).Render(view, options, 7);
}

// Albedo at the lattice point (i, j) of a face: a checkerboard of the samples on the 9 x 9 grid of
// the unit square (R = 8 on both triangles of the quad), 0.1 / 0.9.
class LookupField : public render::AlbedoField {
 public:
  LookupField(std::shared_ptr<const MeshColors> colors, bool baked)
      : colors_(std::move(colors)), baked_(baked) {}
  // Nearest = what the viewer must show; baked = the three vertex samples interpolated, i.e. what
  // vertex colours would show.
  Eigen::Vector3f Eval(int face, float b1, float b2) const override {
    if (!baked_) return colors_->Nearest(face, b1, b2);
    const int r = colors_->FaceResolution(face);
    const auto& c = colors_->colors();
    return (1.0f - b1 - b2) * c[colors_->SampleIndex(face, 0, 0)] +
           b1 * c[colors_->SampleIndex(face, r, 0)] + b2 * c[colors_->SampleIndex(face, 0, r)];
  }

 private:
  std::shared_ptr<const MeshColors> colors_;
  bool baked_;
};

// A checkerboard stored in Mesh Colors at R = 8 appears sharp. The screenshot is
// compared with a path-traced render of the same view (albedo = path-traced radiance under a
// point light divided by the same render with albedo 1: exact, a delta light and pixel-centre
// rays); vertex colours (the baked field) fail the same bound.
TEST(ViewerApp, MeshColorsCheckerboardIsSharpAndMatchesPathTracer) {
  test::TempDir ws;
  TriangleMesh quad;
  quad.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  quad.faces = {{0, 1, 2}, {0, 2, 3}};
  WritePly(ws / "mesh.ply", quad);
  auto colors = std::make_shared<MeshColors>(quad, std::vector<int>{8, 8});
  const std::vector<Eigen::Vector3f> position = colors->InterpolateVertexAttribute(quad.vertices);
  for (size_t s = 0; s < colors->SampleCount(); ++s) {
    const int a = static_cast<int>(std::lround(8 * position[s].x()));
    const int b = static_cast<int>(std::lround(8 * position[s].y()));
    colors->colors()[s] = Eigen::Vector3f::Constant((a + b) % 2 ? 0.9f : 0.1f);
  }
  WriteMeshColors(ws / "albedo.mcol", *colors);

  // The camera: keyframe 0 of the workspace, looking down at the quad.
  const PosedView view = QuadView();
  WriteKeyframeCamera(ws, view);
  const fs::path png = ws / "checker.png";
  const auto r = RunViewer(
      ws.path().string() +
      " --mode albedo --camera keyframe:0 --size 96x96 --no-overlay --screenshot " + png.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const ImageRgb shot = ReadColorImage(png, CameraResponse());

  // Path-traced albedo images: field / constant 1, same view, pixel-centre rays.
  const auto render = [&](render::SurfaceAlbedo albedo) { return RenderQuad(quad, view, albedo); };
  render::SurfaceAlbedo field, baked;
  field.kind = baked.kind = render::SurfaceAlbedo::Kind::kField;
  field.field = std::make_shared<LookupField>(colors, false);
  baked.field = std::make_shared<LookupField>(colors, true);
  const render::RenderOutput white =
      render(render::SurfaceAlbedo::Constant(Eigen::Vector3f::Ones()));
  const render::RenderOutput sharp = render(field), smeared = render(baked);

  // Mean |difference| over the pattern's pixels, as a fraction of the pattern's contrast (0.8).
  double diff_sharp = 0.0, diff_baked = 0.0;
  int n = 0;
  for (int v = 0; v < 96; ++v) {
    for (int u = 0; u < 96; ++u) {
      if (white.object(u, v) < 0) continue;
      const float g = white.radiance(u, v).x();
      ASSERT_GT(g, 0.0f);
      const float reference = sharp.radiance(u, v).x() / g;
      diff_sharp += std::abs(shot(u, v).x() - reference) / 0.8;
      diff_baked += std::abs(smeared.radiance(u, v).x() / g - reference) / 0.8;
      ++n;
    }
  }
  ASSERT_GT(n, 96 * 96 / 2);  // the quad fills most of the view
  diff_sharp /= n;
  diff_baked /= n;
  std::printf(
      "checkerboard R=8: mean |viewer - path traced| = %.2f %%, vertex colours: %.2f %% (%d px)\n",
      100 * diff_sharp, 100 * diff_baked, n);
  EXPECT_LE(diff_sharp, 0.05);
  EXPECT_GT(diff_baked, 0.05);
}

// The shader's Mesh Colors lookup (its GLSL copy of LocateInLattice) against the CPU's, with
// linear interpolation, at every lattice size from one cell to 64 per edge: random sample colours,
// so a wrong sample or weight anywhere (the faces' long edges, their shared diagonal, the
// rounding at vertices) shows. The reference is the path tracer's albedo image (radiance under a
// point light over the radiance with albedo 1, pixel-centre rays) with MeshColors::Linear.
class LinearField : public render::AlbedoField {
 public:
  explicit LinearField(std::shared_ptr<const MeshColors> colors) : colors_(std::move(colors)) {}
  Eigen::Vector3f Eval(int face, float b1, float b2) const override {
    return colors_->Linear(face, b1, b2);
  }

 private:
  std::shared_ptr<const MeshColors> colors_;
};

TEST(ViewerApp, LinearMeshColorsLookupMatchesTheCpuAtEveryResolution) {
  TriangleMesh quad;
  quad.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  quad.faces = {{0, 1, 2}, {0, 2, 3}};
  const PosedView view = QuadView();
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> unit(0.1f, 0.9f);
  for (const std::vector<int>& resolutions :
       std::vector<std::vector<int>>{{1, 1}, {4, 2}, {64, 64}}) {
    test::TempDir ws;
    WritePly(ws / "mesh.ply", quad);
    auto colors = std::make_shared<MeshColors>(quad, resolutions);
    for (auto& c : colors->colors()) c = {unit(rng), unit(rng), unit(rng)};
    WriteMeshColors(ws / "albedo.mcol", *colors);
    WriteKeyframeCamera(ws, view);
    const fs::path png = ws / "linear.png";
    const auto r = RunViewer(ws.path().string() +
                             " --mode albedo --lookup linear --camera keyframe:0 --size 96x96 "
                             "--no-overlay --screenshot " +
                             png.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const ImageRgb shot = ReadColorImage(png, CameraResponse());

    const auto render = [&](render::SurfaceAlbedo albedo) {
      return RenderQuad(quad, view, albedo);
    };
    render::SurfaceAlbedo field;
    field.kind = render::SurfaceAlbedo::Kind::kField;
    field.field = std::make_shared<LinearField>(colors);
    const render::RenderOutput white =
        render(render::SurfaceAlbedo::Constant(Eigen::Vector3f::Ones()));
    const render::RenderOutput linear = render(field);
    double diff = 0.0;
    int n = 0, far = 0;
    for (int v = 0; v < 96; ++v) {
      for (int u = 0; u < 96; ++u) {
        if (white.object(u, v) < 0) continue;
        const Eigen::Vector3f reference = linear.radiance(u, v) / white.radiance(u, v).x();
        const float d = (shot(u, v) - reference).cwiseAbs().maxCoeff();
        diff += d;
        far += d > 0.1f;
        ++n;
      }
    }
    ASSERT_GT(n, 96 * 96 / 2);
    std::printf(
        "R = %d / %d: mean |viewer - CPU lookup| %.4f, %d of %d pixels off by more than 0.1\n",
        resolutions[0], resolutions[1], diff / n, far, n);
    EXPECT_LE(diff / n, 0.02) << "R = " << resolutions[0];
    EXPECT_LE(far, n / 200) << "R = " << resolutions[0];
  }
}

// What is missing is said, one line each, and what exists is shown; no folder, or
// nothing to show, is an error; no display is one line suggesting xvfb-run or --screenshot.
TEST(ViewerApp, MissingPiecesAndNoDisplayAreReportedClearly) {
  test::TempDir ws;
  TriangleMesh quad;
  quad.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  quad.faces = {{0, 1, 2}, {0, 2, 3}};

  // Nothing at all.
  auto r = RunViewer(ws.path().string() + " --screenshot " + (ws / "x.png").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "nothing to show");
  r = RunViewer((ws / "absent").string() + " --screenshot " + (ws / "x.png").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "no such workspace folder");

  // A mesh only: shown (geometry), and every missing piece named with the stage that makes it.
  WritePly(ws / "mesh.ply", quad);
  test::WriteFile(ws / "albedo.mcol", "not a mesh colors file");
  const fs::path png = ws / "mesh_only.png";
  r = RunViewer(ws.path().string() + " --mode albedo --size 64x48 --camera \"" +
                PoseText(LookAt({0.5, 0.45, 1.5}, {0.5, 0.5, 0.0})) + "\" --screenshot " +
                png.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* line : {"texture.mcol: missing (run genscene-texture)",
                           "albedo.mcol: not shown:", "trajectory.txt: missing (run genscene-fuse)",
                           "keyframes: missing", "lights.json: missing", "--mode albedo needs",
                           "genscene-view: geometry, 64x48"}) {
    EXPECT_CONTAINS(r.output, line);
  }
  const ImageRgb image = ReadColorImage(png, CameraResponse());
  EXPECT_GT(image(32, 24).x(), 0.3f);  // the grey quad in the middle
  EXPECT_LT(image(0, 0).x(), 0.1f);    // the background (0.08)

  // --refined shows mesh_refined.ply's vertices (the quad moved 0.6 m right: the middle is empty);
  // without one it is a clear error.
  const std::string camera =
      " --size 64x48 --camera \"" + PoseText(LookAt({0.5, 0.45, 1.5}, {0.5, 0.5, 0.0})) + "\"";
  r = RunViewer(ws.path().string() + " --refined" + camera + " --screenshot " + png.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "--refined: no mesh_refined.ply to show");
  TriangleMesh moved = quad;
  for (Eigen::Vector3f& v : moved.vertices) v.x() += 0.6f;
  WritePly(ws / "mesh_refined.ply", moved);
  r = RunViewer(ws.path().string() + " --refined" + camera + " --screenshot " + png.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(ReadColorImage(png, CameraResponse())(32, 24).x(), 0.1f);
  r = RunViewer(ws.path().string() + camera + " --screenshot " + png.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_GT(ReadColorImage(png, CameraResponse())(32, 24).x(), 0.3f);
  fs::remove(ws / "mesh_refined.ply");

  r = RunViewer(ws.path().string() + " --camera keyframe:2 --screenshot " + png.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_CONTAINS(r.output, "keyframe:2: the workspace has 0 keyframes");

  // No display, with and without --screenshot: one line, non-zero exit.
  for (const std::string extra : {"", " --screenshot x.png"}) {
    r = RunCommand("env -u DISPLAY -u WAYLAND_DISPLAY " + AppPath("genscene-view") + " " +
                   ws.path().string() + extra);
    EXPECT_NE(r.exit_code, 0) << r.output;
    EXPECT_CONTAINS(r.output, "genscene-view: error: no display");
    EXPECT_CONTAINS(r.output, "xvfb-run -a genscene-view");
    if (extra.empty()) {
      EXPECT_CONTAINS(r.output, "--screenshot");
    }
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
}

}  // namespace
}  // namespace genscene
