// Back-projection of keyframes into Mesh Colors: synthetic scenes
// lit by ambient light only, so that the observed colour equals the albedo exactly.
#include "texturing/backproject.h"

#include <cmath>

#include "core/parallel.h"
#include "core/synthetic.h"
#include "tests/test_util.h"
#include "texturing/raster.h"

namespace genscene::texturing {
namespace {

using test::ErrorOf;

CameraIntrinsics Intrinsics(int w, int h) {
  return CameraIntrinsics::Centered(w, h, 0.9 * w);
}

std::vector<RgbdFrame> WallViews(const SyntheticScene& scene, int count) {
  std::vector<RgbdFrame> frames;
  for (int i = 0; i < count; ++i) {
    const double x = -1.0 + 2.0 * i / (count - 1);
    const Eigen::Isometry3d pose =
        LookAt(Eigen::Vector3d(x, -1.2, 1.1), Eigen::Vector3d(0.4 * x, 1.0, 1.0));
    frames.push_back(RenderSyntheticFrame(scene, Intrinsics(240, 180), pose, i / 30.0));
  }
  return frames;
}

// The albedo the scene has at each texel (found by a short ray from just above the texel), and
// whether the texel is on the wall's front face.
struct Truth {
  std::vector<Eigen::Vector3f> albedo;
  std::vector<uint8_t> on_wall;
};
Truth TruthOf(const SyntheticScene& scene, const TriangleMesh& mesh, const MeshColors& texture) {
  TriangleMesh with_normals = mesh;
  with_normals.ComputeVertexNormals();
  const auto positions = texture.InterpolateVertexAttribute(mesh.vertices);
  Truth t;
  for (size_t s = 0; s < texture.SampleCount(); ++s) {
    int f;
    double b1, b2;
    texture.SampleFacePoint(s, &f, &b1, &b2);
    const Eigen::Vector3d n = with_normals.FaceNormalScaled(f).normalized().cast<double>();
    const Eigen::Vector3d p = positions[s].cast<double>();
    const auto hit = scene.Intersect(p + 1e-4 * n, -n);
    t.albedo.push_back(hit ? hit->albedo : Eigen::Vector3f::Constant(-1.0f));
    t.on_wall.push_back(std::abs(p.y() - 1.0) < 1e-6 && n.y() < -0.9);
  }
  return t;
}

struct ErrorFigures {
  double mean = 0.0, max = 0.0;  // |estimate - truth|, mean over channels
  size_t texels = 0;
  double range = 0.0;  // max - min of the true values
};
// Over wall texels seen by at least `min_views` keyframes (by `seen`'s view counts; default: r's).
ErrorFigures WallError(const TexturingResult& r, const Truth& truth, int min_views = 1,
                       const TexturingResult* seen = nullptr) {
  ErrorFigures e;
  float lo = 1e9f, hi = -1e9f;
  const std::vector<int32_t>& views = (seen ? seen : &r)->texture.labels();
  for (size_t s = 0; s < truth.albedo.size(); ++s) {
    if (!truth.on_wall[s] || views[s] < min_views) continue;
    const double err = (r.texture.colors()[s] - truth.albedo[s]).cwiseAbs().mean();
    e.mean += err;
    e.max = std::max(e.max, err);
    ++e.texels;
    lo = std::min(lo, truth.albedo[s].minCoeff());
    hi = std::max(hi, truth.albedo[s].maxCoeff());
  }
  e.mean /= std::max<size_t>(1, e.texels);
  e.range = hi - lo;
  return e;
}

TexturingOptions TestOptions() {
  TexturingOptions o;
  o.texel_spacing = 0.01;
  o.max_resolution = 128;
  return o;
}

TEST(Texturing, RasterizerDrawsWallsThatReachBehindTheCamera) {
  // A floor quad from y = -10 to 10 under a camera at the origin looking along +y: half of it is
  // behind the camera and must be clipped, not dropped.
  TriangleMesh floor;
  floor.vertices = {{-10, -10, 0}, {10, -10, 0}, {10, 10, 0}, {-10, 10, 0}};
  floor.faces = {{0, 1, 2}, {0, 2, 3}};
  const CameraIntrinsics k = Intrinsics(64, 48);
  const Eigen::Isometry3d world_from_camera =
      LookAt(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 5, 0.5));
  const ImageDepth depth = RenderDepth(floor, k, world_from_camera.inverse());
  int drawn = 0;
  double worst = 0.0;
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      // Exact planar depth of the floor z = 0 along the pixel's ray.
      const Eigen::Vector3d d = world_from_camera.linear() * k.RayDirection(u, v);
      if (d.z() >= 0.0) {
        EXPECT_EQ(depth(u, v), 0.0f) << u << "," << v;
        continue;
      }
      const double t = 1.0 / -d.z();  // ray parameter where z = 0 (d has camera z component 1)
      const Eigen::Vector3d hit = world_from_camera.translation() + t * d;
      if (hit.head<2>().cwiseAbs().maxCoeff() > 9.99) continue;  // beyond the quad's far end
      ++drawn;
      worst = std::max(worst, std::abs(depth(u, v) - t) / t);
    }
  }
  EXPECT_GT(drawn, k.width * k.height / 3);
  EXPECT_LT(worst, 1e-5) << "perspective-correct depth";
}

