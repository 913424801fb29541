// .oni recordings through OpenNI2 itself: the files genscene writes must play in OpenNI2's own
// player (Device::open + VideoStream), and the OpenNI2 frame source must give back exactly the
// frames of the folder they were made from. Damaged files and a missing camera give one clear
// error, never a hang (each test also runs under a CTest timeout).
#include "capture/openni2_source.h"

#include <OpenNI.h>
#include <gtest/gtest.h>

#include <cmath>

#include "capture/oni_format.h"
#include "capture/record.h"
#include "core/check.h"
#include "core/file_util.h"
#include "tests/capture/capture_test_util.h"
#include "tests/test_util.h"

namespace genscene::capture {
namespace {

namespace fs = std::filesystem;
using test::ErrorOf;

// A TUM folder of 6 frames and the .oni made from it, shared by the tests of this file.
class OniFromTumFolder : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    folder_frames_ = new std::vector<RgbdFrame>(test::MakeTumFolder(*dir_ / "tum", 6, 64, 48));
    auto source = OpenFrameSource((*dir_ / "tum").string(), SourceOptions());
    folder_intrinsics_ = source->Intrinsics();
    RecordTargets targets;
    targets.oni = *dir_ / "rec.oni";
    RecordFrames(*source, targets, RecordSettings());
  }
  static void TearDownTestSuite() {
    delete folder_frames_;
    delete dir_;
  }
  static fs::path Oni() { return *dir_ / "rec.oni"; }

  static test::TempDir* dir_;
  static std::vector<RgbdFrame>* folder_frames_;
  static CameraIntrinsics folder_intrinsics_;
};
test::TempDir* OniFromTumFolder::dir_ = nullptr;
std::vector<RgbdFrame>* OniFromTumFolder::folder_frames_ = nullptr;
CameraIntrinsics OniFromTumFolder::folder_intrinsics_;

