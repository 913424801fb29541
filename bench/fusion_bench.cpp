// Fusion speed against error: frames per second of tracking + fusion, and of integration alone,
// on TUM-layout folders with ground truth (e.g. made by genscene-synth at 320x240 and 640x480),
// with the ATE of each run. Usage: bench_fusion FOLDER [FOLDER ...] [--threads N]
//
// Then the per-frame cost against the size of the volume: the model raycast of every tracked
// frame, timed on the volume the run built and on that volume with `--copies` translated copies
// of all its blocks beside it (out of every frustum, as the rest of a room scanned before is):
// only the blocks of chunks in the frustum are visited, so the two times should agree.
//
// --scale N: a long scan instead of folders: N frames of the analytic living room of
// core/synthetic.h (5 x 4 x 2.6 m, its surfaces tiled with random brightness of --texture m,
// default 0.15, 0 = plain; exact depth bent by --depth-bias K (AddRadialDepthBias, default 0),
// then Kinect-v1 noise, AddKinectDepthNoise), --width pixels wide (default 640, 4:3), the camera
// walking a circle of --radius m (default 0.4) looking out at the walls, one turn every
// --per-turn frames (default 400, 0.9 degrees a frame; MakeRoomLoopTrajectory), rendered one at
// a time (untimed) and tracked and fused with the defaults (--no-loop-closure: without loop
// closure; --color-weight W: icp_color_weight; --trajectory PREFIX: PREFIX_estimate.txt and
// PREFIX_truth.txt, TUM format, both in the first kept camera's frame); a line for each loop
// closed; every 100 frames a row of fps over those frames, blocks, the volume's megabytes, the
// process's peak memory, the ATE so far and the drift (the last pose against the truth, both
// relative to the first).
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/frame_source.h"
#include "core/parallel.h"
#include "core/se3.h"
#include "core/synthetic.h"
#include "core/trajectory_metrics.h"
#include "fusion/kinect_fusion.h"

using namespace genscene;

namespace {

constexpr const char* kUsage =
    "usage: bench_fusion FOLDER [FOLDER ...] [--threads N] [--model-subsample N] "
    "[--allocation-stride N]"
    " [--weighting noise|uniform] [--copies N] [--color-weight W] [--no-loop-closure]\n"
    "         [--set KEY=VALUE ...]\n"
    "       bench_fusion --scale N [--texture M] [--width W] [--per-turn N]\n"
    "         [--radius M] [--depth-bias K] [--color-weight W] [--no-loop-closure]\n"
    "         [--threads N] [--trajectory PREFIX]\n";

// --set KEY=VALUE: any option of the fusion section (genscene-fuse --help lists them).
using Overrides = std::vector<std::pair<std::string, std::string>>;

void ApplyOverrides(const Overrides& overrides, fusion::FusionOptions* options) {
  for (const auto& [key, text] : overrides) {
    bool found = false;
    options->Visit([&](const char* name, auto& value, const char*, const char*) {
      if (key != name) return;
      found = true;
      using T = std::decay_t<decltype(value)>;
      if constexpr (std::is_same_v<T, bool>) {
        value = text == "true" || text == "1";
      } else if constexpr (std::is_same_v<T, std::string>) {
        value = text;
      } else if constexpr (std::is_integral_v<T>) {
        value = static_cast<T>(std::stoll(text));
      } else {
        value = static_cast<T>(std::stod(text));
      }
    });
    if (!found) throw std::runtime_error("--set: no fusion option " + key);
  }
}

double PeakMegabytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // kilobytes on Linux
}

