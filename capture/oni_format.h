// The OpenNI .oni recording container (DESIGN.md §6), in plain C++: a writer of uncompressed
// recordings (codec "NONE", depth DEPTH_1_MM, colour RGB888) that OpenNI2's own player plays, and a
// reader that inspects any .oni file (records, nodes, properties) and decodes uncompressed frames.
//
// Layout, little-endian. File header: "NI10", version {1, 0, 1, 0} (u8 major, u8 minor,
// u16 maintenance, u32 build), u64 max timestamp, u32 max node id (24 bytes). Then records, each a
// 28-byte header "NIR\0", u32 type, u32 node id, u32 fields size (header + fields), u32 payload
// size, u64 undo position; then its fields and its payload. See oni_format.cpp for each record.
//
// The writer emits, per stream, NodeAdded + the properties the player reads (oniRequiredFrameSize,
// xnMapOutputMode, oniPixelFormat, xnCropping, xnFOV, and our exact intrinsics as gsIntrinsics,
// which OpenNI2 ignores) + StateReady; then DataBegin per stream; then one NewData record per
// frame and stream (depth before colour, same time stamp); then End.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/color.h"
#include "core/rgbd_frame.h"

namespace genscene::capture {

// Node (stream) types of the container (XnPredefinedProductionNodeType).
constexpr uint32_t kOniNodeDepth = 2;
constexpr uint32_t kOniNodeImage = 3;
constexpr uint32_t kOniNodeIr = 5;
// OniPixelFormat values.
constexpr uint32_t kOniPixelDepth1Mm = 100;
constexpr uint32_t kOniPixelDepth100Um = 101;
constexpr uint32_t kOniPixelRgb888 = 200;

// One frame as the container stores it: raw integers, before any unit or colour conversion.
struct OniRawFrame {
  uint64_t timestamp_us = 0;       // microseconds
  std::vector<uint16_t> depth_mm;  // width * height, row-major; 0 = no measurement
  std::vector<uint8_t> color_rgb;  // width * height * 3 (RGB888); empty when there is no colour
};

// What a writer puts in the file header and stream properties.
struct OniLayout {
  int width = 0, height = 0;  // pixels, both streams
  int fps = 30;               // frames per second stored in xnMapOutputMode
  bool with_color = true;     // false: a depth-only recording
  // Exact pinhole intrinsics, stored as gsIntrinsics (fx fy cx cy) and, as OpenNI2 sees them, as
  // field of view: hfov = 2 atan(W / (2 fx)), vfov = 2 atan(H / (2 fy)).
  CameraIntrinsics intrinsics;
  // Test knob: false leaves out xnCropping, which makes OpenNI2's player drop every frame.
  bool write_cropping = true;
  // Mirrored, as NiViewer and many recorders store streams with OpenNI's mirroring on: xnMirror = 1
  // on both streams and every frame stored left-right flipped.
  bool mirrored = false;

  void Validate() const;
};

// Streams frames into a .oni file. Frames go straight to disk; Finish() writes the end record
// and patches frame counts and time stamps into the header records. Callers that want an atomic
// file write through WriteFileAtomically (core/file_util.h) into the temporary path.
class OniWriter {
 public:
  OniWriter(const std::filesystem::path& path, const OniLayout& layout);
  ~OniWriter();
  OniWriter(const OniWriter&) = delete;
  OniWriter& operator=(const OniWriter&) = delete;

  // Appends one frame. Throws Error when its sizes disagree with the layout or time goes backwards.
  void Add(const OniRawFrame& frame);
  // Completes the file. Throws Error when no frame was added.
  void Finish();
  size_t frames() const { return frames_; }

