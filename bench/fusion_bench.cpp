// Fusion speed against error: frames per second of tracking + fusion, and of integration alone,
// on TUM-layout folders with ground truth (e.g. made by genscene-synth at 320x240 and 640x480),
// with the ATE of each run. Usage: bench_fusion FOLDER [FOLDER ...] [--threads N]
#include <chrono>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "core/frame_source.h"
#include "core/parallel.h"
#include "core/trajectory_metrics.h"
#include "fusion/kinect_fusion.h"

using namespace genscene;

namespace {

constexpr const char* kUsage =
    "usage: bench_fusion FOLDER [FOLDER ...] [--threads N] [--model-subsample N] "
    "[--allocation-stride N]"
    " [--weighting noise|uniform]\n";

int Run(int argc, char** argv) {
  std::vector<std::string> folders;
  int threads = 0;
  int model_subsample = fusion::FusionOptions().model_subsample;
  int allocation_stride = fusion::FusionOptions().allocation_stride;
  std::string weighting = fusion::FusionOptions().weighting;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::printf(
          "%s"
          "  FOLDER: a TUM-layout sequence with groundtruth.txt (e.g. from genscene-synth)\n"
          "  prints per-frame times of each step, fps, ATE, and integration alone (known poses)\n",
          kUsage);
      return 0;
    }
    if (std::strcmp(argv[i], "--model-subsample") == 0 && i + 1 < argc) {
      model_subsample = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--weighting") == 0 && i + 1 < argc) {
      weighting = argv[++i];
    } else if (std::strcmp(argv[i], "--allocation-stride") == 0 && i + 1 < argc) {
      allocation_stride = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--threads") == 0 && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else {
      folders.push_back(argv[i]);
    }
  }
  if (folders.empty()) {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  SetThreadCount(threads);
  std::printf(
      "threads %d, model raycast at 1/%d resolution, allocation stride %d (0 = width / 160), %s "
      "weights\n",
      ThreadCount(), model_subsample, allocation_stride, weighting.c_str());
  std::printf("%-28s %9s %7s | %8s %8s %8s %8s %8s | %9s | %8s %9s\n", "sequence", "size", "frames",
              "prep ms", "track ms", "integ ms", "ray ms", "fps", "ATE cm", "integ fps", "blocks");
  for (const std::string& folder : folders) {
    auto source = OpenFrameSource(folder, SourceOptions());
    const std::vector<RgbdFrame> frames = ReadAllFrames(*source);  // decoding is not timed
    double totals[2][4] = {};
    double ate = 0.0;
    size_t blocks = 0;
    for (int mode = 0; mode < 2; ++mode) {
      fusion::FusionOptions options;
      options.tracking = mode == 0 ? "icp" : "known";
      options.model_subsample = model_subsample;
      options.allocation_stride = allocation_stride;
      options.weighting = weighting;
      options.Validate();
      fusion::KinectFusion kf(options, source->Intrinsics());
      for (const RgbdFrame& f : frames) {
        const fusion::FrameReport r = kf.ProcessFrame(f);
        totals[mode][0] += r.seconds_preprocess;
        totals[mode][1] += r.seconds_track;
        totals[mode][2] += r.seconds_integrate;
        totals[mode][3] += r.seconds_raycast;
      }
      if (mode == 0) {
        ate = ComputeAte(kf.trajectory(), source->KnownPoses()).rmse;
        blocks = kf.volume().num_blocks();
      }
    }
    const double n = static_cast<double>(frames.size());
    const double per_frame = (totals[0][0] + totals[0][1] + totals[0][2] + totals[0][3]) / n;
    char size[32];
    std::snprintf(size, sizeof(size), "%dx%d", source->Intrinsics().width,
                  source->Intrinsics().height);
    std::printf("%-28s %9s %7zu | %8.2f %8.2f %8.2f %8.2f %8.1f | %9.3f | %8.1f %9zu\n",
                folder.substr(folder.size() > 28 ? folder.size() - 28 : 0).c_str(), size,
                frames.size(), 1e3 * totals[0][0] / n, 1e3 * totals[0][1] / n,
                1e3 * totals[0][2] / n, 1e3 * totals[0][3] / n, 1.0 / per_frame, 100.0 * ate,
                n / totals[1][2], blocks);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_fusion: error: %s\n", e.what());
    return 1;
  }
}
