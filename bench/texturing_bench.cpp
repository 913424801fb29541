// Texturing speed against error and the albedo figure.
//  1. A striped wall (3 m x 2 m, albedo varying smoothly between two colours with a 0.5 m period)
//     behind a red box, lit by ambient light only so that the observed colour is the albedo;
//     the exact mesh is pre-split into ~10 cm triangles like a fused mesh; 9 keyframes at
//     320x240. For each texel spacing: texels, observed texels, seconds, texels per second, and
//     the mean / max colour error of the observed wall texels against the true albedo.
//  2. With ../shared/data: the Blender Cycles Cornell box (full global illumination, 3 views):
//     texturing + albedo, the clusters, and Fig. 2 of the paper written as
//     OUT/fig2_cbox_albedo.png = [input image | observed colour (texture.mcol) | clustered albedo].
// Run by hand:  build/bench/bench_texturing [--out DIR] [--data DIR] [--threads N]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

#include "core/frame_source.h"
#include "core/image_io.h"
#include "core/parallel.h"
#include "core/ply_io.h"
#include "core/synthetic.h"
#include "texturing/albedo.h"
#include "texturing/backproject.h"
#include "texturing/raster.h"

using namespace genscene;
using namespace genscene::texturing;
namespace fs = std::filesystem;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void SpeedAgainstError() {
  const SyntheticScene scene = MakeStripedWallScene();
  const TriangleMesh exact = scene.ToMesh();
  // Split into small triangles (R = 32 per original face) like a fused mesh.
  TriangleMesh mesh =
      MeshColors(exact, std::vector<int>(exact.faces.size(), 32)).ToSubdividedMesh(exact);
  mesh.vertex_colors.clear();
  mesh.normals.clear();
  const CameraIntrinsics k = CameraIntrinsics::Centered(320, 240, 288.0);
  std::vector<RgbdFrame> frames;
  for (int i = 0; i < 9; ++i) {
    const double x = -1.0 + 2.0 * i / 8.0;
    frames.push_back(
        RenderSyntheticFrame(scene, k, LookAt({x, -1.2, 1.1}, {0.4 * x, 1.0, 1.0}), i / 30.0));
  }
  std::printf("\n1. Striped wall + occluder, %zu triangles, 9 keyframes 320x240, %d threads\n",
              mesh.faces.size(), ThreadCount());
  std::printf("%-10s %-9s %10s %10s %9s %12s %11s %11s\n", "spacing", "R", "texels", "observed",
              "seconds", "Mtexels/s", "mean err", "max err");
  for (double spacing : {0.04, 0.02, 0.01, 0.005}) {
    TexturingOptions o;
    o.texel_spacing = spacing;
    o.limit_to_image_detail = false;                   // the table is about the spacing asked for
    TexturingResult r = TextureMesh(mesh, frames, o);  // warm-up
    double best = 1e300;
    for (int run = 0; run < 3; ++run) {
      const double t0 = Now();
      r = TextureMesh(mesh, frames, o);
      best = std::min(best, Now() - t0);
    }
    int r_lo = 1 << 30, r_hi = 0;
    for (int rf : r.texture.face_resolutions())
      r_lo = std::min(r_lo, rf), r_hi = std::max(r_hi, rf);
    // Error of the linear lookup at 20 fixed random points per face of the wall's front (not at
    // the texels themselves: between texels is where the spacing shows), where every texel of
    // the sub-triangle was observed.
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
    double sum = 0.0, worst = 0.0;
    size_t n = 0;
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      const Eigen::Vector3f a = mesh.vertices[mesh.faces[f][0]],
                            b = mesh.vertices[mesh.faces[f][1]],
                            c = mesh.vertices[mesh.faces[f][2]];
      if (std::abs(a.y() - 1.0f) > 1e-5f || std::abs(b.y() - 1.0f) > 1e-5f ||
          std::abs(c.y() - 1.0f) > 1e-5f)
        continue;
      for (int k = 0; k < 20; ++k) {
        float b1 = uniform(rng), b2 = uniform(rng);
        if (b1 + b2 > 1.0f) b1 = 1.0f - b1, b2 = 1.0f - b2;
        const int rf = r.texture.FaceResolution(static_cast<int>(f));
        const int i = std::min(static_cast<int>(b1 * rf), rf - 1),
                  j = std::min(static_cast<int>(b2 * rf), rf - 1 - i);
        if (r.texture.labels()[r.texture.SampleIndex(static_cast<int>(f), i, j)] == 0 ||
            r.texture.labels()[r.texture.SampleIndex(static_cast<int>(f), i + 1, j)] == 0 ||
            r.texture.labels()[r.texture.SampleIndex(static_cast<int>(f), i, j + 1)] == 0) {
          continue;
        }
        const Eigen::Vector3d p = ((1.0f - b1 - b2) * a + b1 * b + b2 * c).cast<double>();
        const double err =
            (r.texture.Linear(static_cast<int>(f), b1, b2) - scene.boxes[0].AlbedoAt(p))
                .cwiseAbs()
                .mean();
        sum += err, worst = std::max(worst, err), ++n;
      }
    }
    std::printf("%-10s %-9s %10zu %10zu %9.3f %12.2f %11.5f %11.5f\n",
                (std::to_string(spacing * 100).substr(0, 4) + " cm").c_str(),
                (std::to_string(r_lo) + "-" + std::to_string(r_hi)).c_str(), r.stats.texels,
                r.stats.observed, best, r.stats.texels / best / 1e6, sum / std::max<size_t>(n, 1),
                worst);
  }
  std::printf(
      "(error: mean over channels of |linear lookup - albedo| at random points of the observed "
      "wall; albedo range 0.1-0.9)\n");
}

