// Depth preprocessing for tracking (KinectFusion, Newcombe et al. 2011, §3.2): invalid-depth
// masking, an edge-preserving bilateral filter, a 3-level pyramid, and per-level vertex and
// normal maps in the camera frame. Integration uses the masked raw depth, tracking the filtered
// pyramid, as KinectFusion does.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "core/camera.h"
#include "core/image.h"

namespace genscene::fusion {

using PointImage = Image<Eigen::Vector3f>;  // camera-frame points or unit normals; zero = invalid

struct PreprocessOptions {
  double min_depth = 0.1;  // m; nearer measurements are invalid
  double max_depth = 6.0;  // m; farther measurements are invalid (Kinect noise grows as z^2)
  // The bilateral filter applies to a pyramid at full resolution only (BuildPyramid).
  int bilateral_radius = 2;             // px; half-width of the bilateral window (0 = no filter)
  double bilateral_sigma_space = 1.5;   // px; spatial Gaussian
  double bilateral_sigma_depth = 0.03;  // m; range Gaussian (KinectFusion: 0.03 m)
  int levels = 3;                       // pyramid levels (each halves the resolution)

  void Validate() const;
};

struct MaskStats {
  size_t zero = 0;          // pixels without a measurement
  size_t non_finite = 0;    // NaN or infinite values (masked)
  size_t out_of_range = 0;  // negative, or outside [min_depth, max_depth] (masked)
  size_t valid = 0;
};

// Copy of `depth` with every NaN, infinite, negative or out-of-range value set to 0.
ImageDepth MaskInvalidDepth(const ImageDepth& depth, double min_depth, double max_depth,
                            MaskStats* stats = nullptr);

// Bilateral filter of a masked depth map: invalid pixels stay invalid and do not contribute;
// neighbours more than 3 sigma_depth away from the centre do not either (edges stay sharp).
ImageDepth BilateralFilterDepth(const ImageDepth& depth, int radius, double sigma_space,
                                double sigma_depth);

// Half-resolution depth: mean of the valid pixels of each 2x2 block within 3 sigma_depth of the
// block's top-left valid pixel (KinectFusion's block averaging that does not blur across edges).
ImageDepth DownsampleDepth(const ImageDepth& depth, double sigma_depth);

// Camera-frame points of every valid pixel (zero elsewhere).
PointImage ComputeVertexMap(const ImageDepth& depth, const CameraIntrinsics& intrinsics);

// Unit normals from the cross product of central differences of the vertex map over +-`step`
// pixels, facing the camera; zero where a neighbour is missing or the surface jumps by more than
// `max_jump` metres per metre of depth (depth discontinuities).
PointImage ComputeNormalMap(const PointImage& vertices, double max_jump = 0.1, int step = 1);

struct PyramidLevel {
  CameraIntrinsics intrinsics;
  ImageDepth depth;  // filtered
  PointImage vertices;
  PointImage normals;
};

// A frame's brightness at one pyramid level for the photometric term of tracking: luminance,
// display-encoded (the sRGB curve, so that dark and bright regions carry comparable contrast),
// in [0, 1], and its gradient by central differences (0 on the border row and column).
struct IntensityLevel {
  ImageGray intensity;
  ImageGray grad_u, grad_v;  // per pixel
  // Standard deviation of the image's pixel noise, in brightness: at full resolution the median
  // absolute response to Immerkaer's (1996) mask, which cancels planes and ramps, so that texture
  // edges (a minority of the pixels) do not count as noise; halved at each coarser level (a 2x2
  // mean; the coarser levels' own responses would see texture a few pixels across as noise).
  double noise = 0.0;
};

// `levels` levels from linear RGB `color`, each the 2x2 mean of the one before (the same grid as
// BuildPyramid's levels); the first at 1/subsample of the colour's resolution (a power of two),
// its noise measured at full resolution and halved per halving. Empty when `color` is.
std::vector<IntensityLevel> BuildIntensityPyramid(const ImageRgb& color, int levels,
                                                  int subsample = 1);

// Level 0 = the masked depth bilateral filtered, or with subsample > 1 (a power of two) reduced to
// 1/subsample of its resolution by DownsampleDepth and not filtered further; each next level half
// the previous. `intrinsics` are the input's. Tracking 640x480 frames at 320x240
// (FusionOptions::tracking_subsample's default), ATE with the bilateral filter (radius 2 px, sigma
// 1.5 px) on the reduced level / radius 1, sigma 0.75 / none: 7-Scenes 0.870 / 0.828 / 0.778 cm,
// TUM fr1/desk 0.167 / 0.164 / 0.169 cm, the path-traced room (150 frames, Kinect noise) 0.631 /
// 0.559 / 0.435 cm: four depths averaged leave less noise than the filter's blur costs.
std::vector<PyramidLevel> BuildPyramid(const ImageDepth& masked_depth,
                                       const CameraIntrinsics& intrinsics,
                                       const PreprocessOptions& options, int subsample = 1);

}  // namespace genscene::fusion