 private:
  struct NodeOffsets {
    uint64_t node_added = 0;  // file offset of the NodeAdded record
    uint64_t data_begin = 0;  // file offset of the DataBegin record
    uint64_t last_data = 0;   // offset of the previous NewData record (undo position), 0 = none
  };
  void WriteHeaderRecords();
  void WriteRecord(uint32_t type, uint32_t node, const std::string& fields, const void* payload,
                   uint32_t payload_size, uint64_t undo);
  void Check(const char* what);

  std::filesystem::path path_;
  OniLayout layout_;
  std::ofstream out_;
  std::vector<NodeOffsets> nodes_;  // 0 = depth, 1 = image
  size_t frames_ = 0;
  uint64_t min_timestamp_ = 0, max_timestamp_ = 0;
  bool finished_ = false;
};

// Writes all frames to `path` atomically (temporary name + rename).
void WriteOniFile(const std::filesystem::path& path, const OniLayout& layout,
                  const std::vector<OniRawFrame>& frames);

// --- Reading ----------------------------------------------------------------------------------

struct OniNodeInfo {
  uint32_t id = 0;
  std::string name;
  uint32_t type = 0;    // kOniNodeDepth, kOniNodeImage, kOniNodeIr, or another node type
  std::string codec;    // 4 characters: "NONE", "16zT", "JPEG", ...
  uint32_t frames = 0;  // frame count declared in NodeAdded
  uint64_t min_timestamp_us = 0, max_timestamp_us = 0;
  uint32_t data_records = 0;  // NewData records actually found for this node
  std::optional<std::array<uint32_t, 3>> map_output_mode;  // width, height, fps
  std::optional<uint32_t> pixel_format;                    // OniPixelFormat
  std::optional<uint64_t> required_frame_size;             // bytes
  bool has_cropping = false;
  bool mirrored = false;  // xnMirror = 1: the frames are stored left-right flipped
  std::optional<std::array<double, 2>> field_of_view;  // horizontal, vertical, radians
  std::optional<std::array<double, 4>> gs_intrinsics;  // fx fy cx cy, written by genscene

  std::string TypeName() const;  // "depth", "colour", "IR" or "type N"
};

struct OniFileInfo {
  std::filesystem::path path;
  std::array<int, 4> version{};  // major, minor, maintenance, build
  uint64_t max_timestamp_us = 0;
  uint32_t max_node_id = 0;
  std::vector<OniNodeInfo> nodes;
  bool has_end_record = false;

  const OniNodeInfo* FindNode(uint32_t type) const;
};

// Reads the file header and walks every record header (payloads are skipped, not read). Throws
// Error naming the file when it is not a .oni recording, a record runs past the end of the file
// (truncated), a record is malformed, or a node's declared frame count disagrees with its data.
OniFileInfo InspectOniFile(const std::filesystem::path& path);

// Throws Error unless OpenNI2's player can play the file into RGB-D frames: one depth and one
// colour stream, each with xnMapOutputMode and xnCropping (without it the player delivers no
// frames, DESIGN.md §5), at least one frame, and a complete file (end record present).
void RequirePlayableRgbd(const OniFileInfo& info);

// Every frame of an uncompressed ("NONE") recording, pairing depth and colour by frame number.
struct OniRecording {
  OniFileInfo info;
  int width = 0, height = 0;
  std::vector<OniRawFrame> frames;
};
OniRecording ReadOniFile(const std::filesystem::path& path);

// --- Conversions between container frames and RgbdFrame ---------------------------------------

// Depth in meters -> millimetres (rounded), linear colour -> 8-bit with `response`. Throws Error
// when a depth does not fit in 16-bit millimetres (it would wrap) or the time stamp is negative.
OniRawFrame ToOniRawFrame(const RgbdFrame& frame, const CameraResponse& response);

// The intrinsics OpenNI2 reports for a stream: focal lengths from the field of view, principal
// point at the image centre (cx = (W-1)/2, DESIGN.md §1).
CameraIntrinsics IntrinsicsFromFieldOfView(double hfov_rad, double vfov_rad, int width, int height);

}  // namespace genscene::capture
