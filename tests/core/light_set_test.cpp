// lights.json (core/light_set.h): round trip, checked reading, the voxel model's figures.
#include "core/light_set.h"

#include <gtest/gtest.h>

#include <fstream>
#include <limits>

#include "core/check.h"
#include "core/color.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

VoxelLightGrid SmallGrid() {
  VoxelLightGrid g;
  g.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 2));
  g.dims = Eigen::Vector3i(2, 3, 4);
  g.intensity.assign(24, Eigen::Vector3f::Zero());
  g.weights.assign(24, {1, 1, 1, 1, 1, 1});
  g.intensity[5] = Eigen::Vector3f(0.725f, 1.5f, 3.0f);
  g.weights[5] = {0.1f, 0.0f, 0.25f, 1.0f, 0.5f, 0.75f};
  g.intensity[17] = Eigen::Vector3f(0.01f, 0.02f, 0.03f);
  g.cube_size = 0.02;
  g.softening = 0.035;
  return g;
}

TEST(LightSet, LightsJsonRoundTrips) {
  test::TempDir dir;
  const VoxelLightGrid g = SmallGrid();
  WriteLightsJson(dir / "lights.json", g, R"({"note": "test"})");
  const VoxelLightGrid back = ReadLightsJson(dir / "lights.json");
  EXPECT_EQ(back.dims, g.dims);
  EXPECT_EQ(back.bounds.min(), g.bounds.min());
  EXPECT_EQ(back.bounds.max(), g.bounds.max());
  EXPECT_EQ(back.cube_size, g.cube_size);
  EXPECT_EQ(back.softening, g.softening);
  EXPECT_EQ(back.intensity, g.intensity);
  EXPECT_EQ(back.weights, g.weights);
  EXPECT_FALSE(back.distant);
  EXPECT_EQ(back.LightCount(), back.VoxelCount());

  // With the distant light: light VoxelCount(), written and read back.
  VoxelLightGrid d = g;
  d.distant = true;
  d.distant_intensity = Eigen::Vector3f(0.5f, 0.25f, 2.0f);
  d.distant_weights = {0.0f, 0.1f, 0.2f, 0.3f, 1.0f, 0.5f};
  WriteLightsJson(dir / "distant.json", d);
  const VoxelLightGrid read = ReadLightsJson(dir / "distant.json");
  ASSERT_TRUE(read.distant);
  EXPECT_EQ(read.distant_intensity, d.distant_intensity);
  EXPECT_EQ(read.distant_weights, d.distant_weights);
  EXPECT_EQ(read.LightCount(), 25);
  EXPECT_EQ(read.IntensityOf(24), d.distant_intensity);
  EXPECT_EQ(read.IntensityOf(5), d.intensity[5]);
  EXPECT_EQ(read.WeightsOf(24), d.distant_weights);
}

// E(w) = L_d sum_k lambda_dk max(0, w . d_k): the lobes of the faces w points along, zero
// without a distant light.
TEST(LightSet, DistantRadianceIsTheLobesAlongTheDirection) {
  VoxelLightGrid g = SmallGrid();
  const Eigen::Vector3f up(0, 0, 1), slant = Eigen::Vector3f(0.6f, -0.8f, 0.0f);
  EXPECT_EQ(g.DistantRadiance(up), Eigen::Vector3f::Zero());
  g.distant = true;
  g.distant_intensity = Eigen::Vector3f(1.0f, 2.0f, 4.0f);
  g.distant_weights = {0.5f, 0.1f, 0.2f, 0.25f, 1.0f, 0.0f};
  EXPECT_TRUE((g.DistantRadiance(up) - g.distant_intensity).norm() < 1e-6f);
  EXPECT_TRUE((g.DistantRadiance(-up)).norm() < 1e-6f);
  const float lobes = 0.5f * 0.6f + 0.25f * 0.8f;
  EXPECT_TRUE((g.DistantRadiance(slant) - lobes * g.distant_intensity).norm() < 1e-5f);
  EXPECT_TRUE(g.HasDistantLight());
  g.distant_intensity.setZero();
  EXPECT_FALSE(g.HasDistantLight());
}

// The falloff 1 / (d^2 + e^2): a point's 1 / d^2 far away, bounded by 1 / e^2 at the centre; a
// negative or infinite softening is an error.
TEST(LightSet, SofteningBoundsTheFalloff) {
  VoxelLightGrid g = SmallGrid();
  EXPECT_FLOAT_EQ(g.Falloff(0.0f), 1.0f / (0.035f * 0.035f));
  EXPECT_NEAR(g.Falloff(100.0f) * 100.0f, 1.0, 2e-5);
  g.softening = 0.0;
  EXPECT_FLOAT_EQ(g.Falloff(0.25f), 4.0f);
  for (double bad : {-0.01, std::numeric_limits<double>::infinity()}) {
    g.softening = bad;
    EXPECT_THROW(g.Validate(), Error) << bad;
  }
}