// Reads every frame of one stream with OpenNI2's plain API: manual stepping, no repeat, frames
// counted against getNumberOfFrames, every wait with a timeout (DESIGN.md §5).
TEST_F(OniFromTumFolder, PlaysInOpenNI2sOwnPlayer) {
  ASSERT_EQ(openni::OpenNI::initialize(), openni::STATUS_OK);
  openni::Device device;
  ASSERT_EQ(device.open(Oni().c_str()), openni::STATUS_OK) << openni::OpenNI::getExtendedError();
  ASSERT_TRUE(device.isFile());
  ASSERT_TRUE(device.hasSensor(openni::SENSOR_DEPTH));
  ASSERT_TRUE(device.hasSensor(openni::SENSOR_COLOR));
  // Streams wrapped without ownership of their handles, which are left alone at the end (see
  // there): the C++ wrapper of a stream made with create() destroys it in its destructor.
  OniStreamHandle depth_handle = nullptr, color_handle = nullptr;
  ASSERT_EQ(oniDeviceCreateStream(device._getHandle(), ONI_SENSOR_DEPTH, &depth_handle),
            ONI_STATUS_OK);
  ASSERT_EQ(oniDeviceCreateStream(device._getHandle(), ONI_SENSOR_COLOR, &color_handle),
            ONI_STATUS_OK);
  openni::VideoStream depth(depth_handle), color(color_handle);
  EXPECT_EQ(depth.getVideoMode().getResolutionX(), 64);
  EXPECT_EQ(depth.getVideoMode().getResolutionY(), 48);
  EXPECT_EQ(depth.getVideoMode().getPixelFormat(), openni::PIXEL_FORMAT_DEPTH_1_MM);
  EXPECT_EQ(color.getVideoMode().getPixelFormat(), openni::PIXEL_FORMAT_RGB888);
  EXPECT_NEAR(depth.getHorizontalFieldOfView(),
              2.0 * std::atan(64.0 / (2.0 * folder_intrinsics_.fx)), 1e-6);
  openni::PlaybackControl* playback = device.getPlaybackControl();
  ASSERT_NE(playback, nullptr);
  playback->setRepeatEnabled(false);
  playback->setSpeed(-1.0f);
  ASSERT_EQ(playback->getNumberOfFrames(depth), 6);
  ASSERT_EQ(playback->getNumberOfFrames(color), 6);
  ASSERT_EQ(depth.start(), openni::STATUS_OK);
  ASSERT_EQ(color.start(), openni::STATUS_OK);

  const OniRecording ours = ReadOniFile(Oni());
  openni::VideoStream* streams[2] = {&depth, &color};
  int depth_frames = 0, color_frames = 0;
  while (depth_frames < 6 || color_frames < 6) {
    int ready = -1;
    ASSERT_EQ(openni::OpenNI::waitForAnyStream(streams, 2, &ready, 2000), openni::STATUS_OK)
        << "after " << depth_frames << " depth and " << color_frames << " colour frames";
    openni::VideoFrameRef frame;
    ASSERT_EQ(streams[ready]->readFrame(&frame), openni::STATUS_OK);
    const int index = frame.getFrameIndex();
    ASSERT_GE(index, 1);
    ASSERT_LE(index, 6);
    const OniRawFrame& expected = ours.frames[index - 1];
    EXPECT_EQ(frame.getTimestamp(), expected.timestamp_us);
    if (ready == 0) {
      ++depth_frames;
      ASSERT_EQ(frame.getDataSize(), 64 * 48 * 2);
      EXPECT_EQ(std::memcmp(frame.getData(), expected.depth_mm.data(), 64 * 48 * 2), 0)
          << "depth frame " << index;
    } else {
      ++color_frames;
      ASSERT_EQ(frame.getDataSize(), 64 * 48 * 3);
      EXPECT_EQ(std::memcmp(frame.getData(), expected.color_rgb.data(), 64 * 48 * 3), 0)
          << "colour frame " << index;
    }
  }
  // At the end: no further frame arrives (and waiting does not hang).
  int ready = -1;
  EXPECT_EQ(openni::OpenNI::waitForAnyStream(streams, 2, &ready, 300), openni::STATUS_TIME_OUT);
  // The recording has played to its end: stop, close the device, and leave the two stream
  // handles alone. Destroying a stream of an open recording races with the OniFile driver's
  // player thread, which walks its stream list without a lock (SIGSEGV now and then under
  // ctest -j2), and destroying it after the device is closed touches freed memory (valgrind).
  // OpenNI2Source::Close (capture/openni2_source.cpp) has the details and the other cases.
  depth.stop();
  color.stop();
  device.close();
}

TEST_F(OniFromTumFolder, SourceGivesTheFolderFramesBack) {
  auto source = OpenAnySource(Oni().string(), SourceOptions());
  EXPECT_EQ(source->FrameCount(), 6u);
  EXPECT_CONTAINS(source->Describe(), "OpenNI2 recording");
  // Exact intrinsics from the recording (gsIntrinsics), including the off-centre principal point.
  EXPECT_EQ(source->Intrinsics().fx, folder_intrinsics_.fx);
  EXPECT_EQ(source->Intrinsics().cx, folder_intrinsics_.cx);
  EXPECT_EQ(source->Intrinsics().cy, folder_intrinsics_.cy);
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), folder_frames_->size());
  const CameraResponse srgb;
  for (size_t f = 0; f < frames.size(); ++f) {
    const RgbdFrame& a = frames[f];
    const RgbdFrame& b = (*folder_frames_)[f];
    EXPECT_NEAR(a.timestamp, b.timestamp, 0.5e-6) << "frame " << f;
    ASSERT_TRUE(a.depth.SameSize(b.depth));
    size_t depth_diff = 0, color_diff = 0;
    double max_linear_diff = 0.0;
    for (size_t i = 0; i < a.depth.size(); ++i) {
      // Depth to the millimetre: the .oni holds round(z * 1000) mm.
      depth_diff +=
          std::lround(a.depth.pixels()[i] * 1000.0) != std::lround(b.depth.pixels()[i] * 1000.0);
      depth_diff +=
          std::abs(a.depth.pixels()[i] * 1000.0 - std::lround(a.depth.pixels()[i] * 1000.0)) > 1e-3;
      for (int c = 0; c < 3; ++c) {
        color_diff += std::lround(srgb.FromLinear(a.color.pixels()[i][c]) * 255.0f) !=
                      std::lround(srgb.FromLinear(b.color.pixels()[i][c]) * 255.0f);
        max_linear_diff = std::max<double>(
            max_linear_diff, std::abs(a.color.pixels()[i][c] - b.color.pixels()[i][c]));
      }
    }
    EXPECT_EQ(depth_diff, 0u) << "frame " << f;
    EXPECT_EQ(color_diff, 0u) << "frame " << f;
    EXPECT_LT(max_linear_diff, 1e-6) << "frame " << f;
  }
  // After the last frame the source says so at once, again and again.
  EXPECT_FALSE(source->Next().has_value());
  EXPECT_FALSE(source->Next().has_value());
}

