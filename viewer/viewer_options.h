// Options of genscene-view (DESIGN.md §3 options pattern: flags and config section "view").
#pragma once

#include <Eigen/Core>
#include <string>

#include "core/options.h"

namespace genscene::viewer {

struct ViewerOptions {
  static constexpr const char* kSection = "view";

  std::string screenshot;           // render one frame into this PNG and exit ("" = open a window)
  std::string camera = "overview";  // overview, keyframe:N, or "tx ty tz qx qy qz qw"
  std::string mode = "";         // color, albedo, shading, clusters, geometry ("" = best available)
  std::string size = "960x720";  // window or screenshot size WxH
  std::string lookup = "nearest";  // Mesh Colors lookup: nearest or linear
  bool cull_back_faces = false;    // hide faces seen from behind
  bool no_overlay = false;         // hide trajectory, keyframe frusta and light glyphs
  bool refined = false;  // mesh_refined.ply's vertices instead of mesh.ply's (R in the window)

  template <typename V>
  void Visit(V&& v) {
    v("screenshot", screenshot, "", "render one frame offscreen into this PNG (sRGB) and exit");
    v("camera", camera, "",
      "overview, keyframe:N (0-based), or a pose 'tx ty tz qx qy qz qw' (world_from_camera)");
    v("mode", mode, "",
      "color (observed), albedo, shading (observed / albedo), clusters, geometry; default: the "
      "first available");
    v("size", size, "px", "window or screenshot size WxH");
    v("lookup", lookup, "", "Mesh Colors lookup per fragment: nearest or linear");
    v("cull_back_faces", cull_back_faces, "",
      "hide faces seen from behind (look into a room from outside)");
    v("no_overlay", no_overlay, "", "hide the trajectory, keyframe frusta and light glyphs");
    v("refined", refined, "",
      "show the refined mesh (mesh_refined.ply) instead of mesh.ply; R toggles it in the window");
  }
  // Throws Error naming the flag and value when one is malformed.
  void Validate() const;
};

}  // namespace genscene::viewer
