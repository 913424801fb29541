// Raycasting the sparse TSDF (KinectFusion §3.4): per pixel, march along the viewing ray to the
// first zero crossing from positive to negative distance and refine it by linear interpolation.
// Empty space is skipped block by block; the march starts at the nearest allocated block seen in
// the pixel's image tile (InfiniTAM's min/max depth range rendering), so a frame costs a few
// samples per pixel. Used for tracking (the model at the previous pose) and for previews.
#pragma once

#include <Eigen/Geometry>

#include "core/camera.h"
#include "core/image.h"
#include "core/tsdf_volume.h"
#include "fusion/preprocess.h"

namespace genscene::fusion {

struct RaycastResult {
  ImageDepth depth;    // planar z of the surface in the camera, 0 = no surface
  PointImage points;   // camera-frame surface points (zero = none)
  PointImage normals;  // camera-frame unit normals facing the camera (zero = none)
  ImageRgb color;      // interpolated voxel colour (zero = none)
  // The per-frame pass over the volume: chunks (8^3 blocks) tested against the frustum, and the
  // blocks of the chunks in it whose corners were projected.
  size_t chunks_tested = 0, blocks_projected = 0;
};

// Rays start no nearer than min_depth and stop at max_depth (metres, planar z). The colour
// image is left black unless with_color (tracking does not need it). Normals are taken over a
// baseline of +-normal_step pixels: the raycast points carry the TSDF's small interpolation
// errors, which a 1-pixel baseline turns into normal noise at full resolution; a model raycast at
// half resolution takes 1 (the same baseline in metres).
RaycastResult RaycastVolume(const TsdfVolume& volume, const CameraIntrinsics& intrinsics,
                            const Eigen::Isometry3d& world_from_camera, double min_depth = 0.1,
                            double max_depth = 10.0, bool with_color = true, int normal_step = 2);

}  // namespace genscene::fusion
