// The .oni container as written and read by genscene's own code (capture/oni_format.h): exact
// round trips of depth (millimetres), colour (8-bit) and time stamps (microseconds), the byte
// layout of DESIGN.md §6, and clear errors on damaged files.
#include "capture/oni_format.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>

#include "capture/record.h"
#include "core/check.h"
#include "core/file_util.h"
#include "tests/capture/capture_test_util.h"
#include "tests/test_util.h"

namespace genscene::capture {
namespace {

namespace fs = std::filesystem;
using test::ErrorOf;

OniLayout SmallLayout(int w, int h, bool with_color = true) {
  OniLayout layout;
  layout.width = w, layout.height = h, layout.with_color = with_color;
  layout.intrinsics.width = w, layout.intrinsics.height = h;
  layout.intrinsics.fx = layout.intrinsics.fy = 1.1 * w;
  layout.intrinsics.cx = 0.5 * (w - 1), layout.intrinsics.cy = 0.5 * (h - 1);
  return layout;
}

// Frames whose every value is known: depth (u + 7 v + 100 f) mm, colour bytes from a hash.
std::vector<OniRawFrame> PatternFrames(int w, int h, int count, bool with_color = true) {
  std::vector<OniRawFrame> frames(count);
  for (int f = 0; f < count; ++f) {
    frames[f].timestamp_us = 1000000ull * 1305031102ull + 33333ull * f;
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u)
        frames[f].depth_mm.push_back(static_cast<uint16_t>(u + 7 * v + 100 * f));
    }
    if (with_color) {
      for (int i = 0; i < 3 * w * h; ++i)
        frames[f].color_rgb.push_back(static_cast<uint8_t>((i * 2654435761u + f) >> 7));
    }
  }
  return frames;
}

std::string ReadBytes(const fs::path& path) {
  return ReadTextFile(path);
}

TEST(OniFormat, WriterFollowsTheDesignLayout) {
  test::TempDir dir;
  const fs::path oni = dir / "a.oni";
  WriteOniFile(oni, SmallLayout(4, 3), PatternFrames(4, 3, 2));
  const std::string bytes = ReadBytes(oni);
  ASSERT_GT(bytes.size(), 24u + 28u);
  // File header: "NI10", version 1.0.1.0 as u8 u8 u16 u32, u64 max timestamp, u32 max node id.
  EXPECT_EQ(bytes.substr(0, 4), "NI10");
  EXPECT_EQ(bytes.substr(4, 8), std::string("\x01\x00\x01\x00\x00\x00\x00\x00", 8));
  uint64_t max_ts;
  uint32_t max_node;
  std::memcpy(&max_ts, bytes.data() + 12, 8);
  std::memcpy(&max_node, bytes.data() + 20, 4);
  EXPECT_EQ(max_ts, 1000000ull * 1305031102ull + 33333ull);
  EXPECT_EQ(max_node, 1u);
  // First record: NodeAdded (13) for node 0 named "Depth", type 2, codec "NONE", 2 frames.
  EXPECT_EQ(bytes.substr(24, 4), std::string("NIR\0", 4));
  uint32_t type, node, fields, payload, name_len, node_type, frames;
  std::memcpy(&type, bytes.data() + 28, 4);
  std::memcpy(&node, bytes.data() + 32, 4);
  std::memcpy(&fields, bytes.data() + 36, 4);
  std::memcpy(&payload, bytes.data() + 40, 4);
  std::memcpy(&name_len, bytes.data() + 52, 4);
  EXPECT_EQ(type, 13u);
  EXPECT_EQ(node, 0u);
  EXPECT_EQ(payload, 0u);
  EXPECT_EQ(name_len, 6u);
  EXPECT_EQ(bytes.substr(56, 6), std::string("Depth\0", 6));
  std::memcpy(&node_type, bytes.data() + 62, 4);
  EXPECT_EQ(node_type, 2u);
  EXPECT_EQ(bytes.substr(66, 4), "NONE");
  std::memcpy(&frames, bytes.data() + 70, 4);
  EXPECT_EQ(frames, 2u);
  EXPECT_EQ(fields, 28u + 4 + 6 + 4 + 4 + 4 + 8 + 8 + 8);
  // The file ends with an End record (type 11).
  std::memcpy(&type, bytes.data() + bytes.size() - 28 + 4, 4);
  EXPECT_EQ(bytes.substr(bytes.size() - 28, 4), std::string("NIR\0", 4));
  EXPECT_EQ(type, 11u);
}

