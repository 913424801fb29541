// Live fusion against a 30 Hz camera: genscene-fuse --input openni2 on the emulated OpenNI2 camera
// (tests/capture/emulated_camera/), which streams a TUM folder in real time through OpenNI2's own
// driver interface. Fusion reads the newest frame when it is ready for one; the frames that arrived
// meanwhile are skipped and counted (fusion.json camera_frames_skipped). Prints, per stream mode,
// the camera frames sent, fused and skipped, fusion's own rate, and the trajectory error against
// the folder's ground truth.
//
//   bench_live_camera [--folder TUM] [--intrinsics K] [--frames N] [--modes 640x480,320x240]
//                     [--driver libgenscene_emulated_camera.so]
//
// Without --folder a genscene-synth Cornell box of 30 frames is streamed (the camera loops over a
// folder's frames).
#include <OniCAPI.h>
#include <dlfcn.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/check.h"
#include "core/file_util.h"
#include "core/trajectory.h"
#include "core/trajectory_metrics.h"

namespace fs = std::filesystem;
using namespace genscene;

namespace {

// Runs a shell command; its exit code.
int Shell(const std::string& command) {
  const int rc = std::system(command.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

std::vector<std::string> Split(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// A folder where OpenNI2 loads the emulated camera (and its recording player): a copy of the
// libOpenNI2 this bench runs with, its OpenNI2/Drivers beside it.
fs::path PrepareOpenNI2(const fs::path& dir, const fs::path& driver) {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&oniInitialize), &info) == 0 || info.dli_fname == nullptr)
    throw Error("cannot find the libOpenNI2 in use");
  const fs::path lib = fs::canonical(info.dli_fname);
  const fs::path drivers = dir / "OpenNI2" / "Drivers";
  fs::create_directories(drivers);
  fs::copy_file(lib, dir / "libOpenNI2.so.0", fs::copy_options::overwrite_existing);
  if (!fs::exists(driver))
    throw Error(Format(driver.string(), ": no emulated camera driver (build the tests first)"));
  fs::copy_file(driver, drivers / "libgenscene_emulated_camera.so.0",
                fs::copy_options::overwrite_existing);
  return dir;
}

int Run(int argc, char** argv) {
  CLI::App app{"bench_live_camera: live fusion against the emulated 30 Hz OpenNI2 camera"};
  std::string folder, intrinsics, modes = "640x480,320x240";
  std::string driver = GENSCENE_EMULATED_CAMERA_DRIVER;
  std::string apps = GENSCENE_APPS_DIR;
  int frames = 150;
  app.add_option("--folder", folder, "TUM folder the camera streams (default: a synthetic box)");
  app.add_option("--intrinsics", intrinsics, "intrinsics of the folder (default: its own)");
  app.add_option("--frames", frames, "frames to fuse per run")->capture_default_str();
  app.add_option("--modes", modes, "stream modes, comma-separated")->capture_default_str();
  app.add_option("--driver", driver, "the emulated camera driver")->capture_default_str();
  app.add_option("--apps", apps, "folder of genscene-fuse and genscene-synth")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const fs::path tmp = fs::temp_directory_path() /
                       ("bench_live_camera." + std::to_string(static_cast<long>(getpid())));
  fs::create_directories(tmp);
  struct Cleanup {
    fs::path dir;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } cleanup{tmp};
  const fs::path lib = PrepareOpenNI2(tmp / "lib", driver);
  if (folder.empty()) {
    folder = (tmp / "seq").string();
    std::fprintf(stderr, "synthesising a 30-frame Cornell box at 640x480 ...\n");
    if (Shell(apps +
              "/genscene-synth --scene cornell --frames 30 --size 640x480 --spp 1 --arc 20 "
              "--out " +
              folder + " > /dev/null 2>&1") != 0)
      throw Error("genscene-synth failed");
  }
  if (intrinsics.empty()) intrinsics = (fs::path(folder) / "intrinsics.txt").string();
  // The trajectory error needs one ground-truth pose per streamed frame, as genscene-synth writes
  // (scene.json beside it); a real recording's ground truth is denser than its frames.
  const fs::path truth_path = fs::path(folder) / "groundtruth.txt";
  const Trajectory truth = fs::exists(fs::path(folder) / "scene.json") && fs::exists(truth_path)
                               ? ReadTumTrajectory(truth_path)
                               : Trajectory();
  const size_t folder_frames = truth.size();

  std::printf("live fusion on the emulated OpenNI2 camera (30 Hz), %s, %d frames per run\n\n",
              folder.c_str(), frames);
  std::printf(
      "| mode | camera frames | fused | skipped | skipped %% | fusion fps (processing) | "
      "median ms/frame | fused per camera second | ATE mm |\n"
      "|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& mode : Split(modes)) {
    const fs::path ws = tmp / ("ws_" + mode);
    // The small mode is every other pixel (pixel u is pixel 2u of the full frame): the folder's
    // intrinsics at half scale, principal point included.
    CameraIntrinsics k = ResolveIntrinsics(intrinsics);
    const int width = std::stoi(mode.substr(0, mode.find('x')));
    const double scale = static_cast<double>(width) / k.width;
    k.fx *= scale, k.fy *= scale, k.cx *= scale, k.cy *= scale;
    k.width = width, k.height = static_cast<int>(std::lround(k.height * scale));
    const fs::path k_file = tmp / ("intrinsics_" + mode + ".txt");
    WriteTextFileAtomically(k_file, k.ToString() + "\n");
    const std::string command =
        "LD_LIBRARY_PATH=" + lib.string() + " GENSCENE_EMULATED_CAMERA=" + folder +
        " timeout 600 " + apps + "/genscene-fuse --input openni2 " + ws.string() + " --mode " +
        mode + " --max-frames " + std::to_string(frames) + " --intrinsics " + k_file.string() +
        " > " + (tmp / "fuse.log").string() + " 2>&1";
    if (Shell(command) != 0) {
      std::printf("| %s | genscene-fuse failed: %s |\n", mode.c_str(),
                  ReadTextFile(tmp / "fuse.log").substr(0, 300).c_str());
      continue;
    }
    const auto report = nlohmann::json::parse(ReadTextFile(ws / "fusion.json"));
    const auto& summary = report["summary"];
    const size_t fused = summary["frames"].get<size_t>();
    const size_t skipped = summary.value("camera_frames_skipped", size_t{0});
    std::vector<double> ms;
    for (const auto& f : report["frames"]) {
      ms.push_back(f["ms_preprocess"].get<double>() + f["ms_track"].get<double>() +
                   f["ms_integrate"].get<double>() + f["ms_raycast"].get<double>());
    }
    const Trajectory live = ReadTumTrajectory(ws / "trajectory.txt");
    const double span =
        live.empty() ? 0.0
                     : live.poses().back().timestamp - live.poses().front().timestamp + 1.0 / 30.0;
    std::string ate = "-";
    if (folder_frames > 0 && live.size() >= 3) {
      Trajectory looped;
      for (const StampedPose& p : live.poses()) {
        const long n = std::lround(p.timestamp * 30.0);
        looped.Add(p.timestamp,
                   truth.poses()[static_cast<size_t>(n) % folder_frames].world_from_camera);
      }
      ate = Format(1e3 * ComputeAte(live, looped).rmse);
    }
    std::printf("| %s | %zu | %zu | %zu | %.1f | %.1f | %.1f | %.1f | %s |\n", mode.c_str(),
                fused + skipped, fused, skipped,
                100.0 * skipped / std::max<size_t>(1, fused + skipped),
                fused / std::max(summary["seconds"].get<double>(), 1e-9), Median(ms),
                fused / std::max(span, 1e-9), ate.c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_live_camera: error: %s\n", e.what());
    return 1;
  }
}