TEST(Texturing, StripedWallBehindAnOccluderIsRecoveredWithoutContamination) {
  const SyntheticScene scene = MakeStripedWallScene();
  const TriangleMesh mesh = scene.ToMesh();
  const std::vector<RgbdFrame> frames = WallViews(scene, 9);
  const TexturingResult r = TextureMesh(mesh, frames, TestOptions());
  const Truth truth = TruthOf(scene, mesh, r.texture);
  const ErrorFigures e = WallError(r, truth);
  std::cout << "wall texels " << e.texels << ": mean error " << e.mean << " ("
            << 100 * e.mean / e.range << " % of the range " << e.range << "), max " << e.max
            << "; filled " << r.stats.filled << ", samples used " << r.stats.samples_used
            << ", rejected " << r.stats.samples_rejected << "\n";
  ASSERT_GT(e.texels, 5000u);
  EXPECT_LE(e.mean, 0.02 * e.range);
  // Contamination by the red occluder would show as errors of ~0.5 and more.
  EXPECT_LT(e.max, 0.1);
  // The occluder's own front face is red.
  double worst_occluder = 0.0;
  for (size_t s = 0; s < truth.albedo.size(); ++s) {
    if (truth.on_wall[s] || r.texture.labels()[s] == 0) continue;
    if ((truth.albedo[s] - Eigen::Vector3f(0.9f, 0.05f, 0.05f)).norm() > 1e-6) continue;
    worst_occluder = std::max(
        worst_occluder,
        static_cast<double>((r.texture.colors()[s] - truth.albedo[s]).cwiseAbs().maxCoeff()));
  }
  EXPECT_LT(worst_occluder, 0.1);
}

TEST(Texturing, SensorDepthStopsAnOccluderTheMeshLacks) {
  // Images show the red box, the mesh is the wall alone: only the measured depth tells.
  const SyntheticScene scene = MakeStripedWallScene();
  SyntheticScene wall_only = scene;
  wall_only.boxes.resize(1);
  const TriangleMesh mesh = wall_only.ToMesh();
  const std::vector<RgbdFrame> frames = WallViews(scene, 9);
  TexturingOptions o = TestOptions();
  const TexturingResult with_depth = TextureMesh(mesh, frames, o);
  o.use_sensor_depth = false;
  const TexturingResult without = TextureMesh(mesh, frames, o);
  const Truth truth = TruthOf(wall_only, mesh, with_depth.texture);
  const ErrorFigures good = WallError(with_depth, truth);
  const ErrorFigures bad = WallError(without, truth);
  EXPECT_LT(good.max, 0.1);
  EXPECT_GT(bad.max, 0.2)
      << "without the depth test the red box must leak in (else this test proves nothing)";
}

TEST(Texturing, SpecularHighlightsInSomeViewsAreRejected) {
  // A bright disc (3x the albedo, a highlight) in 2 of 9 views, each at another spot of the wall.
  const SyntheticScene scene = MakeStripedWallScene();
  const TriangleMesh mesh = scene.ToMesh();
  std::vector<RgbdFrame> frames = WallViews(scene, 9);
  for (int i : {2, 6}) {
    ImageRgb& c = frames[i].color;
    for (int v = 0; v < c.height(); ++v) {
      for (int u = 0; u < c.width(); ++u) {
        if (std::hypot(u - 60.0, v - 50.0) < 25.0) c(u, v) *= 3.0f;
      }
    }
  }
  TexturingOptions o = TestOptions();
  const TexturingResult robust = TextureMesh(mesh, frames, o);
  o.outlier_ratio = 100.0;  // keeps every sample: a plain weighted mean
  const TexturingResult plain = TextureMesh(mesh, frames, o);
  const Truth truth = TruthOf(scene, mesh, robust.texture);
  // Where at least 4 views see a texel, at most 2 of them show a highlight: the median is clean.
  // (A texel seen only in highlighted views cannot be cleaned by any average.)
  const ErrorFigures good = WallError(robust, truth, 4, &plain);
  const ErrorFigures bad = WallError(plain, truth, 4, &plain);
  std::cout << "highlights: " << good.texels << " wall texels seen 4+ times: robust max error "
            << good.max << " (" << robust.stats.samples_rejected
            << " samples rejected), plain mean max error " << bad.max << "\n";
  EXPECT_GT(robust.stats.samples_rejected, 500u);
  EXPECT_LT(good.max, 0.1);
  EXPECT_LE(good.mean, 0.02 * good.range);
  EXPECT_GT(bad.max, 0.15)
      << "without rejection the highlights must show (else this test proves nothing)";
}

