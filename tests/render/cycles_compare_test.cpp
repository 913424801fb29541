// Our path tracer against Blender Cycles on ../shared/data/cbox-cycles:
// every view of the Cornell box and of both icosphere variants, full and direct-only, box filter
// and pixel-centre rays, from the set's own geometry, albedo, light and cameras. For every region
// (mesh) the mean must agree within 1 % per channel, and the per-pixel RMS relative difference
// over the brighter half of the pixels must be within 1.25x what the two images' noise predicts
// (Cycles' noise from the set's stats.json, ours from two seeds). Labelled "slow".
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "core/file_util.h"
#include "core/frame_source.h"
#include "render/formats/scene_io.h"
#include "render/path_tracer.h"
#include "render/render_compare.h"
#include "tests/test_util.h"

namespace genscene::render {
namespace {

struct CyclesCase {
  const char* scene_folder;  // relative to cbox-cycles/: the scene's geometry
  const char* views;         // the view set
  const char* noise_key;     // stats.json: noise.<key>.<view>
  int max_depth;             // Cycles max bounces 8 -> 10 segments; direct only (0 bounces) -> 2
  const char* filter;
};

std::string Name(const ::testing::TestParamInfo<CyclesCase>& info) {
  std::string name = info.param.views;
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

class CyclesComparison : public ::testing::TestWithParam<CyclesCase> {};

TEST_P(CyclesComparison, RegionMeansAndPixelNoiseAgree) {
  GS_REQUIRE_SHARED_DATA(data);
  const CyclesCase& c = GetParam();
  const auto root = data / "cbox-cycles";
  const Scene scene = LoadCyclesScene(root / c.scene_folder);
  std::vector<bool> emitters;
  for (const SceneMesh& m : scene.meshes) emitters.push_back(m.IsEmitter());
  const nlohmann::json stats =
      nlohmann::json::parse(ReadTextFile(root / c.scene_folder / "stats.json"));
  const PathTracer tracer(scene);
  RenderOptions options;
  options.spp = 256;
  options.max_depth = c.max_depth;
  options.filter = c.filter;

  auto source = OpenFrameSource((root / c.views).string(), SourceOptions());
  int index = 0;
  while (auto frame = source->Next()) {
    const std::string view_name = std::filesystem::path(frame->color_path).stem().string();
    SCOPED_TRACE(view_name);
    ASSERT_TRUE(frame->world_from_camera.has_value());
    const PosedView view{frame->intrinsics, *frame->world_from_camera, frame->timestamp};
    const RenderOutput a = tracer.Render(view, options, 1000 + 2 * index);
    const RenderOutput b = tracer.Render(view, options, 1001 + 2 * index);
    ++index;
    const ImageComparison cmp = CompareWithReference(a, b, frame->color, emitters);
    ASSERT_GE(cmp.regions.size(), 3u);
    // Regions left almost unlit (the ceiling under a downward light without bounces: Cycles
    // reads 0 to 7e-5 there, from pixels touching the light) are compared in absolute terms,
    // to 0.1 % of the brightest region.
    double brightest = 0.0;
    for (const RegionComparison& r : cmp.regions)
      brightest = std::max(brightest, r.mean_reference.maxCoeff());
    const double unlit = 1e-3 * brightest;
    for (const RegionComparison& r : cmp.regions) {
      for (int ch = 0; ch < 3; ++ch) {
        if (r.mean_reference[ch] < unlit) {
          EXPECT_NEAR(r.mean_ours[ch], r.mean_reference[ch], unlit)
              << "mesh " << scene.meshes[r.mesh].name;
          continue;
        }
        EXPECT_LE(r.RelativeBias()[ch], 0.01)
            << "mesh " << scene.meshes[r.mesh].name << " channel " << ch << ": ours "
            << r.mean_ours[ch] << " vs Cycles " << r.mean_reference[ch] << " over " << r.pixels
            << " pixels";
      }
    }
    const double cycles_noise =
        stats.at("noise").at(c.noise_key).at(view_name).at("brighter_half").at("rel_rms_lum");
    const double predicted = std::hypot(cmp.ours_relative_noise, cycles_noise);
    double worst = 0.0;
    for (const RegionComparison& r : cmp.regions) {
      for (int ch = 0; ch < 3; ++ch) {
        if (r.mean_reference[ch] >= unlit) worst = std::max(worst, r.RelativeBias()[ch]);
      }
    }
    std::printf(
        "[ cycles   ] %-30s %-9s regions %zu, worst bias %.3f%%, rms diff %.3f%% vs predicted "
        "%.3f%%\n",
        c.views, view_name.c_str(), cmp.regions.size(), 100 * worst,
        100 * cmp.rms_relative_difference, 100 * predicted);
    EXPECT_LE(cmp.rms_relative_difference, 1.25 * predicted)
        << "ours noise " << cmp.ours_relative_noise << ", Cycles noise " << cycles_noise
        << ", over " << cmp.pixels << " pixels";
  }
  EXPECT_GT(index, 0);
}

INSTANTIATE_TEST_SUITE_P(
    CboxCycles, CyclesComparison,
    ::testing::Values(
        CyclesCase{"", "views/train", "rgb", 10, "box"},
        CyclesCase{"", "views/novel", "rgb", 10, "box"},
        CyclesCase{"", "views/train_direct", "rgb_direct", 2, "box"},
        CyclesCase{"", "views/novel_direct", "rgb_direct", 2, "box"},
        CyclesCase{"", "views/train_center", "rgb_center", 10, "center"},
        CyclesCase{"", "views/novel_center", "rgb_center", 10, "center"},
        CyclesCase{"icosphere_flat", "icosphere_flat/views/full", "rgb", 10, "box"},
        CyclesCase{"icosphere_flat", "icosphere_flat/views/direct", "rgb_direct", 2, "box"},
        CyclesCase{"icosphere_smooth", "icosphere_smooth/views/full", "rgb", 10, "box"},
        CyclesCase{"icosphere_smooth", "icosphere_smooth/views/direct", "rgb_direct", 2, "box"}),
    Name);

}  // namespace
}  // namespace genscene::render
