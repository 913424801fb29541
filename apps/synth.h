// genscene-synth as a function: a synthetic RGB-D sequence with exact ground truth, path-traced,
// written as a TUM folder (rgb/, depth/, rgb.txt, depth.txt, groundtruth.txt, intrinsics.txt,
// linear EXR colour in rgb_linear.txt, the ground-truth mesh mesh_gt.ply and the whole scene as
// scene.json). Shared by the genscene-synth app and `genscene demo`.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "render/path_tracer.h"

namespace genscene::apps {

struct SynthOptions {
  static constexpr const char* kSection = "synth";

  std::string scene = "cornell";  // cornell, room, or a scene file (.xml Mitsuba subset, .json)
  int frames = 30;                // number of frames
  std::string size = "160x120";   // image size WxH in pixels
  std::string noise = "none";     // depth noise: none, or kinect (see core/synthetic.h)
  double fov = 60.0;              // horizontal field of view, degrees
  double arc = 60.0;              // the camera sways along an arc of this many degrees
  render::RenderOptions paths = render::RenderOptions::Paths(16);  // for the colour images

  template <typename V>
  void Visit(V&& v) {
    v("scene", scene, "", "cornell, room, or a scene file (.xml Mitsuba 3 subset, .json genscene)");
    v("frames", frames, "", "number of frames");
    v("size", size, "px", "image size WxH");
    v("noise", noise, "",
      "depth noise: none or kinect (axial noise, disparity steps, edge dropouts)");
    v("fov", fov, "deg", "horizontal field of view");
    v("arc", arc, "deg", "arc the hand-held camera sways along");
    paths.VisitPaths(v, "path-tracing samples per pixel");
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
  double render_seconds = 0.0;
};

// Renders and writes the sequence to `out_dir` (atomically: complete or absent).
SynthSummary Synthesize(const SynthOptions& options, uint64_t seed,
                        const std::filesystem::path& out_dir);

}  // namespace genscene::apps
