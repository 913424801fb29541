// The live camera path through OpenNI2 itself: genscene-capture and genscene-fuse on an emulated
// camera. The camera is an OpenNI2 driver (tests/capture/emulated_camera/) that streams a
// genscene-synth folder at 30 Hz. OpenNI2 loads its drivers from OpenNI2/Drivers next to the
// libOpenNI2.so in use, so each suite copies the system's libOpenNI2.so.0 into a temporary folder
// with the driver in its OpenNI2/Drivers, and runs the apps with LD_LIBRARY_PATH pointing there:
// the product's code is the one a real camera runs through. Every command runs under a timeout.
#include <OniCAPI.h>
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <thread>

#include "capture/oni_format.h"
#include "core/file_util.h"
#include "core/trajectory.h"
#include "core/trajectory_metrics.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

constexpr int kFolderFrames = 10;  // frames of the streamed folder (the camera loops over them)
constexpr int kWidth = 640, kHeight = 480;

// Pieces of the output between line breaks and carriage returns (progress lines use '\r').
std::vector<std::string> Pieces(const std::string& text) {
  std::vector<std::string> pieces;
  std::string piece;
  for (char c : text) {
    if (c == '\n' || c == '\r') {
      if (!piece.empty()) pieces.push_back(piece);
      piece.clear();
    } else {
      piece += c;
    }
  }
  if (!piece.empty()) pieces.push_back(piece);
  return pieces;
}

// The error lines ("<app>: error: ...") of an app's output; a progress piece the error was printed
// right after is cut off.
std::vector<std::string> ErrorLines(const std::string& text) {
  std::vector<std::string> errors;
  for (const std::string& p : Pieces(text)) {
    const size_t at = p.find(": error: ");
    if (at == std::string::npos) continue;
    const size_t app = p.rfind("genscene-", at);
    errors.push_back(p.substr(app == std::string::npos ? 0 : app));
  }
  return errors;
}

// Where the libOpenNI2 this test runs with lives (the apps load the same one).
std::optional<fs::path> SystemOpenNI2() {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&oniInitialize), &info) == 0 || info.dli_fname == nullptr)
    return std::nullopt;
  std::error_code ec;
  fs::path path = fs::canonical(info.dli_fname, ec);
  if (ec || !fs::is_regular_file(path)) return std::nullopt;
  return path;
}

