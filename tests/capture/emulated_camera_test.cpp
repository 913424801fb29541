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
  EXPECT_EQ(numbers.front(), 0) << "the first frame the camera sends is recorded";
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

TEST_F(EmulatedCamera, StalledOrUnpluggedCameraIsOneErrorAndNoOutput) {
  for (const std::string fault : {"stall=4", "disconnect=4"}) {
    test::TempDir out;
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(ExpectOneError(Env(fault) + AppPath("genscene-capture") + " --record " +
                             (out / "live.oni").string() + " --out " + (out / "tum").string()),
              "genscene-capture: error: openni2: no depth frame within 2 s (camera stalled or "
              "unplugged)")
        << fault;
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::cout << fault << ": capture failed after " << seconds << " s\n";
    // Recording is atomic: neither a half-written .oni nor a partial folder is left behind.
    EXPECT_FALSE(fs::exists(out / "live.oni")) << fault;
    EXPECT_FALSE(fs::exists(out / "tum")) << fault;
    EXPECT_EQ(test::CountFilesContaining(out.path(), "tmp"), 0) << fault;
    EXPECT_CONTAINS(ExpectOneError(Env(fault) + AppPath("genscene-fuse") + " --input openni2 " +
                                   (out / "ws").string()),
                    "genscene-fuse: error: openni2: no depth frame within 2 s");
    EXPECT_FALSE(fs::exists(out / "ws" / "trajectory.txt")) << fault;
  }
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

// Ctrl-C ends a live recording after the current frame: exit 0 within a second, and the frames
// so far are a complete recording.
TEST_F(EmulatedCamera, CtrlCEndsALiveRecordingCleanly) {
  test::TempDir out;
  const fs::path log = out / "capture.log", oni = out / "live.oni";
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    setenv("LD_LIBRARY_PATH", Lib().c_str(), 1);
    setenv("GENSCENE_EMULATED_CAMERA", Seq().c_str(), 1);
    if (!std::freopen(log.c_str(), "w", stderr) || !std::freopen(log.c_str(), "a", stdout))
      _exit(127);
    const std::string app = AppPath("genscene-capture");
    execl(app.c_str(), app.c_str(), "--record", oni.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Waits for the child (at most `limit`; then kills it): its exit status, or -1.
  const auto wait_for = [&](std::chrono::milliseconds limit) {
    const auto until = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < until) {
      int status = 0;
      if (waitpid(pid, &status, WNOHANG) == pid)
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    kill(pid, SIGKILL);
    waitpid(pid, nullptr, 0);
    return -2;
  };
  const auto log_text = [&] {
    std::error_code ec;
    return fs::exists(log, ec) ? ReadTextFile(log) : std::string();
  };
  bool capturing = false;
  for (int i = 0; i < 3000 && !capturing; ++i) {  // up to 30 s (a hang guard)
    capturing = log_text().find("capturing: 5 frames") != std::string::npos;
    if (!capturing) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (!capturing) {
    wait_for(std::chrono::milliseconds(0));
    FAIL() << "no 5 frames captured within 30 s:\n" << ReadTextFile(log);
  }
  kill(pid, SIGINT);
  const auto sent = std::chrono::steady_clock::now();
  const int code = wait_for(std::chrono::seconds(10));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  EXPECT_EQ(code, 0) << ReadTextFile(log);
  EXPECT_LT(seconds, 1.0);
  const capture::OniRecording rec = capture::ReadOniFile(oni);
  EXPECT_GE(rec.frames.size(), 5u);
  EXPECT_CONTAINS(ReadTextFile(log), "frames:  " + std::to_string(rec.frames.size()));
  ExpectFolderFrames(rec);
  EXPECT_EQ(test::CountFilesContaining(out.path(), "tmp"), 0);
}

}  // namespace
}  // namespace genscene
