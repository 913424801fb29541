// genscene-synth as a function: a synthetic RGB-D sequence with exact ground truth, written as a
// TUM folder (rgb/, depth/, rgb.txt, depth.txt, groundtruth.txt, intrinsics.txt, mesh_gt.ply).
// Shared by the genscene-synth app and `genscene demo`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace genscene::apps {

struct SynthOptions {
  static constexpr const char* kSection = "synth";

  std::string scene = "cornell";  // built-in scene (cornell); room and Mitsuba XML come with issue 3
  int frames = 30;                // number of frames
  std::string size = "160x120";   // image size WxH in pixels
  std::string noise = "none";     // depth noise: none, or kinect (axial Kinect v1 model)
  double fov = 60.0;              // horizontal field of view, degrees
  double arc = 60.0;              // the camera orbits the scene centre over this arc, degrees

  template <typename V>
  void Visit(V&& v) {
    v("scene", scene, "", "built-in scene: cornell");
    v("frames", frames, "", "number of frames");
    v("size", size, "px", "image size WxH");
    v("noise", noise, "", "depth noise: none or kinect");
    v("fov", fov, "deg", "horizontal field of view");
    v("arc", arc, "deg", "arc the camera orbits over");
  }
  void Validate() const;
  int Width() const;
  int Height() const;
};

struct SynthSummary {
  int frames = 0;
  int width = 0, height = 0;
  double min_depth = 0.0, max_depth = 0.0;  // meters, over valid pixels
  size_t mesh_vertices = 0, mesh_faces = 0;
};

// Renders and writes the sequence to `out_dir` (atomically: complete or absent).
SynthSummary Synthesize(const SynthOptions& options, uint64_t seed, const std::filesystem::path& out_dir);

}  // namespace genscene::apps
