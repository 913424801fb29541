// I/O throughput of the readers: frames per second for each sequence format, against the depth
// error of the 16-bit encoding (max |decoded - exact| over valid pixels). Run by hand:
//   build/bench/bench_io [frames] [size]
// It prints a table; nothing is timed in the tests.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/frame_source.h"
#include "core/sequence_writer.h"
#include "core/synthetic.h"

int main(int argc, char** argv) {
  using namespace genscene;
  const int frames = argc > 1 ? std::atoi(argv[1]) : 20;
  const int width = argc > 2 ? std::atoi(argv[2]) : 320;
  const int height = width * 3 / 4;
  const SyntheticScene scene = MakeCornellScene();
  const CameraIntrinsics k = CameraIntrinsics::Centered(width, height, 0.8 * width);
  std::vector<RgbdFrame> exact;
  const Trajectory orbit = MakeOrbitTrajectory({0, 0, 0.6}, 0.9, 1.0, 60.0, frames);
  for (const auto& p : orbit.poses())
    exact.push_back(RenderSyntheticFrame(scene, k, p.world_from_camera, p.timestamp));
  const auto dir = std::filesystem::temp_directory_path() / "genscene-bench-io";
  std::filesystem::remove_all(dir);

  std::printf("%-22s %10s %12s %16s\n", "format", "frames", "frames/s", "max depth err m");
  for (double scale : {1000.0, 5000.0}) {
    TumWriteOptions write;
    write.depth_scale = scale;
    auto t0 = std::chrono::steady_clock::now();
    WriteTumSequence(dir, exact, write);
    const double write_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    SourceOptions options;
    options.depth_scale = scale;
    t0 = std::chrono::steady_clock::now();
    auto source = OpenFrameSource(dir.string(), options);
    double max_error = 0.0;
    size_t i = 0;
    while (auto f = source->Next()) {
      for (size_t p = 0; p < f->depth.size(); ++p) {
        max_error = std::max(max_error,
                             std::abs(double(f->depth.pixels()[p]) - exact[i].depth.pixels()[p]));
      }
      ++i;
    }
    const double read_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("%-22s %10zu %12.1f %16.2e\n",
                ("TUM write, scale " + std::to_string(int(scale))).c_str(), exact.size(),
                exact.size() / write_s, 0.0);
    std::printf("%-22s %10zu %12.1f %16.2e\n",
                ("TUM read, scale " + std::to_string(int(scale))).c_str(), i, i / read_s,
                max_error);
  }
  std::filesystem::remove_all(dir);
  return 0;
}