// The long scan of --scale (see the top of the file).
void LongScan(int frames, double texture, int width, int per_turn, bool loop_closure, double radius,
              double depth_bias, double color_weight, const Overrides& overrides,
              const std::string& trajectory_prefix) {
  SyntheticScene room = MakeLivingRoomScene();
  room.texture_tile = texture;
  const int height = width * 3 / 4;
  const CameraIntrinsics k = CameraIntrinsics::Centered(width, height, 525.0 * width / 640.0);
  const Trajectory truth = MakeRoomLoopTrajectory(
      Eigen::Vector3d::Zero(), radius, 1.5, static_cast<double>(frames) / per_turn, frames, 11);
  fusion::FusionOptions options;
  options.loop.enabled = loop_closure;
  if (color_weight >= 0.0) options.icp.color_weight = color_weight;
  ApplyOverrides(overrides, &options);
  options.Validate();
  fusion::KinectFusion kf(options, k);
  std::printf(
      "long scan of the analytic living room, %d frames of %dx%d, Kinect noise, radial depth bias "
      "%g, texture tiles %g m, a %g m circle every %d frames, loop closure %s, threads %d\n",
      frames, k.width, k.height, depth_bias, texture, radius, per_turn, loop_closure ? "on" : "off",
      ThreadCount());
  std::printf("%7s | %8s %8s | %8s %9s %9s | %8s | %s\n", "frames", "fps", "worst ms", "blocks",
              "volume MB", "peak MB", "ATE cm", "statuses");
  double seconds = 0.0, worst = 0.0;
  int window = 0;
  std::map<std::string, int> statuses;
  for (int i = 0; i < frames; ++i) {
    const StampedPose& p = truth.poses()[static_cast<size_t>(i)];
    RgbdFrame frame = RenderSyntheticFrame(room, k, p.world_from_camera, p.timestamp);
    if (depth_bias != 0.0) AddRadialDepthBias(frame.depth, k, depth_bias);
    AddKinectDepthNoise(frame.depth, 5, static_cast<uint64_t>(i));
    frame.world_from_camera.reset();  // tracked, not given
    const fusion::FrameReport r = kf.ProcessFrame(frame);
    seconds += r.seconds();
    worst = std::max(worst, r.seconds());
    ++window;
    ++statuses[fusion::ToString(r.status)];
    if (r.loop_closure) {
      const fusion::LoopClosureEvent& e = *r.loop_closure;
      std::printf(
          "  frame %d: loop closed against t = %.3f (%d feature inliers, ICP %.2f / %.2f mm): "
          "discrepancy %.2f cm %.2f deg, frames moved up to %.2f cm, %zu re-integrated, %.0f ms\n",
          i, e.against_timestamp, e.feature_inliers, e.icp_inlier_ratio, 1e3 * e.icp_rms,
          100.0 * e.discrepancy_translation, e.discrepancy_degrees, 100.0 * e.largest_move,
          r.reintegrated, 1e3 * r.seconds_loop);
    }
    if ((i + 1) % 100 == 0 || i + 1 == frames) {
      Trajectory so_far;
      for (int j = 0; j <= i; ++j)
        so_far.Add(truth.poses()[j].timestamp, truth.poses()[j].world_from_camera);
      double ate = std::nan("");
      try {
        ate = ComputeAte(kf.trajectory(), so_far).rmse;
      } catch (const std::exception&) {
      }
      // Drift: the last tracked pose against the truth, both relative to the first frame.
      double drift = std::nan("");
      if (!kf.trajectory().poses().empty()) {
        const StampedPose& last = kf.trajectory().poses().back();
        for (int j = 0; j <= i; ++j) {
          if (truth.poses()[j].timestamp != last.timestamp) continue;
          const Eigen::Isometry3d rel =
              truth.poses()[0].world_from_camera.inverse() * truth.poses()[j].world_from_camera;
          drift = (rel.translation() - last.world_from_camera.translation()).norm();
        }
      }
      std::string counts = "drift " + std::to_string(100.0 * drift) + " cm ";
      for (const auto& [name, n] : statuses) counts += name + " " + std::to_string(n) + " ";
      std::printf("%7d | %8.1f %8.1f | %8zu %9.1f %9.0f | %8.3f | %s\n", i + 1, window / seconds,
                  1e3 * worst, kf.volume().num_blocks(), kf.volume().allocated_bytes() / 1e6,
                  PeakMegabytes(), 100.0 * ate, counts.c_str());
      std::fflush(stdout);
      seconds = worst = 0.0;
      window = 0;
    }
  }
  if (!trajectory_prefix.empty() && !kf.trajectory().poses().empty()) {
    // Both in the frame of the first camera fusion kept (its trajectory starts at the identity).
    const double first = kf.trajectory().poses().front().timestamp;
    const auto truth_first = truth.Nearest(first, 0.0);
    if (!truth_first)
      throw std::runtime_error("--trajectory: no true pose at fusion's first frame");
    Trajectory truth_in_first;
    const Eigen::Isometry3d first_from_world = truth_first->world_from_camera.inverse();
    for (const StampedPose& p : truth.poses())
      truth_in_first.Add(p.timestamp, first_from_world * p.world_from_camera);
    WriteTumTrajectory(trajectory_prefix + "_estimate.txt", kf.trajectory());
    WriteTumTrajectory(trajectory_prefix + "_truth.txt", truth_in_first);
    std::printf("trajectories: %s_estimate.txt, %s_truth.txt\n", trajectory_prefix.c_str(),
                trajectory_prefix.c_str());
  }
}