// A recording made with mirroring on (xnMirror = 1, frames stored flipped, as NiViewer records)
// reads back as the same frames as the recording made without it: the room, not its mirror image.
TEST_F(OniFromTumFolder, MirroredRecordingReadsAsTheUnmirroredOne) {
  const fs::path mirrored = *dir_ / "mirrored.oni";
  {
    auto source = OpenFrameSource((*dir_ / "tum").string(), SourceOptions());
    RecordSettings settings;
    settings.mirror = true;
    RecordTargets targets;
    targets.oni = mirrored;
    RecordFrames(*source, targets, settings);
  }
  const OniFileInfo info = InspectOniFile(mirrored);
  EXPECT_TRUE(info.FindNode(kOniNodeDepth)->mirrored);
  EXPECT_TRUE(info.FindNode(kOniNodeImage)->mirrored);
  EXPECT_FALSE(InspectOniFile(Oni()).FindNode(kOniNodeDepth)->mirrored);
  const auto plain = ReadAllFrames(*OpenAnySource(Oni().string(), SourceOptions()));
  const auto flipped_back = ReadAllFrames(*OpenAnySource(mirrored.string(), SourceOptions()));
  ASSERT_EQ(plain.size(), flipped_back.size());
  for (size_t f = 0; f < plain.size(); ++f) {
    EXPECT_EQ(plain[f].depth.pixels(), flipped_back[f].depth.pixels()) << "frame " << f;
    EXPECT_EQ(plain[f].color.pixels(), flipped_back[f].color.pixels()) << "frame " << f;
  }
  // The frames as stored: every row reversed.
  const OniRecording stored = ReadOniFile(mirrored), straight = ReadOniFile(Oni());
  const int w = plain[0].depth.width();
  for (int v = 0; v < plain[0].depth.height(); ++v) {
    for (int u = 0; u < w; ++u) {
      EXPECT_EQ(stored.frames[0].depth_mm[v * w + u],
                straight.frames[0].depth_mm[v * w + w - 1 - u])
          << u << ", " << v;
      EXPECT_EQ(stored.frames[0].color_rgb[3 * (v * w + u) + 1],
                straight.frames[0].color_rgb[3 * (v * w + w - 1 - u) + 1]);
    }
  }
}

TEST_F(OniFromTumFolder, FrameSelectionAndGivenIntrinsicsApply) {
  SourceOptions options;
  options.first_frame = 1;
  options.stride = 2;
  options.max_frames = 2;
  options.intrinsics = (*dir_ / "k.txt").string();
  test::WriteFile(*dir_ / "k.txt", "50 51 31.5 23.5 64 48\n");
  auto source = OpenAnySource(Oni().string(), options);
  EXPECT_EQ(source->FrameCount(), 2u);
  EXPECT_EQ(source->Intrinsics().fx, 50.0);
  const auto frames = ReadAllFrames(*source);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_NEAR(frames[0].timestamp, (*folder_frames_)[1].timestamp, 0.5e-6);
  EXPECT_NEAR(frames[1].timestamp, (*folder_frames_)[3].timestamp, 0.5e-6);
}