void CornellFigure(const fs::path& data, const fs::path& out) {
  const fs::path root = data / "cbox-cycles";
  const TriangleMesh mesh = ReadPly(root / "geometry" / "scene.ply");
  auto source = OpenFrameSource((root / "views" / "train").string(), SourceOptions());
  const std::vector<RgbdFrame> frames = ReadAllFrames(*source);
  TexturingOptions to;
  to.texel_spacing = 0.01;
  double t0 = Now();
  const TexturingResult texture = TextureMesh(mesh, frames, to);
  const double t_texture = Now() - t0;
  t0 = Now();
  const AlbedoResult albedo =
      EstimateAlbedo(texture.texture, texture.texture.labels(), AlbedoOptions());
  const double t_albedo = Now() - t0;
  std::printf(
      "\n2. Cycles Cornell box (views/train, %zu views 160x120): %zu texels (%zu observed) in %.3f "
      "s, "
      "albedo in %.3f s: %d chromaticity classes, %d pieces, %zu clusters\n",
      frames.size(), texture.stats.texels, texture.stats.observed, t_texture, t_albedo,
      albedo.stats.chroma_classes, albedo.stats.pieces, albedo.clusters.size());
  for (const AlbedoCluster& c : albedo.clusters) {
    std::printf(
        "   cluster %d: albedo (%.3f, %.3f, %.3f), chromaticity (%.3f, %.3f, %.3f), %zu texels, %d "
        "pieces\n",
        c.id, c.albedo.x(), c.albedo.y(), c.albedo.z(), c.chromaticity.x(), c.chromaticity.y(),
        c.chromaticity.z(), c.texels, c.pieces);
  }
  // Fig. 2: the first view, three panels.
  const RgbdFrame& view = frames.front();
  const SurfaceImage surface =
      RenderSurface(mesh, view.intrinsics, view.world_from_camera->inverse());
  const int w = view.intrinsics.width, h = view.intrinsics.height;
  std::vector<float> lum;
  for (const Eigen::Vector3f& c : view.color.pixels()) lum.push_back(c.maxCoeff());
  std::nth_element(lum.begin(), lum.begin() + lum.size() * 97 / 100, lum.end());
  const float exposure = 1.0f / std::max(1e-6f, lum[lum.size() * 97 / 100]);
  ImageRgb figure(3 * w, h, Eigen::Vector3f::Zero());
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      figure(u, v) = view.color(u, v) * exposure;
      const int f = surface.face(u, v);
      if (f < 0) continue;
      figure(w + u, v) = texture.texture.Linear(f, surface.b1(u, v), surface.b2(u, v)) * exposure;
      figure(2 * w + u, v) = albedo.albedo.Linear(f, surface.b1(u, v), surface.b2(u, v));
    }
  }
  fs::create_directories(out);
  WritePng(out / "fig2_cbox_albedo.png", figure);
  std::printf("   figure: %s (input | observed colour | clustered albedo)\n",
              (out / "fig2_cbox_albedo.png").string().c_str());
}

}  // namespace

int main(int argc, char** argv) {
  fs::path out = "bench-out", data = "../shared/data";
  int threads = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--out")) out = argv[i + 1];
    if (!std::strcmp(argv[i], "--data")) data = argv[i + 1];
    if (!std::strcmp(argv[i], "--threads")) threads = std::atoi(argv[i + 1]);
  }
  SetThreadCount(threads);
  try {
    SpeedAgainstError();
    if (fs::exists(data / "cbox-cycles")) {
      CornellFigure(data, out);
    } else {
      std::printf("\n2. skipped: %s/cbox-cycles not found (--data DIR)\n", data.string().c_str());
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_texturing: %s\n", e.what());
    return 1;
  }
  return 0;
}
