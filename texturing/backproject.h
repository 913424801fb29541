// Texturing (DESIGN.md §2): the observed colour of the mesh as Mesh Colors, back-projected from
// posed keyframes.
//
// For every texel (Mesh Colors sample) and every keyframe:
//   visible   <=> the texel projects inside the image, faces the camera within max_view_angle,
//                 is not behind the mesh's own z-buffer by more than the depth tolerance (occlusion
//                 by other geometry), not behind the keyframe's measured depth either (occluders
//                 the mesh lacks), and not within edge_margin pixels of a depth discontinuity of
//                 the z-buffer or of the measured depth;
//   sample    =  the keyframe's linear colour, bilinear at the projected point;
//   weight    =  cos(view angle) / z^2 * sharpness, where sharpness is the keyframe's variance of
//                the Laplacian of luminance relative to the sharpest keyframe, at least 0.25
//                (blurred frames count less).
// The texel's colour is a robust weighted mean: the median luminance m of its samples (one vote
// per view, so that one heavily weighted view cannot carry its highlight) is found, samples whose
// luminance is outside m (1 +- outlier_ratio) are dropped (specular highlights, misregistration),
// and the rest are averaged with their weights. (Two views that disagree beyond the ratio: the
// darker is kept, highlights being the likelier outlier.) Texels no keyframe sees are filled
// from their lattice neighbours and counted.
//
// Resolution: each face gets the smallest power-of-two resolution whose sample spacing is at most
// texel_spacing, but no finer than the finest pixel footprint (z / f) any keyframe has on it:
// samples denser than the images cannot hold detail, and faces no keyframe sees get R = 1.
#pragma once

#include <vector>

#include "core/mesh.h"
#include "core/mesh_colors.h"
#include "core/options.h"
#include "core/rgbd_frame.h"

namespace genscene::texturing {

struct TexturingOptions {
  static constexpr const char* kSection = "texturing";
  double texel_spacing = 0.005;       // target distance between colour samples, meters
  int max_resolution = 64;            // largest per-face resolution (power of two)
  bool limit_to_image_detail = true;  // no sample spacing finer than the keyframes' pixel footprint
  double depth_tolerance = 0.01;      // texel counts as visible within this of the z-buffer, meters
  double depth_tolerance_ratio = 0.02;  // ... or this fraction of its depth, whichever is larger
  bool use_sensor_depth = true;         // also test against the keyframe's measured depth
  double depth_jump_ratio = 0.05;       // a depth discontinuity: neighbours differ by this x depth
  int edge_margin =
      2;  // pixels around discontinuities not used (at most 1/40 of the image's smaller side), px
  double max_view_angle = 75.0;  // samples seen at a more grazing angle are not used, degrees
  double outlier_ratio = 0.25;   // keep samples within m (1 +- this) of the median luminance

  template <typename V>
  void Visit(V&& v) {
    v("texel_spacing", texel_spacing, "m", "target distance between colour samples");
    v("max_resolution", max_resolution, "",
      "largest per-face Mesh Colors resolution (power of two)");
    v("limit_to_image_detail", limit_to_image_detail, "",
      "no texel spacing finer than the keyframes' pixel footprint");
    v("depth_tolerance", depth_tolerance, "m",
      "visibility: largest distance behind the z-buffer still visible");
    v("depth_tolerance_ratio", depth_tolerance_ratio, "",
      "visibility tolerance as a fraction of depth (the larger applies)");
    v("use_sensor_depth", use_sensor_depth, "",
      "also test visibility against the keyframes' measured depth");
    v("depth_jump_ratio", depth_jump_ratio, "",
      "neighbouring depths differing by this fraction are a discontinuity");
    v("edge_margin", edge_margin, "px",
      "pixels around depth discontinuities that are not used (at most 1/40 of the image's smaller "
      "side)");
    v("max_view_angle", max_view_angle, "deg", "most grazing view angle used");
    v("outlier_ratio", outlier_ratio, "",
      "samples farther than this fraction from the median luminance are dropped");
  }
  void Validate() const;
};

struct TexturingStats {
  size_t texels = 0;            // Mesh Colors samples
  size_t observed = 0;          // texels seen by at least one keyframe
  size_t filled = 0;            // texels no keyframe sees, filled from neighbours
  size_t unreached = 0;         // texels of mesh parts no keyframe sees at all: the mean colour
  size_t isolated = 0;          // texels on vertices without faces: left black
  size_t samples_used = 0;      // keyframe samples averaged in
  size_t samples_rejected = 0;  // keyframe samples dropped as outliers
  int keyframes = 0;
  int keyframes_seeing_mesh = 0;
  double seconds_visibility = 0.0;  // z-buffers and edge masks
  double seconds_backproject = 0.0;
};

struct TexturingResult {
  // Linear RGB observed colour; labels() = the number of keyframe samples averaged into each
  // texel (0 = not observed: filled from neighbours), which the albedo stage reads.
  MeshColors texture;
  TexturingStats stats;
};

// Keyframes: colour (linear RGB), optional depth, intrinsics and world_from_camera (required).
// Throws Error when the mesh is empty or invalid, there are no keyframes, a keyframe has no pose
// or no colour, or no keyframe sees any of the mesh.
TexturingResult TextureMesh(const TriangleMesh& mesh, const std::vector<RgbdFrame>& keyframes,
                            const TexturingOptions& options);

}  // namespace genscene::texturing
