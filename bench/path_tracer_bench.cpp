// Rays per second of the full path tracer against a bare Embree intersect/occlude loop over the
// same scene and the same number of rays, in one run, and the path
// tracer's error against a high-spp reference as spp grows. Each rate is the best of 3 runs after
// a warm-up. Run by hand:
//   build/bench/bench_path_tracer [width] [spp]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "core/parallel.h"
#include "core/rng.h"
#include "core/synthetic.h"
#include "render/path_tracer.h"

using namespace genscene;
using namespace genscene::render;

namespace {

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The synthetic Cornell room with a 0.5 x 0.5 m area light under its ceiling.
Scene MakeScene() {
  const SyntheticScene cornell = MakeCornellScene();
  Scene scene;
  SceneMesh room;
  room.name = "room";
  room.mesh = cornell.ToMesh(4);
  room.albedo = SurfaceAlbedo::FromMesh(room.mesh, Eigen::Vector3f::Constant(0.5f));
  scene.meshes.push_back(room);
  SceneMesh light;
  light.name = "light";
  light.mesh.vertices = {{-0.25f, -0.25f, 1.99f},
                         {0.25f, -0.25f, 1.99f},
                         {0.25f, 0.25f, 1.99f},
                         {-0.25f, 0.25f, 1.99f}};
  light.mesh.faces = {{0, 2, 1}, {0, 3, 2}};  // facing down
  light.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Zero());
  light.emission = Eigen::Vector3f(20.0f, 16.0f, 12.0f);
  scene.meshes.push_back(light);
  return scene;
}

}  // namespace

int main(int argc, char** argv) {
  const int width = argc > 1 ? std::atoi(argv[1]) : 160;
  const int spp = argc > 2 ? std::atoi(argv[2]) : 32;
  const Scene scene = MakeScene();
  const PathTracer tracer(scene);
  PosedView view;
  view.intrinsics.width = width;
  view.intrinsics.height = width * 3 / 4;
  view.intrinsics.fx = view.intrinsics.fy = 0.8 * width;
  view.intrinsics.cx = 0.5 * (width - 1);
  view.intrinsics.cy = 0.5 * (view.intrinsics.height - 1);
  view.world_from_camera = LookAt({0.0, -0.95, 1.0}, {0.0, 0.5, 0.8});
  RenderOptions options;
  options.spp = spp;

  // 1. The path tracer: a warm-up render (thread pool, first touches), then the best of 3.
  RenderOptions warm = options;
  warm.spp = 1;
  tracer.Render(view, warm, 0);
  RenderOutput out;
  double trace_s = INFINITY;
  for (int run = 0; run < 3; ++run) {
    const auto start = std::chrono::steady_clock::now();
    out = tracer.Render(view, options, 1);
    trace_s = std::min(trace_s, Seconds(start));
  }
  const uint64_t rays = out.rays.total();

  // 2. The same numbers of intersect and occlude calls, bare: random rays from random points
  //    inside the room, with no shading, sampling or bookkeeping.
  const RayTracer& bare = tracer.tracer();
  const size_t n_intersect = out.rays.intersect, n_occluded = out.rays.occluded;
  const size_t chunk = 4096;
  uint64_t hits = 0;
  double bare_s = INFINITY;
  for (int run = 0; run < 3; ++run) {
    const auto start = std::chrono::steady_clock::now();
    hits = DeterministicReduce(
        n_intersect + n_occluded, chunk, uint64_t{0},
        [&](size_t b, size_t e) {
          uint64_t h = 0;
          CounterRng rng(7, b);
          for (size_t i = b; i < e; ++i) {
            const Eigen::Vector3f o(1.8f * rng.Uniform() - 0.9f, 1.8f * rng.Uniform() - 0.9f,
                                    0.1f + 1.8f * rng.Uniform());
            const Eigen::Vector3f d =
                Eigen::Vector3f(rng.Uniform() - 0.5f, rng.Uniform() - 0.5f, rng.Uniform() - 0.5f)
                    .normalized();
            if (i < n_intersect) {
              h += bare.Intersect(o, d).has_value();
            } else {
              h += bare.Occluded(o, d, 0.0f, 0.5f);
            }
          }
          return h;
        },
        [](uint64_t a, uint64_t b) { return a + b; });
    bare_s = std::min(bare_s, Seconds(start));
  }

  std::printf("scene: synthetic Cornell room, %zu triangles; %dx%d, %d spp, %d threads\n",
              scene.meshes[0].mesh.faces.size() + 2, width, view.intrinsics.height, spp,
              ThreadCount());
  std::printf("%-28s %14s %12s %14s\n", "loop", "rays", "seconds", "Mrays/s");
  std::printf("%-28s %14llu %12.3f %14.2f\n", "path tracer (NEE+MIS)", (unsigned long long)rays,
              trace_s, rays / trace_s / 1e6);
  std::printf("%-28s %14llu %12.3f %14.2f   (%llu hits)\n", "bare Embree intersect/occl.",
              (unsigned long long)(n_intersect + n_occluded), bare_s,
              (n_intersect + n_occluded) / bare_s / 1e6, (unsigned long long)hits);
  std::printf("path tracer / bare: %.0f %%\n\n",
              100.0 * (rays / trace_s) / ((n_intersect + n_occluded) / bare_s));

  // 3. Speed against error: RMS relative error of the image against a 16x-spp reference.
  RenderOptions ref_options = options;
  ref_options.spp = spp * 16;
  const RenderOutput reference = tracer.Render(view, ref_options, 2);
  std::printf("%-8s %12s %16s\n", "spp", "seconds", "RMS rel. error");
  for (int s = 1; s <= spp; s *= 4) {
    options.spp = s;
    const auto start = std::chrono::steady_clock::now();
    const RenderOutput img = tracer.Render(view, options, 3);
    const double t = Seconds(start);
    double sum = 0.0;
    size_t n = 0;
    for (size_t i = 0; i < img.radiance.size(); ++i) {
      const double r = reference.radiance.pixels()[i].mean();
      if (r <= 1e-4) continue;
      sum += std::pow((img.radiance.pixels()[i].mean() - r) / r, 2);
      ++n;
    }
    std::printf("%-8d %12.3f %16.4f\n", s, t, std::sqrt(sum / n));
  }
  return 0;
}
