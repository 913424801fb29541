// Our path tracer against Blender Cycles on ../shared/data/cbox-cycles: prints, per view, the
// worst region bias and the per-pixel RMS relative difference against the noise both images
// predict, with the render time; writes ours, Cycles' and the relative difference as EXR.
//   build/bench/bench_cycles_compare [shared_data_dir] [out_dir] [spp]
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "core/frame_source.h"
#include "core/image_io.h"
#include "render/formats/scene_io.h"
#include "render/path_tracer.h"
#include "render/render_compare.h"

using namespace genscene;
using namespace genscene::render;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  CLI::App app{
      "bench_cycles_compare: our path tracer against Blender Cycles' renders of "
      "DATA/cbox-cycles (region bias, RMS relative difference against the predicted noise, "
      "seconds per view; EXR images of ours, Cycles' and their relative difference in OUT)"};
  std::string data_dir = "../shared/data", out_dir = "cycles_compare";
  int spp = 256;
  app.add_option("data", data_dir, "shared data folder holding cbox-cycles/");
  app.add_option("out", out_dir, "folder for the EXR images");
  app.add_option("spp", spp, "samples per pixel of each of our two renders per view")
      ->check(CLI::Range(1, 1 << 20));
  CLI11_PARSE(app, argc, argv);
  const fs::path data = data_dir, out = out_dir;
  try {
    fs::create_directories(out);
    struct Case {
      const char *scene, *views, *noise;
      int max_depth;
      const char* filter;
    };
    const Case cases[] = {
        {"", "views/train", "rgb", 10, "box"},
        {"", "views/novel", "rgb", 10, "box"},
        {"", "views/train_direct", "rgb_direct", 2, "box"},
        {"", "views/novel_direct", "rgb_direct", 2, "box"},
        {"", "views/train_center", "rgb_center", 10, "center"},
        {"", "views/novel_center", "rgb_center", 10, "center"},
        {"icosphere_flat", "icosphere_flat/views/full", "rgb", 10, "box"},
        {"icosphere_flat", "icosphere_flat/views/direct", "rgb_direct", 2, "box"},
        {"icosphere_smooth", "icosphere_smooth/views/full", "rgb", 10, "box"},
        {"icosphere_smooth", "icosphere_smooth/views/direct", "rgb_direct", 2, "box"}};
    const fs::path root = data / "cbox-cycles";
    std::printf("%-34s %-10s %8s %12s %12s %12s %9s\n", "views", "view", "regions", "worst bias",
                "rms diff", "predicted", "seconds");
    for (const Case& c : cases) {
      const Scene scene = LoadCyclesScene(root / c.scene);
      std::vector<bool> emitters;
      for (const SceneMesh& m : scene.meshes) emitters.push_back(m.IsEmitter());
      const auto stats = nlohmann::json::parse(ReadTextFile(root / c.scene / "stats.json"));
      const PathTracer tracer(scene);
      RenderOptions options;
      options.spp = spp;
      options.max_depth = c.max_depth;
      options.filter = c.filter;
      auto source = OpenFrameSource((root / c.views).string(), SourceOptions());
      int index = 0;
      while (auto frame = source->Next()) {
        const std::string name = fs::path(frame->color_path).stem().string();
        const PosedView view{frame->intrinsics, *frame->world_from_camera, frame->timestamp};
        const auto start = std::chrono::steady_clock::now();
        const RenderOutput a = tracer.Render(view, options, 1000 + 2 * index);
        const RenderOutput b = tracer.Render(view, options, 1001 + 2 * index);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        ++index;
        const ImageComparison cmp = CompareWithReference(a, b, frame->color, emitters);
        double worst = 0.0;
        for (const auto& r : cmp.regions) {
          for (int ch = 0; ch < 3; ++ch) {
            if (r.mean_reference[ch] > 1e-3) worst = std::max(worst, r.RelativeBias()[ch]);
          }
        }
        const double cycles_noise = stats["noise"][c.noise][name]["brighter_half"]["rel_rms_lum"];
        std::printf("%-34s %-10s %8zu %11.3f%% %11.3f%% %11.3f%% %9.1f\n", c.views, name.c_str(),
                    cmp.regions.size(), 100 * worst, 100 * cmp.rms_relative_difference,
                    100 * std::hypot(cmp.ours_relative_noise, cycles_noise), seconds);
        // Images: ours (mean of both seeds), Cycles, and (ours - Cycles) / Cycles.
        ImageRgb ours(a.radiance.width(), a.radiance.height()), diff = ours;
        for (size_t i = 0; i < ours.size(); ++i) {
          ours.pixels()[i] = 0.5f * (a.radiance.pixels()[i] + b.radiance.pixels()[i]);
          const Eigen::Vector3f ref = frame->color.pixels()[i];
          for (int ch = 0; ch < 3; ++ch)
            diff.pixels()[i][ch] = ref[ch] > 0 ? (ours.pixels()[i][ch] - ref[ch]) / ref[ch] : 0.0f;
        }
        std::string tag = c.views;
        for (char& ch : tag) ch = ch == '/' ? '_' : ch;
        WriteExr(out / (tag + "_" + name + "_ours.exr"), ours);
        WriteExr(out / (tag + "_" + name + "_cycles.exr"), frame->color);
        WriteExr(out / (tag + "_" + name + "_reldiff.exr"), diff);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_cycles_compare: %s\n", e.what());
    return 1;
  }
  return 0;
}