class EmulatedCamera : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    const std::optional<fs::path> lib = SystemOpenNI2();
    if (!lib) {
      skip_reason_ = new std::string("libOpenNI2.so.0 not found; the emulated camera needs it");
      return;
    }
    fs::create_directories(Lib() / "OpenNI2" / "Drivers");
    fs::copy_file(*lib, Lib() / "libOpenNI2.so.0");
    // OpenNI2 loads the files named lib*.so.0 of its driver folder.
    fs::copy_file(GENSCENE_EMULATED_CAMERA_DRIVER,
                  Lib() / "OpenNI2" / "Drivers" / "libgenscene_emulated_camera.so.0");
    // And OpenNI2's own recording player, so that `genscene run` reads back what it recorded.
    const fs::path player = lib->parent_path() / "OpenNI2" / "Drivers" / "libOniFile.so.0";
    if (!fs::exists(player)) {
      skip_reason_ = new std::string(player.string() + " not found; genscene run needs it");
      return;
    }
    fs::copy_file(player, Lib() / "OpenNI2" / "Drivers" / "libOniFile.so.0");
    // A slow sway (10 degrees over the folder) that ICP tracks even across the frames fusion
    // misses while it works, and across the jump back when the camera loops.
    auto r = RunCommand(AppPath("genscene-synth") + " --scene cornell --frames " +
                            std::to_string(kFolderFrames) +
                            " --size 640x480 --spp 1 --arc 10 --out " + Seq().string(),
                        300);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    // The reference: the folder's frames as genscene-capture records the folder itself.
    r = RunCommand(AppPath("genscene-capture") + " --input " + Seq().string() + " --record " +
                       (*dir_ / "reference.oni").string(),
                   120);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    reference_ = new capture::OniRecording(capture::ReadOniFile(*dir_ / "reference.oni"));
    ASSERT_EQ(reference_->frames.size(), static_cast<size_t>(kFolderFrames));
  }
  static void TearDownTestSuite() {
    delete reference_;
    delete skip_reason_;
    delete dir_;
    reference_ = nullptr;
    skip_reason_ = nullptr;
  }

  void SetUp() override {
    if (skip_reason_) {
      if (test::InCi()) FAIL() << *skip_reason_ << ", and CI=true requires it";
      GTEST_SKIP() << *skip_reason_;
    }
    ASSERT_NE(reference_, nullptr) << "the suite's setup failed";
  }

  static fs::path Lib() { return *dir_ / "lib"; }
  static fs::path Seq() { return *dir_ / "seq"; }

  // The environment that makes OpenNI2 load the emulated camera streaming the folder.
  static std::string Env(const std::string& fault = "", const fs::path& folder = Seq()) {
    return "LD_LIBRARY_PATH=" + Lib().string() + " GENSCENE_EMULATED_CAMERA=" + folder.string() +
           (fault.empty() ? "" : " GENSCENE_EMULATED_FAULT=" + fault) + " ";
  }

  // Camera frame number of a recorded frame (the camera stamps frame n with n / 30 s).
  static int FrameNumber(const capture::OniRawFrame& f) {
    return static_cast<int>(std::llround(static_cast<double>(f.timestamp_us) * 30.0 / 1e6));
  }

  // Checks that every frame of `rec` is the frame of `reference` (the folder as recorded directly)
  // that its time stamp names (the camera loops), subsampled by `step`, in increasing order;
  // returns the frame numbers.
  static std::vector<int> ExpectFolderFrames(const capture::OniRecording& rec, int step = 1,
                                             const capture::OniRecording* reference = nullptr) {
    if (reference == nullptr) reference = reference_;
    const size_t count = reference->frames.size();
    std::vector<int> numbers;
    const int w = kWidth / step, h = kHeight / step;
    EXPECT_EQ(rec.width, w);
    EXPECT_EQ(rec.height, h);
    for (const capture::OniRawFrame& f : rec.frames) {
      const int n = FrameNumber(f);
      EXPECT_NEAR(static_cast<double>(f.timestamp_us), n * 1e6 / 30.0, 1.0);
      if (!numbers.empty()) {
        EXPECT_GT(n, numbers.back()) << "frames out of order";
      }
      numbers.push_back(n);
      const capture::OniRawFrame& want = reference->frames[n % count];
      EXPECT_EQ(f.depth_mm.size(), static_cast<size_t>(w * h));
      EXPECT_EQ(f.color_rgb.size(), static_cast<size_t>(w * h * 3));
      if (f.depth_mm.size() != static_cast<size_t>(w * h) ||
          f.color_rgb.size() != static_cast<size_t>(w * h * 3))
        continue;
      size_t depth_diff = 0, color_diff = 0;
      for (int v = 0; v < h; ++v) {
        for (int u = 0; u < w; ++u) {
          const size_t src = static_cast<size_t>(v * step) * kWidth + u * step;
          const size_t dst = static_cast<size_t>(v) * w + u;
          depth_diff += f.depth_mm[dst] != want.depth_mm[src];
          for (int c = 0; c < 3; ++c)
            color_diff += f.color_rgb[3 * dst + c] != want.color_rgb[3 * src + c];
        }
      }
      EXPECT_EQ(depth_diff, 0u) << "camera frame " << n;
      EXPECT_EQ(color_diff, 0u) << "camera frame " << n;
    }
    return numbers;
  }

  // genscene-capture --record --max-frames `frames` from the camera misbehaving as `fault` says,
  // read back (no frames, with the failure reported, when the capture fails).
  static capture::OniRecording RecordLive(const std::string& fault, int frames) {
    test::TempDir out;
    const auto r =
        RunCommand(Env(fault) + AppPath("genscene-capture") + " --record " +
                       (out / "live.oni").string() + " --max-frames " + std::to_string(frames),
                   60);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    if (r.exit_code != 0) return {};
    return capture::ReadOniFile(out / "live.oni");
  }

  // A command that must fail: one error line, exit code 1, within the hang guard.
  static std::string ExpectOneError(const std::string& command) {
    const auto r = RunCommand(command, 30);
    const std::string tail =
        r.output.substr(r.output.size() - std::min<size_t>(r.output.size(), 2000));
    EXPECT_EQ(r.exit_code, 1) << command << "\n..." << tail;
    const std::vector<std::string> errors = ErrorLines(r.output);
    EXPECT_EQ(errors.size(), 1u) << "..." << tail;
    return errors.empty() ? "(no error line) ..." + tail : errors.front();
  }

  static test::TempDir* dir_;
  static std::string* skip_reason_;
  static capture::OniRecording* reference_;
};
test::TempDir* EmulatedCamera::dir_ = nullptr;
std::string* EmulatedCamera::skip_reason_ = nullptr;
capture::OniRecording* EmulatedCamera::reference_ = nullptr;

