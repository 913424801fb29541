// Sequence readers behind one interface. Fusion and every other consumer read frames through
// FrameSource and never know where they came from: a TUM folder, a view set (DESIGN.md §2), an
// Open3D/Redwood folder, and (capture/openni2_source.h) a .oni recording or a live OpenNI2 camera.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/options.h"
#include "core/rgbd_frame.h"
#include "core/trajectory.h"

namespace genscene {

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // One line for logs: "TUM folder data/fr1 (9 frames, 640x480)".
  virtual std::string Describe() const = 0;
  // Number of frames, when known in advance (std::nullopt for a live camera).
  virtual std::optional<size_t> FrameCount() const = 0;
  virtual const CameraIntrinsics& Intrinsics() const = 0;
  // The next frame, decoded and validated; std::nullopt after the last one.
  virtual std::optional<RgbdFrame> Next() = 0;
  // The known poses of the sequence (ground truth or given), empty when there are none.
  virtual const Trajectory& KnownPoses() const = 0;
  // Frames of a live camera that Next never returned: dropped by the camera, or replaced by newer
  // ones while the reader was busy. 0 for recordings and folders, which give every frame.
  virtual size_t SkippedFrames() const { return 0; }
};

struct SourceOptions {
  static constexpr const char* kSection = "source";

  // Intrinsics: a file (`fx fy cx cy width height`, or Open3D JSON) or a name (tum1, tum2, tum3,
  // primesense). Empty: the source's own (intrinsics.txt or camera JSON in the folder), else the
  // format's default (TUM: tum1 is NOT guessed - TUM folders must say; Redwood: primesense).
  std::string intrinsics;
  // Integer depth units per meter; 0 = the format's default (TUM and view sets 5000, Redwood 1000).
  double depth_scale = 0.0;
  // How integer depth maps to meters: scaled (value / depth_scale), nyu-disparity (NYU Depth v2
  // raw PGM) or sun (SUN RGB-D bit-rotated millimetres).
  std::string depth_encoding = "scaled";
  // How 8-bit colour maps to linear: srgb, linear or gamma:G.
  std::string camera_response = "srgb";
  // TUM: a file of lines `t_rgb rgb_path t_depth depth_path`; empty = associate rgb.txt and
  // depth.txt by nearest timestamps (TUM's associate.py rule).
  std::string associations;
  // Largest rgb-depth time difference accepted by the association, and largest difference between
  // a frame and its ground-truth pose, seconds.
  double max_time_difference = 0.02;
  // Poses file overriding the folder's own (TUM groundtruth.txt / Redwood .log / pose.txt).
  std::string trajectory;
  int first_frame = 0;  // skip frames before this index
  int max_frames = 0;   // read at most this many frames (0 = all)
  int stride = 1;       // take every stride-th frame

  template <typename V>
  void Visit(V&& v) {
    v("intrinsics", intrinsics, "",
      "intrinsics file or name (tum1|tum2|tum3|primesense); empty = the source's own");
    v("depth_scale", depth_scale, "units/m",
      "integer depth units per meter (0 = format default: TUM 5000, Redwood 1000)");
    v("depth_encoding", depth_encoding, "",
      "integer depth to meters: scaled, nyu-disparity or sun");
    v("camera_response", camera_response, "", "8-bit colour to linear: srgb, linear or gamma:G");
    v("associations", associations, "",
      "TUM associations file (t_rgb rgb t_depth depth); empty = match rgb.txt/depth.txt by time");
    v("max_time_difference", max_time_difference, "s",
      "largest rgb-depth and frame-pose time difference");
    v("trajectory", trajectory, "", "poses file overriding the folder's own (TUM or Redwood .log)");
    v("first_frame", first_frame, "", "index of the first frame to read");
    v("max_frames", max_frames, "", "read at most this many frames (0 = all)");
    v("stride", stride, "", "read every stride-th frame");
  }
  void Validate() const;
};

// Opens a source by its specification: a folder (TUM layout with rgb.txt, a view set, a Redwood
// folder with color/ and depth/, or the 7-Scenes / 3DMatch layout), undistorted (Undistorted).
// Throws Error naming the path when it is not recognised, a list is empty or names a missing
// file, or sizes disagree.
std::unique_ptr<FrameSource> OpenFrameSource(const std::string& spec, const SourceOptions& options);

// The source with lens distortion taken out: when its intrinsics carry distortion (k1 k2 p1 p2
// k3, OpenCV's model), every frame's colour (bilinear) and depth (nearest, so that no depth is
// mixed across an edge) are resampled once, at ingest, to the same camera without distortion,
// which Intrinsics() and the frames then report; pixels whose source falls outside the image
// are black and without depth. Other sources are returned as they are.
std::unique_ptr<FrameSource> Undistorted(std::unique_ptr<FrameSource> source);

// Reads every frame of a source (for small sequences and tests).
std::vector<RgbdFrame> ReadAllFrames(FrameSource& source);

}  // namespace genscene
