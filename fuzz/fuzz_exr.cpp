// OpenEXR (colour and depth) through core/image_io: the structure check, then OpenCV.
#include "core/image_io.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    WriteExr(dir / "rgb.exr", ImageRgb(5, 3, Eigen::Vector3f(0.2f, 0.5f, 0.9f)));
    WriteDepthExr(dir / "depth.exr", ImageDepth(4, 3, 1.25f));
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("input.exr", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadColorImage(path, CameraResponse()));
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadDepthImage(path));
  return 0;
}
