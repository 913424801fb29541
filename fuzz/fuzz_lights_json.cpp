// lights.json (the voxel light grid) through core/light_set.
#include "core/light_set.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    VoxelLightGrid grid;
    grid.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 2));
    grid.dims = Eigen::Vector3i(2, 1, 2);
    grid.intensity.assign(4, Eigen::Vector3f::Zero());
    grid.weights.assign(4, {1, 1, 1, 1, 1, 1});
    grid.intensity[3] = Eigen::Vector3f(2.0f, 1.0f, 0.5f);
    grid.weights[3] = {0.0f, 0.5f, 1.0f, 0.0f, 0.25f, 1.0f};
    WriteLightsJson(dir / "lights.json", grid, "{\"rounds\": 2}");
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("lights.json", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadLightsJson(path));
  return 0;
}
