// Light estimation on images from another renderer: voxel lights estimated
// from the three Cycles training views of ../shared/data/cbox-cycles, with the library's default
// options, must sit under the true ceiling light and predict the two novel views.
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "core/frame_source.h"
#include "inverse/lights/light_estimation.h"
#include "render/formats/scene_io.h"
#include "render/path_tracer.h"
#include "tests/test_util.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on
namespace {

TEST(LightEstimationCycles, ActiveVoxelsConcentrateUnderTheTrueLight) {
  GS_REQUIRE_SHARED_DATA(data);
  const auto root = data / "cbox-cycles";
  const Scene scene = LoadCyclesScene(root);
  // The true light: the centre of the emitting meshes' bounding box (Cycles' ceiling quad).
  Eigen::AlignedBox3d light;
  for (const SceneMesh& m : scene.meshes) {
    if (!m.IsEmitter()) continue;
    for (const Eigen::Vector3f& v : m.mesh.vertices) light.extend(v.cast<double>());
  }
  ASSERT_FALSE(light.isEmpty()) << "the Cycles scene has no emitter";
  const std::vector<PosedImage> train = ReadPosedImages(root / "views" / "train");
  const std::vector<PosedImage> novel = ReadPosedImages(root / "views" / "novel");
  ASSERT_EQ(train.size(), 3u);
  ASSERT_EQ(novel.size(), 2u);

  const LightEstimationOptions
      options;  // 7^3 voxels refined once, 3000 pixels per view, penalty 1e-3
  const LightEstimate e = EstimateLights(scene, train, options, 7);
  ASSERT_GT(e.active_voxels, 0);

  ASSERT_GT(e.lights.TotalPowerLuminance(), 0.0);
  const Eigen::Vector3d centroid = e.lights.PowerCentroid();
  const double spacing = (e.lights.VoxelCenter(1) - e.lights.VoxelCenter(0)).norm();
  const double distance = (centroid - light.center()).norm();
  EXPECT_LT(distance, spacing) << "power-weighted centroid (" << centroid.transpose()
                               << ") vs light centre (" << light.center().transpose() << ")";

  // Novel views: relative RMSE of the expected images (render noise and Cycles' 0.0028 RMS noise
  // taken out), against the acceptance's goal of 0.05. With adaptive refinement (the default) the
  // lights are a 14^3 grid, so `spacing` above is a finer voxel: half the goal's distance.
  Scene lit = WithoutLights(scene);
  lit.voxel_lights = e.lights;
  const PathTracer lit_tracer(lit);
  double error = 0.0;
  for (const PosedImage& v : novel)
    error += CompareRender(lit_tracer, v, options, 256, 5, 0.0028).rmse_bias / 2.0;
  std::printf(
      "Cycles box: %d active voxels, centroid %.3f voxel from the light, novel relative RMSE "
      "%.4f\n",
      e.active_voxels, distance / spacing, error);
  EXPECT_LT(error, 0.05);
}

}  // namespace
}  // namespace genscene::inverse