TEST_F(OniFromTumFolder, CoreReaderPointsToTheCaptureLibrary) {
  EXPECT_CONTAINS(ErrorOf([&] { OpenFrameSource(Oni().string(), SourceOptions()); }), "capture");
}

TEST(OpenNI2Source, DamagedRecordingsAreClearErrorsNotHangs) {
  test::TempDir dir;
  test::MakeTumFolder(dir / "tum", 3, 32, 24);
  auto folder = OpenFrameSource((dir / "tum").string(), SourceOptions());
  RecordTargets targets;
  targets.oni = dir / "good.oni";
  RecordFrames(*folder, targets, RecordSettings());
  const std::string bytes = ReadTextFile(dir / "good.oni");

  test::WriteFile(dir / "truncated.oni", bytes.substr(0, bytes.size() / 2));
  EXPECT_CONTAINS(
      ErrorOf([&] { OpenAnySource((dir / "truncated.oni").string(), SourceOptions()); }),
      "truncated");
  test::WriteFile(dir / "notoni.oni", "P5\n32 24\n255\n");
  EXPECT_CONTAINS(ErrorOf([&] { OpenAnySource((dir / "notoni.oni").string(), SourceOptions()); }),
                  "not an OpenNI .oni recording");

  OniLayout layout;
  layout.width = 32, layout.height = 24, layout.intrinsics = folder->Intrinsics();
  std::vector<OniRawFrame> raw(2);
  for (auto& f : raw) f.depth_mm.assign(32 * 24, 1000), f.color_rgb.assign(32 * 24 * 3, 128);
  raw[1].timestamp_us = 33333;
  layout.write_cropping = false;
  WriteOniFile(dir / "no_crop.oni", layout, raw);
  EXPECT_CONTAINS(ErrorOf([&] { OpenAnySource((dir / "no_crop.oni").string(), SourceOptions()); }),
                  "has no xnCropping property");
  layout.write_cropping = true;
  layout.with_color = false;
  for (auto& f : raw) f.color_rgb.clear();
  WriteOniFile(dir / "depth_only.oni", layout, raw);
  EXPECT_CONTAINS(
      ErrorOf([&] { OpenAnySource((dir / "depth_only.oni").string(), SourceOptions()); }),
      "has a depth stream but no colour stream");
  EXPECT_CONTAINS(ErrorOf([&] { OpenAnySource((dir / "absent.oni").string(), SourceOptions()); }),
                  "no such file");
}

TEST(OpenNI2Source, NoCameraIsOneClearError) {
  // Recordings opened by earlier tests stay listed by OpenNI2 as devices; they must not count.
  if (!ListCameraUris().empty())
    GTEST_SKIP() << "a camera is attached; the no-camera path cannot be tested here";
  EXPECT_EQ(ErrorOf([&] { OpenAnySource("openni2", SourceOptions()); }), kNoDeviceMessage);
  EXPECT_EQ(ErrorOf([&] { OpenAnySource("openni2:", SourceOptions()); }), kNoDeviceMessage);
}

TEST(OpenNI2Source, OptionsAreValidated) {
  CaptureOptions capture;
  capture.mode = "1280x720";
  EXPECT_CONTAINS(ErrorOf([&] { capture.Validate(); }), "1280x720");
  capture.mode = "320x240";
  EXPECT_NO_THROW(capture.Validate());
  EXPECT_EQ(capture.Width(), 320);
  EXPECT_EQ(capture.Height(), 240);
  EXPECT_TRUE(IsOpenNI2Spec("openni2"));
  EXPECT_TRUE(IsOpenNI2Spec("openni2:freenect://0"));
  EXPECT_TRUE(IsOpenNI2Spec("a/b/REC.ONI"));
  EXPECT_FALSE(IsOpenNI2Spec("data/tum"));
  EXPECT_FALSE(IsOpenNI2Spec("openni2_data"));
}

}  // namespace
}  // namespace genscene::capture
