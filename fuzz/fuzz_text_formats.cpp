// The text formats, chosen by the input's first byte (mod 6); the rest is the file:
//   0 TUM trajectory, 1 Redwood .log, 2 intrinsics (one line), 3 intrinsics (Open3D JSON),
//   4 a view set's rgb.txt (next to a fixed intrinsics.txt and groundtruth.txt),
//   5 a TUM folder's depth.txt (next to a fixed rgb.txt), opened as a frame source.
#include <string>

#include "core/camera.h"
#include "core/file_util.h"
#include "core/frame_source.h"
#include "core/trajectory.h"
#include "core/view_set.h"
#include "fuzz/fuzz_util.h"

using namespace genscene;
namespace fs = std::filesystem;

namespace {

constexpr const char* kTrajectory = "1.0 0 0 0 0 0 0 1\n2.5 0.1 0.2 0.3 0 0 0.7071068 0.7071068\n";
constexpr const char* kLog =
    "0 0 2\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n1 1 2\n1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
constexpr const char* kIntrinsics = "525 525 319.5 239.5 640 480\n";
constexpr const char* kOpen3d =
    "{\"width\": 640, \"height\": 480, \"intrinsic_matrix\": [525, 0, 0, 0, 525, 0, 319.5, 239.5, "
    "1]}";
constexpr const char* kRgbList = "# colour\n1.0 rgb/1.png\n2.5 rgb/2.png\n";
constexpr const char* kDepthList = "# depth\n1.01 depth/1.png\n2.49 depth/2.png\n";

void WriteSeed(const fs::path& path, char kind, const std::string& text) {
  WriteTextFileAtomically(path, std::string(1, kind) + text);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const fs::path& dir) {
    WriteSeed(dir / "tum_trajectory", 0, kTrajectory);
    WriteSeed(dir / "redwood_log", 1, kLog);
    WriteSeed(dir / "intrinsics_line", 2, kIntrinsics);
    WriteSeed(dir / "intrinsics_open3d", 3, kOpen3d);
    WriteSeed(dir / "view_set_rgb", 4, kRgbList);
    WriteSeed(dir / "tum_depth_list", 5, kDepthList);
  });
  const fs::path views = fuzz::ScratchDir() / "views";
  fs::create_directories(views);
  WriteTextFileAtomically(views / "intrinsics.txt", kIntrinsics);
  WriteTextFileAtomically(views / "groundtruth.txt", kTrajectory);
  const fs::path tum = fuzz::ScratchDir() / "tum";
  fs::create_directories(tum);
  WriteTextFileAtomically(tum / "rgb.txt", kRgbList);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const int kind = data[0] % 6;
  ++data;
  --size;
  switch (kind) {
    case 0:
      GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadTumTrajectory(fuzz::Scratch("trajectory.txt", data, size)));
      break;
    case 1:
      GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadRedwoodLog(fuzz::Scratch("trajectory.log", data, size)));
      break;
    case 2:
      GENSCENE_FUZZ_EXPECT_ERROR_OK(
          ReadIntrinsicsFile(fuzz::Scratch("intrinsics.txt", data, size)));
      break;
    case 3:
      GENSCENE_FUZZ_EXPECT_ERROR_OK(
          ReadIntrinsicsFile(fuzz::Scratch("intrinsics.json", data, size)));
      break;
    case 4:
      fuzz::Scratch("views/rgb.txt", data, size);
      GENSCENE_FUZZ_EXPECT_ERROR_OK(ReadViewSet(fuzz::ScratchDir() / "views"));
      break;
    default: {
      fuzz::Scratch("tum/depth.txt", data, size);
      SourceOptions options;
      options.intrinsics = "tum1";
      GENSCENE_FUZZ_EXPECT_ERROR_OK(
          OpenFrameSource((fuzz::ScratchDir() / "tum").string(), options));
    }
  }
  return 0;
}