TEST_F(EmulatedCamera, OpenNI2FindsTheDeviceOnlyWhenItStreams) {
  test::TempDir out;
  // Without a folder the driver lists no device: the usual no-camera line.
  const std::string no_folder = "LD_LIBRARY_PATH=" + Lib().string() + " ";
  EXPECT_EQ(ExpectOneError(no_folder + AppPath("genscene-capture") + " --record " +
                           (out / "a.oni").string()),
            "genscene-capture: error: no OpenNI2 device found \xE2\x80\x94 connect a camera or "
            "give a .oni file or a folder");
  // With it, the first camera and the camera by its URI open.
  for (const std::string input : {"openni2", "openni2:genscene-emulated://0"}) {
    const auto r = RunCommand(Env() + AppPath("genscene-capture") + " --input " + input +
                                  " --record " + (out / "b.oni").string() + " --max-frames 2",
                              30);
    EXPECT_EQ(r.exit_code, 0) << input << "\n" << r.output;
    EXPECT_CONTAINS(r.output, "OpenNI2 camera " + input + " (640x480)");
    EXPECT_CONTAINS(r.output, "capturing: 2/2 frames");
  }
  EXPECT_CONTAINS(
      ExpectOneError(Env() + AppPath("genscene-capture") +
                     " --input openni2:nowhere://1 --record " + (out / "c.oni").string()),
      "OpenNI2 cannot open it");
  EXPECT_FALSE(fs::exists(out / "a.oni"));
  EXPECT_FALSE(fs::exists(out / "c.oni"));
}

TEST_F(EmulatedCamera, RecordingHoldsTheStreamedFramesFrameForFrame) {
  test::TempDir out;
  // 12 frames: more than the folder has, so the camera loops.
  const auto r = RunCommand(Env() + AppPath("genscene-capture") + " --record " +
                                (out / "live.oni").string() + " --max-frames 12",
                            60);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "capturing: 12/12 frames");
  // The camera takes the registration and frame sync the source asks for: no warning about them.
  EXPECT_EQ(r.output.find("regist"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("synchronise"), std::string::npos) << r.output;
  const capture::OniRecording rec = capture::ReadOniFile(out / "live.oni");
  ASSERT_EQ(rec.frames.size(), 12u);
  const std::vector<int> numbers = ExpectFolderFrames(rec);
  // The camera streams at 30 Hz whether or not the reader keeps up, and OpenNI2 keeps only the
  // newest frame of a stream: on a loaded machine (the sanitizer pass, two tests at once) the
  // first read can come after frame 0 was replaced. The recording starts at the first pair read
  // and from there holds every frame, or reports each one it missed.
  const int missed = numbers.back() - numbers.front() + 1 - static_cast<int>(numbers.size());
  EXPECT_CONTAINS(r.output, "skipped: " + std::to_string(missed) + " camera frames");
  EXPECT_LE(numbers.front(), 30) << "the recording starts within the camera's first second";
  EXPECT_EQ(test::CountFilesContaining(out.path(), "tmp"), 0);
}