TEST(OniFormat, OwnReaderRoundTripsEveryValue) {
  test::TempDir dir;
  const auto frames = PatternFrames(5, 4, 3);
  WriteOniFile(dir / "a.oni", SmallLayout(5, 4), frames);
  const OniRecording rec = ReadOniFile(dir / "a.oni");
  EXPECT_EQ(rec.width, 5);
  EXPECT_EQ(rec.height, 4);
  ASSERT_EQ(rec.frames.size(), 3u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(rec.frames[i].timestamp_us, frames[i].timestamp_us);
    EXPECT_EQ(rec.frames[i].depth_mm, frames[i].depth_mm);
    EXPECT_EQ(rec.frames[i].color_rgb, frames[i].color_rgb);
  }
  const OniNodeInfo* depth = rec.info.FindNode(kOniNodeDepth);
  const OniNodeInfo* color = rec.info.FindNode(kOniNodeImage);
  ASSERT_TRUE(depth && color);
  EXPECT_EQ(depth->codec, "NONE");
  EXPECT_EQ(depth->pixel_format, kOniPixelDepth1Mm);
  EXPECT_EQ(color->pixel_format, kOniPixelRgb888);
  EXPECT_EQ(depth->required_frame_size, 5u * 4u * 2u);
  EXPECT_EQ(color->required_frame_size, 5u * 4u * 3u);
  EXPECT_TRUE(depth->has_cropping && color->has_cropping);
  ASSERT_TRUE(depth->map_output_mode.has_value());
  EXPECT_EQ((*depth->map_output_mode)[0], 5u);
  EXPECT_EQ((*depth->map_output_mode)[1], 4u);
  EXPECT_EQ((*depth->map_output_mode)[2], 30u);
  // Field of view of fx = 1.1 W: hfov = 2 atan(W / (2 fx)) = 2 atan(1 / 2.2).
  ASSERT_TRUE(depth->field_of_view.has_value());
  EXPECT_NEAR((*depth->field_of_view)[0], 2.0 * std::atan(1.0 / 2.2), 1e-12);
  EXPECT_EQ(depth->min_timestamp_us, frames.front().timestamp_us);
  EXPECT_EQ(depth->max_timestamp_us, frames.back().timestamp_us);
}

TEST(OniFormat, TumFolderToOniKeepsDepthColourAndTimestamps) {
  test::TempDir dir;
  const auto folder_frames = test::MakeTumFolder(dir / "tum", 5, 40, 30);
  auto source = OpenFrameSource((dir / "tum").string(), SourceOptions());
  RecordTargets targets;
  targets.oni = dir / "rec.oni";
  const RecordSummary summary = RecordFrames(*source, targets, RecordSettings());
  EXPECT_EQ(summary.frames, 5u);
  const OniRecording rec = ReadOniFile(dir / "rec.oni");
  ASSERT_EQ(rec.frames.size(), folder_frames.size());
  const CameraResponse srgb;
  for (size_t f = 0; f < rec.frames.size(); ++f) {
    const RgbdFrame& expected = folder_frames[f];
    EXPECT_EQ(rec.frames[f].timestamp_us,
              static_cast<uint64_t>(std::llround(expected.timestamp * 1e6)));
    size_t depth_diff = 0, color_diff = 0, valid = 0;
    for (size_t i = 0; i < expected.depth.size(); ++i) {
      const auto mm = static_cast<uint16_t>(std::lround(expected.depth.pixels()[i] * 1000.0));
      depth_diff += rec.frames[f].depth_mm[i] != mm;
      valid += mm > 0;
      for (int c = 0; c < 3; ++c) {
        const auto code = static_cast<uint8_t>(
            std::lround(srgb.FromLinear(expected.color.pixels()[i][c]) * 255.0f));
        color_diff += rec.frames[f].color_rgb[3 * i + c] != code;
      }
    }
    EXPECT_EQ(depth_diff, 0u) << "frame " << f;
    EXPECT_EQ(color_diff, 0u) << "frame " << f;
    EXPECT_GT(valid, expected.depth.size() / 2);
  }
  // The exact intrinsics travel in gsIntrinsics (the field of view alone loses the offset centre).
  const OniNodeInfo* depth = rec.info.FindNode(kOniNodeDepth);
  ASSERT_TRUE(depth->gs_intrinsics.has_value());
  EXPECT_EQ((*depth->gs_intrinsics)[2], source->Intrinsics().cx);
  EXPECT_EQ((*depth->gs_intrinsics)[3], source->Intrinsics().cy);
}

