// PNG (colour, 8/16-bit, and 16-bit depth) through core/image_io: the structure check, then OpenCV.
#include "core/image_io.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    ImageRgb rgb(5, 3, Eigen::Vector3f(0.2f, 0.5f, 0.9f));
    WritePng(dir / "rgb.png", rgb);
    ImageDepth depth(4, 3, 1.25f);
    depth(1, 1) = 0.0f;
    WriteDepthPng(dir / "depth.png", depth);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("input.png", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadColorImage(path, CameraResponse()));
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadDepthImage(path));
  return 0;
}