// Real Kinect frames (TUM fr1/desk, with holes and noise): the folder lists 613 colour and 595
// depth images of which 9 each are present; the camera streams those 9.
TEST_F(EmulatedCamera, RealKinectFramesAreRecordedFrameForFrame) {
  GS_REQUIRE_SHARED_DATA(data);
  const fs::path folder = data / "real" / "tum-fr1desk-9f";
  test::TempDir out;
  // The reference without undistortion: the camera streams the images as they are.
  test::WriteFile(out / "k.txt", "525 525 319.5 239.5 640 480\n");
  auto r =
      RunCommand(AppPath("genscene-capture") + " --input " + folder.string() + " --associations " +
                     (folder / "associate_9frames.txt").string() + " --intrinsics " +
                     (out / "k.txt").string() + " --record " + (out / "reference.oni").string(),
                 60);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const capture::OniRecording reference = capture::ReadOniFile(out / "reference.oni");
  ASSERT_EQ(reference.frames.size(), 9u);
  r = RunCommand(Env("", folder) + AppPath("genscene-capture") + " --record " +
                     (out / "live.oni").string() + " --max-frames 9",
                 60);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const capture::OniRecording rec = capture::ReadOniFile(out / "live.oni");
  ASSERT_EQ(rec.frames.size(), 9u);
  ExpectFolderFrames(rec, 1, &reference);
}

TEST_F(EmulatedCamera, SmallModeIsEveryOtherPixel) {
  test::TempDir out;
  const auto r = RunCommand(Env() + AppPath("genscene-capture") + " --mode 320x240 --record " +
                                (out / "small.oni").string() + " --max-frames 3",
                            60);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "OpenNI2 camera openni2 (320x240)");
  const capture::OniRecording rec = capture::ReadOniFile(out / "small.oni");
  ASSERT_EQ(rec.frames.size(), 3u);
  ExpectFolderFrames(rec, 2);
}

// genscene-fuse reports no trajectory error for a live camera (it has no poses); the test computes
// it (Horn-aligned ATE) against the folder's ground truth, and compares it with the ATE of fusing
// the folder itself.
TEST_F(EmulatedCamera, FuseTracksTheLiveCameraAsWellAsTheFolder) {
  test::TempDir out;
  const std::string common = " --max-frames " + std::to_string(kFolderFrames) + " --intrinsics " +
                             (Seq() / "intrinsics.txt").string();
  auto r = RunCommand(AppPath("genscene-fuse") + " --input " + Seq().string() + " " +
                          (out / "ws_folder").string() + common,
                      120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunCommand(
      Env() + AppPath("genscene-fuse") + " --input openni2 " + (out / "ws_live").string() + common,
      120);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "OpenNI2 camera openni2 (640x480)");
  EXPECT_CONTAINS(r.output, "lost 0");
  const Trajectory truth = ReadTumTrajectory(Seq() / "groundtruth.txt");
  const Trajectory folder = ReadTumTrajectory(out / "ws_folder" / "trajectory.txt");
  const Trajectory live = ReadTumTrajectory(out / "ws_live" / "trajectory.txt");
  ASSERT_EQ(truth.size(), static_cast<size_t>(kFolderFrames));
  ASSERT_EQ(folder.size(), static_cast<size_t>(kFolderFrames));
  ASSERT_EQ(live.size(), static_cast<size_t>(kFolderFrames));
  // Fusion runs slower than 30 Hz: the camera frames that arrive meanwhile are superseded, as with
  // a real camera, and the fused frames reach into the camera's next passes over the folder. The
  // ground truth of camera frame n is that of folder frame n mod 10, at the camera's time stamp.
  Trajectory looped_truth;
  for (const StampedPose& p : live.poses()) {
    const int n = static_cast<int>(std::lround(p.timestamp * 30.0));
    looped_truth.Add(p.timestamp, truth.poses()[n % kFolderFrames].world_from_camera);
  }
  EXPECT_EQ(live.poses().front().timestamp, 0.0);
  // The camera frames fusion had no time for are counted, in fusion.json and on the console.
  const int last = static_cast<int>(std::lround(live.poses().back().timestamp * 30.0));
  const size_t skipped = static_cast<size_t>(last + 1) - live.size();
  const auto report = nlohmann::json::parse(ReadTextFile(out / "ws_live" / "fusion.json"));
  EXPECT_EQ(report["summary"]["camera_frames_skipped"].get<size_t>(), skipped);
  EXPECT_CONTAINS(r.output, "camera:     " + std::to_string(last + 1) +
                                " frames sent while fusing, " + std::to_string(skipped) +
                                " skipped");
  const AteResult ate_folder = ComputeAte(folder, truth);
  const AteResult ate_live = ComputeAte(live, looped_truth);
  std::cout << "ATE RMSE: folder " << ate_folder.rmse * 1000.0 << " mm over " << ate_folder.pairs
            << " frames, live " << ate_live.rmse * 1000.0 << " mm over " << ate_live.pairs
            << " frames\n";
  EXPECT_EQ(ate_live.pairs, static_cast<size_t>(kFolderFrames));
  EXPECT_LT(ate_live.rmse, 0.01);
  EXPECT_NEAR(ate_live.rmse, ate_folder.rmse, 1e-3);
}