TEST(LightSet, PowerAndActiveVoxels) {
  const VoxelLightGrid g = SmallGrid();
  // pi * L * sum(lambda) = pi * L * 2.6.
  EXPECT_NEAR(g.Power(5).x(), M_PI * 0.725 * 2.6, 1e-5);
  EXPECT_EQ(g.ActiveVoxels(0.0), (std::vector<int>{5, 17}));
  EXPECT_EQ(g.ActiveVoxels(), (std::vector<int>{5, 17}));  // 17 holds 1 % of 5's power: above 1e-3
  EXPECT_EQ(g.ActiveVoxels(0.5), (std::vector<int>{5}));
}

TEST(LightSet, PowerCentroidWeighsVoxelCentresByPowerLuminance) {
  VoxelLightGrid g = SmallGrid();
  const double p5 = Luminance(g.Power(5)), p17 = Luminance(g.Power(17));
  EXPECT_NEAR(g.TotalPowerLuminance(), p5 + p17, 1e-9);
  const Eigen::Vector3d expected = (p5 * g.VoxelCenter(5) + p17 * g.VoxelCenter(17)) / (p5 + p17);
  EXPECT_LT((g.PowerCentroid() - expected).norm(), 1e-12);
  g.intensity[17] = g.intensity[5];
  g.weights[17] = g.weights[5];
  EXPECT_LT((g.PowerCentroid() - 0.5 * (g.VoxelCenter(5) + g.VoxelCenter(17))).norm(), 1e-12);
  g.intensity.assign(24, Eigen::Vector3f::Zero());
  EXPECT_EQ(g.TotalPowerLuminance(), 0.0);
  EXPECT_TRUE(g.PowerCentroid().array().isNaN().all());
}

TEST(LightSet, BadDistantLightIsAnError) {
  VoxelLightGrid g = SmallGrid();
  g.distant = true;
  g.distant_intensity = Eigen::Vector3f(1.0f, -1.0f, 0.0f);
  EXPECT_CONTAINS(test::ErrorOf([&] { g.Validate(); }), "the distant light has intensity");
  g.distant_intensity = Eigen::Vector3f::Ones();
  g.distant_weights[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_CONTAINS(test::ErrorOf([&] { g.Validate(); }), "the distant light has a directional");
}

TEST(LightSet, BadLightsJsonIsAnErrorNamingTheFile) {
  test::TempDir dir;
  const auto expect_error = [&](const std::string& text, const std::string& part) {
    std::ofstream(dir / "lights.json") << text;
    try {
      ReadLightsJson(dir / "lights.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("lights.json"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_error("{", "malformed JSON");
  expect_error(R"({"genscene_lights": 2, "voxel_lights": {}})", "not a genscene lights file");
  expect_error(R"({"genscene_lights": 1, "surprise": 1})", "unknown key 'surprise'");
  expect_error(R"({"genscene_lights": 1})", "missing \"voxel_lights\"");
  expect_error(
      R"({"genscene_lights": 1, "voxel_lights": {"bounds_min": [0,0,0], "bounds_max": [1,1,1],
      "dims": [1,1,1], "intensity": [[-1, 0, 0]], "weights": [[1,1,1,1,1,1]]}})",
      "must be finite and >= 0");
  expect_error(
      R"({"genscene_lights": 1, "voxel_lights": {"bounds_min": [0,0,0], "bounds_max": [1,1,1],
      "dims": [2,1,1], "intensity": [[1, 0, 0]], "weights": [[1,1,1,1,1,1]]}})",
      "1 intensities and 1 weight sets for 2 voxels");
  expect_error(
      R"({"genscene_lights": 1, "voxel_lights": {"bounds_min": [0,0,0], "bounds_max": [1,1,1],
      "dims": [1,1,1], "intensity": [[1, 0, 0]], "weights": [[1,1,1,1,1,1]],
      "distant": {"intensity": [1, 1, 1]}}})",
      "distant: missing \"weights\"");
  expect_error(
      R"({"genscene_lights": 1, "voxel_lights": {"bounds_min": [0,0,0], "bounds_max": [1,1,1],
      "dims": [1,1,1], "intensity": [[1, 0, 0]], "weights": [[1,1,1,1,1,1]],
      "distant": {"intensity": [1, 1, 1], "weights": [1,1,1,1,1,1], "sky": 1}}})",
      "unknown key 'sky'");
  EXPECT_THROW(ReadLightsJson(dir / "missing.json"), Error);
}

}  // namespace
}  // namespace genscene