// The raycast of fusion's model (its intrinsics, depth range and normals) at every pose of
// `trajectory`, on `volume` and on `volume` with `copies` copies of its blocks beside it.
void TimeRaycastAgainstVolumeSize(const TsdfVolume& volume, const Trajectory& trajectory,
                                  const CameraIntrinsics& intrinsics,
                                  const fusion::FusionOptions& options, int copies,
                                  double per_frame_seconds) {
  TsdfVolumeParams params = volume.params();
  params.memory_cap_bytes = 0;
  TsdfVolume large(params);
  Eigen::Vector3i lo = volume.block_key(0), hi = lo;
  for (size_t b = 0; b < volume.num_blocks(); ++b) {
    lo = lo.cwiseMin(volume.block_key(b));
    hi = hi.cwiseMax(volume.block_key(b));
  }
  // Copies side by side along x, a gap of 30 m between them (beyond the raycast's depth range).
  const int gap = static_cast<int>(std::ceil(30.0 / (kTsdfBlockSide * volume.voxel_size())));
  const int stride = hi.x() - lo.x() + 1 + gap;
  for (int c = 0; c <= copies; ++c) {
    for (size_t b = 0; b < volume.num_blocks(); ++b) {
      large.block(large.AllocateBlock(volume.block_key(b) + Eigen::Vector3i(c * stride, 0, 0))) =
          volume.block(b);
    }
  }
  const int subsample = options.ModelSubsample(intrinsics.width);
  const CameraIntrinsics k = intrinsics.Scaled(1.0 / subsample);
  const int normal_step = std::max(1, 2 / subsample);
  double seconds[2] = {};
  size_t projected[2] = {};
  for (int pass = 0; pass < 3; ++pass) {  // the first pass warms the caches, untimed
    for (const StampedPose& p : trajectory.poses()) {
      for (int which = 0; which < 2; ++which) {
        const TsdfVolume& v = which == 0 ? volume : large;
        const auto start = std::chrono::steady_clock::now();
        const fusion::RaycastResult r =
            fusion::RaycastVolume(v, k, p.world_from_camera, options.preprocess.min_depth,
                                  options.preprocess.max_depth, false, normal_step);
        if (pass == 0) continue;
        seconds[which] +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        projected[which] += r.blocks_projected;
      }
    }
  }
  const double n = 2.0 * static_cast<double>(trajectory.size());
  std::printf(
      "  model raycast %dx%d per frame: volume %zu blocks / %zu chunks: %.2f ms, %.0f blocks "
      "projected; %dx as large (%zu blocks / %zu chunks): %.2f ms, %.0f blocks projected; "
      "per-frame time %+.1f %%\n",
      k.width, k.height, volume.num_blocks(), volume.num_chunks(), 1e3 * seconds[0] / n,
      static_cast<double>(projected[0]) / n, copies + 1, large.num_blocks(), large.num_chunks(),
      1e3 * seconds[1] / n, static_cast<double>(projected[1]) / n,
      100.0 * (seconds[1] - seconds[0]) / n / per_frame_seconds);
}