TEST_F(EmulatedCamera, DroppedFramesAreSkippedAndTheRestRecorded) {
  const capture::OniRecording rec = RecordLive("drop=3", 6);
  ASSERT_EQ(rec.frames.size(), 6u);
  for (int n : ExpectFolderFrames(rec)) EXPECT_NE(n % 3, 2) << "frame " << n << " was dropped";
}

// A colour frame lost on its own: the depth frame of that time is skipped too, never paired with
// the next colour frame.
TEST_F(EmulatedCamera, AColourFrameDroppedAloneLeavesNoMismatchedPair) {
  const capture::OniRecording rec = RecordLive("drop_color=3", 6);
  ASSERT_EQ(rec.frames.size(), 6u);
  for (int n : ExpectFolderFrames(rec)) EXPECT_NE(n % 3, 2) << "frame " << n << " has no colour";
}

// The colour stream a frame behind the depth stream (each frame stamped with its own time): every
// recorded pair is one time's depth and colour, however fast the frames are read.
TEST_F(EmulatedCamera, ColourAFrameBehindIsStillPairedWithItsDepth) {
  const capture::OniRecording rec = RecordLive("out_of_step", 6);
  ASSERT_EQ(rec.frames.size(), 6u);
  ExpectFolderFrames(rec);  // depth and colour of the same folder frame in every recorded pair
}

// An unplugged or stalled camera ends the stream: one warning line, and the frames received are a
// complete recording (and a complete fusion). An unplug ends it at once (OpenNI2's disconnect
// event), a stall after the frame timeout.
TEST_F(EmulatedCamera, UnpluggedOrStalledCameraEndsTheCaptureWithTheFramesReceived) {
  for (const std::string fault : {"disconnect=4", "stall=4"}) {
    test::TempDir out;
    const auto start = std::chrono::steady_clock::now();
    const auto r = RunCommand(Env(fault) + AppPath("genscene-capture") + " --record " +
                                  (out / "live.oni").string() + " --out " + (out / "tum").string(),
                              120);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << fault << ": capture ended after " << seconds << " s\n";
    ASSERT_EQ(r.exit_code, 0) << fault << "\n" << r.output;
    const std::string why = fault == "stall=4" ? "no depth frame within 2 s (camera stalled)"
                                               : "the camera was disconnected";
    // A loaded machine (the sanitizer run beside other tests) can miss a camera frame while
    // writing; the app counts it as skipped. The frames received are the 4 before the fault less
    // those.
    int skipped = 0;
    if (const size_t at = r.output.find("skipped: "); at != std::string::npos)
      skipped = std::stoi(r.output.substr(at + 9));
    const int received = 4 - skipped;
    ASSERT_GE(received, 2) << r.output;
    EXPECT_CONTAINS(r.output, "[warning] openni2: " + why + " after " + std::to_string(received) +
                                  " frames; the capture ends with the frames received");
    EXPECT_EQ(ErrorLines(r.output).size(), 0u) << r.output;
    // The unplug is told apart from the timeout by its warning above (the stall's names the 2 s
    // wait), not by the wall time, which a loaded machine stretches.
    EXPECT_CONTAINS(r.output, "frames:  " + std::to_string(received));
    const capture::OniRecording rec = capture::ReadOniFile(out / "live.oni");
    ASSERT_EQ(rec.frames.size(), static_cast<size_t>(received)) << fault;
    const std::vector<int> folder = ExpectFolderFrames(rec);
    ASSERT_EQ(folder.size(), static_cast<size_t>(received));
    for (size_t i = 0; i < folder.size(); ++i) {
      EXPECT_TRUE(folder[i] >= 0 && folder[i] <= 3 && (i == 0 || folder[i] > folder[i - 1]))
          << "folder frame " << folder[i] << " at " << i;
    }
    EXPECT_EQ(test::CountFilesContaining(out / "tum" / "depth", ".png"), received) << fault;
    EXPECT_EQ(test::CountFilesContaining(out.path(), "tmp"), 0) << fault;

    const auto fuse = RunCommand(Env(fault) + AppPath("genscene-fuse") + " --input openni2 " +
                                     (out / "ws").string() + " --intrinsics " +
                                     (Seq() / "intrinsics.txt").string(),
                                 180);
    ASSERT_EQ(fuse.exit_code, 0) << fault << "\n" << fuse.output;
    EXPECT_CONTAINS(fuse.output, "[warning] openni2: " + why);
    // The camera sent frames 0 to 3; fusion took what it had time for and counted the rest.
    const Trajectory fused = ReadTumTrajectory(out / "ws" / "trajectory.txt");
    ASSERT_GE(fused.size(), 1u) << fault;
    const int first = static_cast<int>(std::lround(fused.poses().front().timestamp * 30.0));
    const int last = static_cast<int>(std::lround(fused.poses().back().timestamp * 30.0));
    EXPECT_LE(last, 3) << fault;
    const auto report = nlohmann::json::parse(ReadTextFile(out / "ws" / "fusion.json"));
    EXPECT_EQ(fused.size() + report["summary"]["camera_frames_skipped"].get<size_t>(),
              static_cast<size_t>(last - first + 1))
        << fault;
  }
  // A camera that stalls before its first frame leaves nothing to keep: one error, no output.
  test::TempDir out;
  EXPECT_EQ(ExpectOneError(Env("stall=0") + AppPath("genscene-capture") + " --record " +
                           (out / "live.oni").string()),
            "genscene-capture: error: OpenNI2 camera openni2 (640x480): no frames to record");
  EXPECT_FALSE(fs::exists(out / "live.oni"));
  EXPECT_EQ(test::CountFilesContaining(out.path(), "tmp"), 0);
}

