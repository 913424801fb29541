// OpenNI .oni recordings through capture/oni_format (our reader of the uncompressed container).
#include "capture/oni_format.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;
using namespace genscene::capture;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) {
    for (const bool color : {true, false}) {
      OniLayout layout;
      layout.width = 4;
      layout.height = 3;
      layout.with_color = color;
      layout.intrinsics.fx = layout.intrinsics.fy = 4.0;
      layout.intrinsics.cx = 1.5;
      layout.intrinsics.cy = 1.0;
      layout.intrinsics.width = 4;
      layout.intrinsics.height = 3;
      std::vector<OniRawFrame> frames(2);
      for (size_t i = 0; i < frames.size(); ++i) {
        frames[i].timestamp_us = 33333 * i;
        frames[i].depth_mm.assign(12, static_cast<uint16_t>(1000 + i));
        if (color) frames[i].color_rgb.assign(36, static_cast<uint8_t>(40 * i));
      }
      WriteOniFile(dir / (color ? "rgbd.oni" : "depth.oni"), layout, frames);
    }
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch("input.oni", data, size);
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadOniFile(path));
  return 0;
}
