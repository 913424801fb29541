// OpenGL 3.3 core renderer of a ViewData: the mesh with its Mesh Colors evaluated per fragment
// (not baked to vertex colours), and the overlay of trajectory, keyframe frusta and light glyphs.
// Needs a current OpenGL 3.3 core context (gl_context.h); no GL type appears in this header.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "core/image.h"
#include "core/view_set.h"
#include "viewer/view_data.h"

namespace genscene::viewer {

// What the mesh shows.
enum class ColorMode {
  kObserved,  // texture.mcol: the observed colour (shading included)
  kAlbedo,    // albedo.mcol
  kShading,   // observed / albedo per channel: the light the surface received
  kClusters,  // albedo.mcol's labels (cluster ids) as false colours
  kGeometry,  // grey with a headlight (no Mesh Colors needed)
};
const char* ColorModeName(ColorMode mode);
// "color" (or "observed"), "albedo", "shading", "clusters", "geometry"; throws Error otherwise.
ColorMode ParseColorMode(const std::string& text);

enum class Lookup { kNearest, kLinear };  // MeshColors::Nearest / MeshColors::Linear

struct DrawOptions {
  ColorMode mode = ColorMode::kObserved;
  Lookup lookup = Lookup::kNearest;
  bool cull_back_faces = false;  // hide faces seen from behind (see into a room from outside)
  bool show_overlay = true;      // trajectory, frusta, light glyphs
  bool show_refined = false;     // mesh_refined.ply's vertices instead of mesh.ply's
  bool encode_srgb = true;       // write sRGB (on screen) or linear (float offscreen target)
  Eigen::Vector3f background{0.08f, 0.08f, 0.1f};  // linear RGB
};

class Renderer {
 public:
  // Uploads the mesh, both Mesh Colors fields and the overlay. Throws Error when the context is
  // older than OpenGL 3.3 or a shader does not compile (with the driver's log).
  explicit Renderer(const ViewData& data);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Whether `mode` has the data it needs (e.g. kShading needs both fields).
  bool Supports(ColorMode mode) const;
  bool HasRefinedMesh() const;
  // The hook for light estimation: replaces the light glyphs drawn in the overlay.
  void SetLights(const std::vector<LightGlyph>& lights);
  // The bounding box of everything drawn (mesh, cameras, lights), for camera placement.
  Eigen::AlignedBox3d Bounds() const;

  // Draws into the bound framebuffer, viewport = the view's image size.
  void Draw(const PosedView& view, const DrawOptions& options);
  // Renders into an offscreen float framebuffer of the view's size and reads it back as a linear
  // image, row 0 at the top (glReadPixels' bottom-up rows flipped). Ignores encode_srgb.
  ImageRgb RenderImage(const PosedView& view, const DrawOptions& options);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace genscene::viewer