TEST_F(EmulatedCamera, CamerasWithoutWhatGensceneNeedsAreOneClearError) {
  test::TempDir out;
  EXPECT_EQ(ExpectOneError(Env("no_color") + AppPath("genscene-capture") + " --record " +
                           (out / "a.oni").string()),
            "genscene-capture: error: openni2: the device has no colour sensor (genscene needs "
            "depth + colour)");
  EXPECT_EQ(ExpectOneError(Env("bad_modes") + AppPath("genscene-capture") + " --record " +
                           (out / "a.oni").string()),
            "genscene-capture: error: openni2: the camera has no depth mode 640x480 @ 30 Hz (it "
            "offers: 1280x1024@30 format 100, 640x480@60 format 100)");
  EXPECT_FALSE(fs::exists(out / "a.oni"));
}

// An app started in the background with the emulated camera, its stderr and stdout in a log file.
class Background {
 public:
  Background(const std::vector<std::string>& args, const fs::path& log, const fs::path& lib,
             const fs::path& folder)
      : log_(log) {
    std::fflush(stdout);  // the child would flush a copy of pending output
    std::fflush(stderr);
    pid_ = fork();
    if (pid_ == 0) {
      setenv("LD_LIBRARY_PATH", lib.c_str(), 1);
      setenv("GENSCENE_EMULATED_CAMERA", folder.c_str(), 1);
      if (!std::freopen(log.c_str(), "w", stderr) || !std::freopen(log.c_str(), "a", stdout))
        _exit(127);
      std::vector<char*> argv;
      for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
  }
  ~Background() {
    if (pid_ > 0 && !exited_) Exit(std::chrono::milliseconds(0));
  }

  std::string Log() const {
    std::error_code ec;
    return fs::exists(log_, ec) ? ReadTextFile(log_) : std::string();
  }
  // True once the log holds `text`; false after `limit` (a hang guard) or when the app exited.
  bool WaitFor(const std::string& text, std::chrono::milliseconds limit) {
    const auto until = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < until) {
      if (Log().find(text) != std::string::npos) return true;
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        code_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        return Log().find(text) != std::string::npos;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  }
  // Sends SIGINT; returns the time it was sent.
  std::chrono::steady_clock::time_point Interrupt() {
    kill(pid_, SIGINT);
    return std::chrono::steady_clock::now();
  }
  // The exit code once the app has exited (at most `limit`; then it is killed): -1 after a signal,
  // -2 when it had to be killed.
  int Exit(std::chrono::milliseconds limit) {
    const auto until = std::chrono::steady_clock::now() + limit;
    while (!exited_ && std::chrono::steady_clock::now() < until) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        code_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (!exited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
      exited_ = true;
      code_ = -2;
    }
    return code_;
  }

 private:
  fs::path log_;
  pid_t pid_ = -1;
  bool exited_ = false;
  int code_ = -1;
};

double SecondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// Ctrl-C ends a live recording after the current frame: exit 0 within a second, and the frames
// so far are a complete recording.
TEST_F(EmulatedCamera, CtrlCEndsALiveRecordingCleanly) {
  test::TempDir out;
  const fs::path oni = out / "live.oni";
  Background app({AppPath("genscene-capture"), "--record", oni.string()}, out / "capture.log",
                 Lib(), Seq());
  ASSERT_TRUE(app.WaitFor("capturing: 5 frames", std::chrono::seconds(30)))
      << "no 5 frames captured within 30 s:\n"
      << app.Log();
  const auto sent = app.Interrupt();
  const int code = app.Exit(std::chrono::seconds(10));
  const double seconds = SecondsSince(sent);
  EXPECT_EQ(code, 0) << app.Log();
  EXPECT_LT(seconds, 1.0);
  const capture::OniRecording rec = capture::ReadOniFile(oni);
  EXPECT_GE(rec.frames.size(), 5u);
  EXPECT_CONTAINS(app.Log(), "frames:  " + std::to_string(rec.frames.size()));
  ExpectFolderFrames(rec);
  EXPECT_EQ(test::CountFilesContaining(out.path(), "tmp"), 0);
}

// A small chain (about 25 s in a Release build): the camera's small mode, no decimation, few
// pixels and samples.
const std::vector<std::string> kSmallChain = {"--mode",
                                              "320x240",
                                              "--decimate-max-error",
                                              "0",
                                              "--lights-grid",
                                              "3",
                                              "--lights-pixels-per-view",
                                              "300",
                                              "--lights-rounds",
                                              "1",
                                              "--refine-iterations",
                                              "1",
                                              "--refine-pixels-per-view",
                                              "200",
                                              "--refine-spp",
                                              "4",
                                              "--seed",
                                              "3"};

std::string Joined(const std::vector<std::string>& words) {
  std::string line;
  for (const std::string& w : words) line += " " + w;
  return line;
}

// The stages a run ran (not skipped as up to date), and the result of one of them.
std::vector<std::string> StagesRun(const nlohmann::json& summary) {
  std::vector<std::string> ran;
  for (const auto& row : summary["stages"])
    if (!row["skipped"].get<bool>()) ran.push_back(row["stage"].get<std::string>());
  return ran;
}
std::string StageResult(const nlohmann::json& summary, const std::string& stage) {
  for (const auto& row : summary["stages"])
    if (row["stage"] == stage) return row["result"].get<std::string>();
  return "<no " + stage + " row>";
}

// `genscene run --input openni2`: the camera's frames are recorded into WS/capture.oni, frame for
// frame, and the whole chain runs on that recording. Frames the camera drops are counted.
TEST_F(EmulatedCamera, RunRecordsTheLiveCameraAndRunsTheChainOnIt) {
  test::TempDir out;
  const fs::path ws = out / "ws";
  const auto r = RunCommand(Env("drop=4") + AppPath("genscene") + " run --input openni2 --out " +
                                ws.string() + " --max-frames 8" + Joined(kSmallChain),
                            900);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_CONTAINS(r.output, "[0/9] capture: recording OpenNI2 camera openni2 (320x240) into " +
                                (ws / "capture.oni").string());
  const capture::OniRecording rec = capture::ReadOniFile(ws / "capture.oni");
  ASSERT_EQ(rec.frames.size(), 8u);
  const std::vector<int> numbers = ExpectFolderFrames(rec, 2);
  for (int n : numbers) EXPECT_NE(n % 4, 3) << "frame " << n << " was dropped by the camera";
  const int skipped = numbers.back() - numbers.front() + 1 - static_cast<int>(numbers.size());
  EXPECT_GE(skipped, 1);
  const auto summary = nlohmann::json::parse(ReadTextFile(ws / "summary.json"));
  const std::vector<std::string> ran = StagesRun(summary);
  const std::vector<std::string> chain = {"capture", "ingest", "fusion", "meshing", "texturing",
                                          "albedo",  "lights", "refine", "export"};
  ASSERT_GE(ran.size(), chain.size()) << summary.dump(1);
  EXPECT_EQ(std::vector<std::string>(ran.begin(), ran.begin() + chain.size()), chain);
  // The recording starts at the first frame it received: frame 0, unless a loaded machine made
  // the camera skip the first ones too.
  EXPECT_CONTAINS(StageResult(summary, "capture"),
                  numbers.front() == 0 ? std::string("8 frames (t = 0 .. ") : "8 frames (t = ");
  EXPECT_CONTAINS(StageResult(summary, "capture"),
                  ", " + std::to_string(skipped) + " camera frames skipped");
  EXPECT_EQ(summary["input"], (ws / "capture.oni").string());
  EXPECT_EQ(ReadTumTrajectory(ws / "trajectory.txt").size(), 8u);
  EXPECT_TRUE(fs::exists(ws / "export" / "model.glb"));
  EXPECT_TRUE(fs::exists(ws / "export" / "model.xml"));
}

// Ctrl-C in a live run ends the recording within a second and the chain runs on it; Ctrl-C again
// stops the chain within a second, naming the command that resumes from the recording, which then
// skips the finished stages.
TEST_F(EmulatedCamera, CtrlCInALiveRunEndsTheRecordingThenStopsTheChain) {
  test::TempDir out;
  const fs::path ws = out / "ws", oni = ws / "capture.oni";
  std::vector<std::string> args = {AppPath("genscene"), "run",   "--input",
                                   "openni2",           "--out", ws.string()};
  args.insert(args.end(), kSmallChain.begin(), kSmallChain.end());
  Background app(args, out / "run.log", Lib(), Seq());
  ASSERT_TRUE(app.WaitFor("recording: 5 frames", std::chrono::seconds(30))) << app.Log();
  auto sent = app.Interrupt();
  ASSERT_TRUE(app.WaitFor("[1/9] ingest", std::chrono::seconds(10))) << app.Log();
  const double recording_ended = SecondsSince(sent);
  std::cout << "recording ended " << recording_ended << " s after Ctrl-C\n";
  EXPECT_LT(recording_ended, 1.0);
  const capture::OniRecording rec = capture::ReadOniFile(oni);
  EXPECT_GE(rec.frames.size(), 5u);
  ExpectFolderFrames(rec, 2);

  ASSERT_TRUE(app.WaitFor("[6/9] lights", std::chrono::seconds(600))) << app.Log();
  sent = app.Interrupt();
  const int code = app.Exit(std::chrono::seconds(10));
  const double stopped = SecondsSince(sent);
  std::cout << "chain stopped " << stopped << " s after the second Ctrl-C\n";
  EXPECT_EQ(code, 130) << app.Log();
  EXPECT_LT(stopped, 1.0);
  EXPECT_CONTAINS(app.Log(),
                  "genscene: interrupted in stage lights; the finished stages and the recording "
                  "are kept: genscene run --input " +
                      oni.string() + " --out " + ws.string() + " resumes");
  EXPECT_FALSE(fs::exists(ws / "lights.json"));

  // The command it names resumes: the stages before lights are up to date.
  const auto r = RunCommand(AppPath("genscene") + " run --input " + oni.string() + " --out " +
                                ws.string() + Joined(kSmallChain) + " --until albedo",
                            300);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto summary = nlohmann::json::parse(ReadTextFile(ws / "summary.json"));
  EXPECT_EQ(StagesRun(summary), std::vector<std::string>{}) << summary.dump(1);
  EXPECT_CONTAINS(StageResult(summary, "albedo"), "up to date");
}

}  // namespace
}  // namespace genscene