TEST(OniFormat, DepthBeyondSixteenBitMillimetresIsAnErrorNotAWrap) {
  RgbdFrame frame;
  frame.depth = ImageDepth(2, 2, 1.0f);
  frame.depth(1, 0) = 70.0f;  // 70000 mm > 65535
  EXPECT_CONTAINS(ErrorOf([&] { ToOniRawFrame(frame, CameraResponse()); }),
                  "does not fit in 16-bit millimetres");
  frame.depth(1, 0) = 65.535f;
  EXPECT_EQ(ToOniRawFrame(frame, CameraResponse()).depth_mm[1], 65535);
}

TEST(OniFormat, FailedWriteLeavesNoFile) {
  test::TempDir dir;
  auto frames = PatternFrames(4, 3, 3);
  frames[2].depth_mm.pop_back();  // the third frame is malformed
  EXPECT_CONTAINS(ErrorOf([&] { WriteOniFile(dir / "a.oni", SmallLayout(4, 3), frames); }),
                  "frame 3: depth has 11 pixels");
  EXPECT_FALSE(fs::exists(dir / "a.oni"));
  EXPECT_EQ(test::CountFilesContaining(dir.path(), ".oni"), 0);
}

TEST(OniFormat, DamagedFilesGiveClearErrors) {
  test::TempDir dir;
  WriteOniFile(dir / "good.oni", SmallLayout(4, 3), PatternFrames(4, 3, 3));
  const std::string bytes = ReadBytes(dir / "good.oni");
  EXPECT_NO_THROW(RequirePlayableRgbd(InspectOniFile(dir / "good.oni")));

  // Cut in the middle of a frame's payload, at a record boundary (no end record), in the header.
  for (size_t keep : {bytes.size() - 40, bytes.size() - 28, size_t{30}, size_t{10}}) {
    test::WriteFile(dir / "cut.oni", bytes.substr(0, keep));
    EXPECT_CONTAINS(ErrorOf([&] { InspectOniFile(dir / "cut.oni"); }), "truncated");
  }
  // Not a recording at all.
  test::WriteFile(dir / "text.oni", "timestamp filename\n0.0 rgb/0.png\n");
  EXPECT_CONTAINS(ErrorOf([&] { InspectOniFile(dir / "text.oni"); }),
                  "not an OpenNI .oni recording");
  test::WriteFile(dir / "empty.oni", "");
  EXPECT_CONTAINS(ErrorOf([&] { InspectOniFile(dir / "empty.oni"); }),
                  "not an OpenNI .oni recording");
  EXPECT_CONTAINS(ErrorOf([&] { InspectOniFile(dir / "missing.oni"); }), "no such file");

  // Depth only.
  WriteOniFile(dir / "depth_only.oni", SmallLayout(4, 3, false), PatternFrames(4, 3, 2, false));
  EXPECT_CONTAINS(ErrorOf([&] { RequirePlayableRgbd(InspectOniFile(dir / "depth_only.oni")); }),
                  "has a depth stream but no colour stream");
  // No xnCropping.
  OniLayout no_crop = SmallLayout(4, 3);
  no_crop.write_cropping = false;
  WriteOniFile(dir / "no_crop.oni", no_crop, PatternFrames(4, 3, 2));
  EXPECT_CONTAINS(ErrorOf([&] { RequirePlayableRgbd(InspectOniFile(dir / "no_crop.oni")); }),
                  "stream 'Depth' has no xnCropping property");
  // A frame count that disagrees with the data (byte 70 holds the depth node's frame count).
  std::string wrong_count = bytes;
  wrong_count[70] = 9;
  test::WriteFile(dir / "count.oni", wrong_count);
  EXPECT_CONTAINS(ErrorOf([&] { InspectOniFile(dir / "count.oni"); }),
                  "declares 9 frames but holds 3");
}

}  // namespace
}  // namespace genscene::capture
