// A small z-buffer rasterizer for visibility: the planar depth of the nearest mesh surface at
// every pixel centre of a pinhole camera (DESIGN.md §1: pixel (u, v) is the centre of that pixel).
// Triangles are clipped against the near plane in camera space, so large walls that reach behind
// the camera are drawn correctly; depth is interpolated perspective-correctly (1/z is linear in
// the image).
#pragma once

#include <Eigen/Geometry>

#include "core/camera.h"
#include "core/image.h"
#include "core/mesh.h"

namespace genscene::texturing {

// Depth (meters, planar z) of the nearest surface at each pixel centre; 0 where no triangle
// covers the pixel. Both faces of a triangle are drawn (a mesh's back faces occlude too).
ImageDepth RenderDepth(const TriangleMesh& mesh, const CameraIntrinsics& intrinsics,
                       const Eigen::Isometry3d& camera_from_world, double near = 0.01);

// What the camera sees at each pixel centre: depth (0 = nothing), the face (-1 = nothing) and
// the perspective-correct barycentric point (b1, b2) on it, for rendering Mesh Colors.
struct SurfaceImage {
  ImageDepth depth;
  Image<int> face;
  ImageDepth b1, b2;
};
SurfaceImage RenderSurface(const TriangleMesh& mesh, const CameraIntrinsics& intrinsics,
                           const Eigen::Isometry3d& camera_from_world, double near = 0.01);

// Marks the pixels within `radius` pixels of a depth discontinuity: a 4-neighbour that differs
// by more than `jump_ratio` x depth, or (with empty_is_edge) has no depth. Colour samples near
// such edges mix foreground and background and are not used. For sensor depth, whose holes are
// mostly dropouts rather than silhouettes, pass empty_is_edge = false.
Image<uint8_t> DepthEdgeMask(const ImageDepth& depth, double jump_ratio, int radius,
                             bool empty_is_edge = true);

}  // namespace genscene::texturing