TEST(Texturing, SameOutputWithOneAndTwoThreads) {
  const SyntheticScene scene = MakeStripedWallScene();
  const TriangleMesh mesh = scene.ToMesh();
  const std::vector<RgbdFrame> frames = WallViews(scene, 5);
  TexturingOptions o = TestOptions();
  o.texel_spacing = 0.03;
  SetThreadCount(1);
  const TexturingResult a = TextureMesh(mesh, frames, o);
  SetThreadCount(2);
  const TexturingResult b = TextureMesh(mesh, frames, o);
  SetThreadCount(0);
  ASSERT_EQ(a.texture.SampleCount(), b.texture.SampleCount());
  for (size_t s = 0; s < a.texture.SampleCount(); ++s)
    ASSERT_EQ(a.texture.colors()[s], b.texture.colors()[s]) << s;
}

TEST(Texturing, BadInputsAreClearErrors) {
  const SyntheticScene scene = MakeStripedWallScene();
  const TriangleMesh mesh = scene.ToMesh();
  std::vector<RgbdFrame> frames = WallViews(scene, 3);
  const TexturingOptions o = TestOptions();
  EXPECT_CONTAINS(ErrorOf([&] { TextureMesh(TriangleMesh(), frames, o); }),
                  "the mesh has no faces");
  EXPECT_CONTAINS(ErrorOf([&] { TextureMesh(mesh, {}, o); }), "no keyframes");
  std::vector<RgbdFrame> unposed = frames;
  unposed[1].world_from_camera.reset();
  unposed[1].color_path = "kf/1.png";
  EXPECT_CONTAINS(ErrorOf([&] { TextureMesh(mesh, unposed, o); }),
                  "keyframe 1 (kf/1.png) has no camera pose");
  // Keyframes that look away from the mesh: no overlap at all.
  std::vector<RgbdFrame> away = frames;
  for (RgbdFrame& f : away)
    f.world_from_camera = LookAt(Eigen::Vector3d(0, -1.2, 1.1), Eigen::Vector3d(0, -5, 1.1));
  EXPECT_CONTAINS(ErrorOf([&] { TextureMesh(mesh, away, o); }),
                  "none of the 3 keyframes sees the mesh");
  TexturingOptions bad = o;
  bad.max_resolution = 48;
  EXPECT_CONTAINS(ErrorOf([&] { TextureMesh(mesh, frames, bad); }), "max_resolution = 48");
}

TEST(Texturing, NonManifoldEdgesAndIsolatedVerticesAreHandled) {
  const SyntheticScene scene = MakeStripedWallScene();
  TriangleMesh mesh = scene.ToMesh();
  // A fin sharing an edge of the wall's front face with both wall triangles (3 faces on one edge),
  // and a vertex no face uses.
  const int fin_tip = static_cast<int>(mesh.vertices.size());
  mesh.vertices.push_back(Eigen::Vector3f(0.0f, 0.5f, 1.0f));
  const int isolated = static_cast<int>(mesh.vertices.size());
  mesh.vertices.push_back(Eigen::Vector3f(5.0f, 5.0f, 5.0f));
  int front = -1;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (mesh.FaceNormalScaled(f).normalized().y() < -0.99f &&
        mesh.vertices[mesh.faces[f][0]].y() < 1.01f) {
      front = static_cast<int>(f);
      break;
    }
  }
  ASSERT_GE(front, 0);
  const Eigen::Vector3i wall_face = mesh.faces[front];
  mesh.faces.emplace_back(wall_face[0], wall_face[1], fin_tip);
  mesh.normals.clear();
  mesh.face_colors.push_back(Eigen::Vector3f::Zero());
  const TexturingResult r = TextureMesh(mesh, WallViews(scene, 3), TestOptions());
  EXPECT_EQ(r.stats.isolated, 1u);
  EXPECT_EQ(r.texture.colors()[isolated], Eigen::Vector3f::Zero());
  EXPECT_GT(r.stats.observed, 1000u);
  for (const Eigen::Vector3f& c : r.texture.colors()) ASSERT_TRUE(c.allFinite());
}

}  // namespace
}  // namespace genscene::texturing
