// Comparison of our renders with a reference image from another renderer, region by region:
// regions are the meshes seen by the pixel-centre ray; pixels on a region boundary (any 8-neighbour
// in another region) and emitter pixels are left out, because a box filter mixes regions there.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/image.h"
#include "render/path_tracer.h"

namespace genscene::render {

struct RegionComparison {
  int mesh = -1;
  size_t pixels = 0;
  Eigen::Vector3d mean_ours = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_reference = Eigen::Vector3d::Zero();
  // |mean(ours) - mean(reference)| / mean(reference), per channel.
  Eigen::Vector3d RelativeBias() const;
};

struct ImageComparison {
  std::vector<RegionComparison> regions;  // regions with at least `min_region_pixels` pixels
  // Over the brighter half (by reference luminance) of the compared pixels:
  size_t pixels = 0;
  double rms_relative_difference = 0.0;  // RMS of (ours - reference) / reference, luminance
  double ours_relative_noise = 0.0;      // RMS relative noise of our image, from its two halves
};

// `a` and `b` are two renders of the same view with different seeds; "ours" is their mean.
// `emitter_meshes[m]` is true for emitting meshes (left out).
ImageComparison CompareWithReference(const RenderOutput& a, const RenderOutput& b,
                                     const ImageRgb& reference,
                                     const std::vector<bool>& emitter_meshes,
                                     size_t min_region_pixels = 50);

}  // namespace genscene::render
