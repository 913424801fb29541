// Images through core/image_io: the structure check, then OpenCV. Built twice: fuzz_png (colour,
// 8/16-bit, and 16-bit depth PNG) and, with GENSCENE_FUZZ_EXR, fuzz_exr (colour and depth OpenEXR).
#include "core/image_io.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    const ImageRgb rgb(5, 3, Eigen::Vector3f(0.2f, 0.5f, 0.9f));
    ImageDepth depth(4, 3, 1.25f);
#ifdef GENSCENE_FUZZ_EXR
    WriteExr(dir / "rgb.exr", rgb);
    WriteDepthExr(dir / "depth.exr", depth);
#else
    depth(1, 1) = 0.0f;
    WritePng(dir / "rgb.png", rgb);
    WriteDepthPng(dir / "depth.png", depth);
#endif
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
#ifdef GENSCENE_FUZZ_EXR
  const auto path = fuzz::Scratch("input.exr", data, size);
#else
  const auto path = fuzz::Scratch("input.png", data, size);
#endif
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadColorImage(path, CameraResponse()));
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadDepthImage(path));
  return 0;
}