int Run(int argc, char** argv) {
  std::vector<std::string> folders;
  int threads = 0;
  int model_subsample = fusion::FusionOptions().model_subsample;
  int allocation_stride = fusion::FusionOptions().allocation_stride;
  std::string weighting = fusion::FusionOptions().weighting;
  int copies = 3;
  int scale = 0;
  double texture = 0.15;
  int width = 640;
  int per_turn = 400;
  bool loop_closure = true;
  double radius = 0.4;
  double depth_bias = 0.0;
  std::string trajectory_prefix;
  double color_weight = -1.0;  // the default
  Overrides overrides;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::printf(
          "%s"
          "  FOLDER: a TUM-layout sequence with groundtruth.txt (e.g. from genscene-synth)\n"
          "  prints per-frame times of each step, fps, ATE, and integration alone (known poses);\n"
          "  then the model raycast per frame on the volume and on it with N translated copies\n"
          "  of its blocks out of view (--copies, default 3: a volume 4x as large)\n",
          kUsage);
      return 0;
    }
    if (std::strcmp(argv[i], "--model-subsample") == 0 && i + 1 < argc) {
      model_subsample = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--weighting") == 0 && i + 1 < argc) {
      weighting = argv[++i];
    } else if (std::strcmp(argv[i], "--allocation-stride") == 0 && i + 1 < argc) {
      allocation_stride = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--copies") == 0 && i + 1 < argc) {
      copies = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--threads") == 0 && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--scale") == 0 && i + 1 < argc) {
      scale = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--texture") == 0 && i + 1 < argc) {
      texture = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--color-weight") == 0 && i + 1 < argc) {
      color_weight = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--depth-bias") == 0 && i + 1 < argc) {
      depth_bias = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--trajectory") == 0 && i + 1 < argc) {
      trajectory_prefix = argv[++i];
    } else if (std::strcmp(argv[i], "--radius") == 0 && i + 1 < argc) {
      radius = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--set") == 0 && i + 1 < argc) {
      const std::string kv = argv[++i];
      const size_t eq = kv.find('=');
      if (eq == std::string::npos) throw std::runtime_error("--set " + kv + ": expected KEY=VALUE");
      overrides.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    } else if (std::strcmp(argv[i], "--no-loop-closure") == 0) {
      loop_closure = false;
    } else if (std::strcmp(argv[i], "--per-turn") == 0 && i + 1 < argc) {
      per_turn = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--width") == 0 && i + 1 < argc) {
      width = std::atoi(argv[++i]);
    } else {
      folders.push_back(argv[i]);
    }
  }
  if (!trajectory_prefix.empty() && scale <= 0)
    throw std::runtime_error("--trajectory: only with --scale (the long scan)");
  if (scale > 0) {
    SetThreadCount(threads);
    LongScan(scale, texture, width, per_turn, loop_closure, radius, depth_bias, color_weight,
             overrides, trajectory_prefix);
    return 0;
  }
  if (folders.empty()) {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  SetThreadCount(threads);
  std::printf(
      "threads %d, model subsample %d (0 = by the width), allocation stride %d (0 = width / 160), "
      "%s "
      "weights, colour weight %g, loop closure %s\n",
      ThreadCount(), model_subsample, allocation_stride, weighting.c_str(),
      color_weight >= 0.0 ? color_weight : fusion::IcpOptions().color_weight,
      loop_closure ? "on" : "off");
  std::printf("%-28s %9s %7s | %8s %8s %8s %8s %8s %8s %8s | %9s | %8s %9s\n", "sequence", "size",
              "frames", "prep ms", "track ms", "integ ms", "ray ms", "loop ms", "fps", "wall fps",
              "ATE cm", "integ fps", "blocks");
  for (const std::string& folder : folders) {
    auto source = OpenFrameSource(folder, SourceOptions());
    const std::vector<RgbdFrame> frames = ReadAllFrames(*source);  // decoding is not timed
    double totals[2][5] = {};
    double wall[2] = {};  // the whole of ProcessFrame
    double ate = 0.0;
    std::optional<TsdfVolume> volume;
    Trajectory trajectory;
    fusion::FusionOptions icp_options;
    for (int mode = 0; mode < 2; ++mode) {
      fusion::FusionOptions options;
      options.tracking = mode == 0 ? "icp" : "known";
      options.model_subsample = model_subsample;
      options.allocation_stride = allocation_stride;
      options.weighting = weighting;
      options.loop.enabled = loop_closure;
      if (color_weight >= 0.0) options.icp.color_weight = color_weight;
      ApplyOverrides(overrides, &options);
      options.Validate();
      fusion::KinectFusion kf(options, source->Intrinsics());
      for (const RgbdFrame& f : frames) {
        const auto start = std::chrono::steady_clock::now();
        const fusion::FrameReport r = kf.ProcessFrame(f);
        wall[mode] +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        totals[mode][0] += r.seconds_preprocess;
        totals[mode][1] += r.seconds_track;
        totals[mode][2] += r.seconds_integrate;
        totals[mode][3] += r.seconds_raycast;
        totals[mode][4] += r.seconds_loop;
      }
      if (mode == 0) {
        ate = ComputeAte(kf.trajectory(), source->KnownPoses()).rmse;
        volume = kf.volume();
        trajectory = kf.trajectory();
        icp_options = options;
      }
    }
    const double n = static_cast<double>(frames.size());
    const double per_frame =
        (totals[0][0] + totals[0][1] + totals[0][2] + totals[0][3] + totals[0][4]) / n;
    char size[32];
    std::snprintf(size, sizeof(size), "%dx%d", source->Intrinsics().width,
                  source->Intrinsics().height);
    std::printf("%-28s %9s %7zu | %8.2f %8.2f %8.2f %8.2f %8.2f %8.1f %8.1f | %9.3f | %8.1f %9zu\n",
                folder.substr(folder.size() > 28 ? folder.size() - 28 : 0).c_str(), size,
                frames.size(), 1e3 * totals[0][0] / n, 1e3 * totals[0][1] / n,
                1e3 * totals[0][2] / n, 1e3 * totals[0][3] / n, 1e3 * totals[0][4] / n,
                1.0 / per_frame, n / wall[0], 100.0 * ate, n / totals[1][2],
                volume ? volume->num_blocks() : size_t{0});
    if (copies > 0 && volume && volume->num_blocks() > 0) {
      TimeRaycastAgainstVolumeSize(*volume, trajectory, source->Intrinsics(), icp_options, copies,
                                   per_frame);
    }
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
