// Render noise of a model against samples per pixel: each view rendered at a high reference spp,
// then at each spp of a list, for each light selection (power; unshadowed: by contribution without
// the visibility cache; contribution: with it); relative RMSE against the reference
// (sqrt(sum |a - ref|^2 / sum |ref|^2) over the views' pixels) and seconds. The scene is a
// workspace (its model and keyframe cameras) or a scene file with views. Run by hand:
//   build/bench/bench_render_noise --scene WS [--views 2] [--spp 16,64,256] [--ref-spp 4096]
// With --against FILE (for example the workspace's export/model.xml), the references of both
// scenes at the scene's cameras are compared instead: mean radiance and their relative difference.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "core/check.h"
#include "core/image_io.h"
#include "render/formats/workspace_scene.h"
#include "render/path_tracer.h"

using namespace genscene;
using namespace genscene::render;

namespace {

// Adds sum |a - ref|^2 to *err and sum |ref|^2 to *norm (the relative RMSE is sqrt(err / norm)).
void AddSquares(const ImageRgb& a, const ImageRgb& ref, double* err, double* norm) {
  for (size_t i = 0; i < a.size(); ++i) {
    *err += (a.data()[i] - ref.data()[i]).cast<double>().squaredNorm();
    *norm += ref.data()[i].cast<double>().squaredNorm();
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_render_noise: render noise of a model against samples per pixel"};
  std::string scene_path;
  int views = 2, ref_spp = 4096;
  std::vector<int> spps = {16, 64, 256};
  std::vector<std::string> selections = {"power", "unshadowed", "contribution"};
  bool hide_emitters = false;
  int max_depth = -1, light_samples = 1;
  std::string against, filter = "box", write_prefix;
  app.add_option("--filter", filter, "pixel filter: box, center or gaussian");
  app.add_option("--write", write_prefix,
                 "write PREFIX_ref_V.png and PREFIX_SELECTION_SPP_V.png (linear, clamped at 1)");
  app.add_option("--scene", scene_path, "workspace folder or scene file")->required();
  app.add_option("--against", against, "a second scene: compare the two references' means");
  std::string against_selection;
  app.add_option("--against-selection", against_selection,
                 "light selection of the second scene's renders (default: the same)");
  app.add_option("--views", views, "views rendered (the scene's first ones)");
  app.add_option("--spp", spps, "samples per pixel to measure")->delimiter(',');
  app.add_option("--ref-spp", ref_spp, "samples per pixel of the reference");
  app.add_option("--selections", selections,
                 "light selections: power, unshadowed (contribution without the visibility "
                 "cache) or contribution")
      ->delimiter(',');
  app.add_option("--light-samples", light_samples, "lights sampled per path vertex");
  int exact_lights = RenderOptions().exact_lights;
  app.add_option("--exact-lights", exact_lights,
                 "lights of the largest contributions taken exactly at the first vertex");
  app.add_option("--max-depth", max_depth, "longest path (segments; -1 = unlimited)");
  app.add_flag("--hide-emitters", hide_emitters, "camera rays that hit an emitter return black");
  CLI11_PARSE(app, argc, argv);
  try {
    const LoadedScene loaded = LoadSceneOrWorkspace(scene_path);
    GS_CHECK(!loaded.views.empty());
    const PathTracer tracer(loaded.scene);
    RenderOptions options;
    options.max_depth = max_depth;
    options.light_samples = light_samples;
    options.filter = filter;
    options.exact_lights = exact_lights;
    options.hide_emitters = hide_emitters || loaded.settings.hide_emitters.value_or(false);
    const int n = std::min<int>(views, static_cast<int>(loaded.views.size()));
    std::vector<ImageRgb> reference;
    const auto start = std::chrono::steady_clock::now();
    options.spp = ref_spp;
    for (int v = 0; v < n; ++v)
      reference.push_back(tracer.Render(loaded.views[v], options, 99).radiance);
    // Written images are scaled so that every reference's mean is 0.25.
    std::vector<float> scale(n, 1.0f);
    for (int v = 0; v < n; ++v) {
      double mean = 0.0;
      for (size_t i = 0; i < reference[v].size(); ++i)
        mean += reference[v].data()[i].cast<double>().mean() / reference[v].size();
      if (mean > 0.0) scale[v] = static_cast<float>(0.25 / mean);
    }
    auto write = [&](const std::string& path, ImageRgb image, int v) {
      for (size_t i = 0; i < image.size(); ++i) image.data()[i] *= scale[v];
      WritePng(path, image);
    };
    if (!write_prefix.empty()) {
      for (int v = 0; v < n; ++v)
        write(write_prefix + "_ref_" + std::to_string(v) + ".png", reference[v], v);
    }
    std::printf("reference: %d views at %d spp (%s), %.1f s\n\n", n, ref_spp,
                options.light_selection.c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    if (!against.empty()) {
      const LoadedScene other = LoadSceneOrWorkspace(against);
      const PathTracer other_tracer(other.scene);
      RenderOptions o = options;
      o.hide_emitters = hide_emitters || other.settings.hide_emitters.value_or(false);
      if (!against_selection.empty()) o.light_selection = against_selection;
      std::printf("| view | mean %s | mean %s | difference |\n|---:|---:|---:|---:|\n",
                  scene_path.c_str(), against.c_str());
      for (int v = 0; v < n; ++v) {
        const ImageRgb b = other_tracer.Render(loaded.views[v], o, 99).radiance;
        double ma = 0.0, mb = 0.0;
        for (size_t i = 0; i < b.size(); ++i) {
          ma += reference[v].data()[i].cast<double>().mean() / b.size();
          mb += b.data()[i].cast<double>().mean() / b.size();
        }
        std::printf("| %d | %.5f | %.5f | %+.2f %% |\n", v, ma, mb, 100.0 * (mb / ma - 1.0));
      }
      return 0;
    }
    std::printf("| light selection | spp | seconds | relative RMSE |\n|---|---:|---:|---:|\n");
    for (const std::string& selection : selections) {
      options.light_selection = selection == "unshadowed" ? "contribution" : selection;
      options.light_visibility = selection != "unshadowed";
      for (int spp : spps) {
        options.spp = spp;
        double err = 0.0, norm = 0.0;
        const auto t0 = std::chrono::steady_clock::now();
        for (int v = 0; v < n; ++v) {
          const ImageRgb image = tracer.Render(loaded.views[v], options, 7 + v).radiance;
          AddSquares(image, reference[v], &err, &norm);
          if (!write_prefix.empty()) {
            write(write_prefix + "_" + selection + "_" + std::to_string(spp) + "_" +
                      std::to_string(v) + ".png",
                  image, v);
          }
        }
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const double rmse = norm > 0.0 ? std::sqrt(err / norm) : 0.0;
        std::printf("| %s | %d | %.2f | %.4f |\n", selection.c_str(), spp, s, rmse);
        std::fflush(stdout);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_render_noise: %s\n", e.what());
    return 1;
  }
  return 0;
}
