// The sparse TSDF volume file (fusion's output) through core/tsdf_volume, under a 64 MB cap.
#include "core/tsdf_volume.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    TsdfVolumeParams params;
    params.voxel_size = 0.02;
    TsdfVolume volume(params);
    const int32_t a = volume.AllocateBlock(Eigen::Vector3i(0, 0, 0));
    volume.AllocateBlock(Eigen::Vector3i(-1, 2, 0));
    (void)a;
    WriteTsdfVolume(dir / "two_blocks.tsdf", volume);
    WriteTsdfVolume(dir / "empty.tsdf", TsdfVolume(params));
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("input.tsdf", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadTsdfVolume(path, 64e6));
  return 0;
}
