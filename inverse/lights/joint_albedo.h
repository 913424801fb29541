// Joint albedo and lights (EstimateLights with JointAlbedoInputs): per-texel albedo alternated with
// the voxel lights. The lights are estimated with the clustering's albedo; then, until the light
// cost stops falling:
//  1. the shading of every sampled pixel, S_i = P_i / a_i per channel (P_i: the cache's
//     prediction, a_i: the albedo its camera ray meets at the pixel centre), is carried to every
//     texel t of the Mesh Colors by a cross-bilateral kernel: the sampled pixels within
//     albedo_radius of the texel whose surface normal is within 45 degrees of the texel's,
//     weighted (1 - d^2 / r^2)^2, widened to 2r, then 4r where fewer than albedo_min_pixels
//     pixels fall inside. Shading is smooth and the pixels are a few thousand per view: texture
//     detail stays in the albedo, the kernel keeps the shading smooth. The shading comes from the
//     first half of the paths only.
//  2. each observed texel with shading gets, per channel, the albedo that minimises
//         (a S_t - o_t)^2 + mu s^2 (a - m_k)^2
//     (o_t: its observed colour, texture.mcol; m_k: the mean of its cluster's unregularised
//     o / S; s^2: the mean S_t^2 over the texels; mu: albedo_prior), i.e.
//         a = (o_t S_t + mu s^2 m_k) / (S_t^2 + mu s^2).
//     Texels that are not observed or that no sampled pixel reaches take m_k.
//     When the 95th percentile of the largest channel over the observed texels exceeds
//     albedo_ceiling, the whole albedo is scaled down to it (the global scale is free: the
//     lights' solve takes it up; without this, real rooms whose shading the lights under-predict
//     clamp at 1 and lose their texture). Then every channel is kept within [0, 1].
//  3. the gauge: albedo x light is unchanged by a per-channel scale at the first bounce, not at
//     the interreflections. The updates keep the clustering's gauge (its global scale, the
//     95th percentile of the largest channel at albedo max_albedo, and its colour split: the
//     chromaticity of the colour modes after the clustering's white balance, which gives a
//     coloured illuminant's cast to the lights); only texels move against it. An explicit
//     per-channel gauge step (the 95th percentile of every channel at 0.9, "white patch") was
//     tried and dropped: the cache's first-bounce rescaling cannot follow it through the
//     interreflections (demo novel views 0.10 against 0.043 without it).
//  4. the cache's rows of each pixel are scaled by a_new / a_old at its first hit (exact for the
//     first bounce; the interreflections keep the previous albedo until a fresh trace) and the
//     lights are solved again. A step that raises the cost, or the second half of the paths'
//     residual sum |P_i - I_i|^2 / sum |I_i|^2 (an independent sample of the prediction's noise:
//     an albedo that took up the first half's noise fits it worse), is undone and ends the
//     alternation.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/mesh_colors.h"
#include "inverse/lights/pixel_sampling.h"
#include "render/path_tracer.h"

namespace genscene::inverse {

// What the joint estimate updates: the Mesh Colors albedo of one mesh of the scene.
struct JointAlbedoInputs {
  int mesh = 0;                          // index into the scene's meshes (not an emitter)
  const MeshColors* observed = nullptr;  // observed linear colour per texel (texture.mcol)
  const MeshColors* clusters = nullptr;  // the clustering's albedo; labels() = cluster ids
  std::vector<int32_t> view_counts;      // keyframe samples per texel (0: not observed); empty:
                                         // every texel observed
};

struct JointAlbedoStep {
  double cost = 0.0, data = 0.0;  // the light cost after the lights' solve
  size_t texels_updated = 0;      // observed texels with shading
  double scale = 1.0;             // the ceiling's global scale of this step (1: none)
  // The second half of the paths' relative squared residual before and after the step.
  double check_before = 0.0, check = 0.0;
  bool kept = true;
};

// The first surface each sampled pixel's centre ray meets (mesh index in `tracer`'s scene).
struct PixelSurface {
  bool hit = false;
  int mesh = -1, face = -1;
  float b1 = 0.0f, b2 = 0.0f;
  Eigen::Vector3f position = Eigen::Vector3f::Zero(), normal = Eigen::Vector3f::Zero();
};
std::vector<PixelSurface> LocatePixels(const render::PathTracer& tracer,
                                       const std::vector<PosedImage>& views,
                                       const std::vector<SampledPixel>& pixels);

// Step 1: the kernel-weighted mean of `pixel_shading` (one per pixel, mesh `mesh` only) at every
// texel of `layout` on `mesh`; `covered` (per texel) tells which texels some pixel reached. A
// texel with fewer than `min_pixels` pixels within `radius` takes the kernel twice, then four
// times as wide (sparse pixels: the shading stays an average, not one pixel's noise).
// ShadingKernel holds what does not change between the alternation's steps (the texels' positions
// and normals, the pixels' point grids); TexelShading is one use of it. `pixels` must outlive it.
class ShadingKernel {
 public:
  ShadingKernel(const TriangleMesh& mesh, const MeshColors& layout, int mesh_index,
                const std::vector<PixelSurface>& pixels, double radius);
  ~ShadingKernel();
  std::vector<Eigen::Vector3f> Shade(const std::vector<Eigen::Vector3f>& pixel_shading,
                                     int min_pixels, std::vector<uint8_t>* covered) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};
std::vector<Eigen::Vector3f> TexelShading(const TriangleMesh& mesh, const MeshColors& layout,
                                          int mesh_index, const std::vector<PixelSurface>& pixels,
                                          const std::vector<Eigen::Vector3f>& pixel_shading,
                                          double radius, int min_pixels,
                                          std::vector<uint8_t>* covered);

// Step 2: the updated albedo (layout and labels of inputs.clusters); `updated` receives the
// number of texels with shading that voted, `applied_scale` the ceiling's scale (1: none).
MeshColors UpdateAlbedo(const JointAlbedoInputs& inputs,
                        const std::vector<Eigen::Vector3f>& texel_shading,
                        const std::vector<uint8_t>& covered, double prior, double ceiling,
                        size_t* updated = nullptr, double* applied_scale = nullptr);

}  // namespace genscene::inverse
