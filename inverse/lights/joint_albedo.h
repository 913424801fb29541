// Joint albedo and lights (EstimateLights with JointAlbedoInputs): per-texel albedo alternated with
// the voxel lights. The lights are estimated with the clustering's albedo; then, until the light
// cost stops falling:
//  1. the shading S = L / a (per channel: the outgoing radiance over the albedo) is traced under
//     the current lights at shading probes: observed texels one per cell of a grid albedo_radius
//     / 3 wide, albedo_probe_spp paths each from just above the surface back along its face
//     normal (a Lambertian surface sends every camera the same radiance), with the current albedo
//     on the mesh for the interreflections. A cross-bilateral kernel carries it to every texel:
//     the probes within albedo_radius of the texel whose face normal is within 10 degrees of the
//     texel's face's (with vertex-interpolated normals and 45 degrees the Open3D room's held-out
//     error was 0.147, with face normals and 10 degrees 0.134; the renders shade the chain's
//     meshes with their interpolated vertex normals, so why the face test does better is not
//     established), weighted (1 - d^2 / r^2)^2, widened to 2r, then 4r where fewer
//     than albedo_min_pixels probes fall inside. (albedo_probe_spp 0: the sampled pixels' shading
//     S_i = P_i / a_i from the first half of the cache's paths instead, normals within 45
//     degrees; a few thousand pixels per view leave the kernel wide, and its blur of the shading
//     went into the albedo: the Open3D room's held-out error is 0.148 with it (and radius 2 %),
//     0.108 with probes.) The probes' shading is independent of both halves of
//     the cache's paths. With albedo_guide > 0 (probes only) the kernel is guided
//     (ShadingGuide): it averages S / (G + c) and multiplies the texel's own G + c back, G the
//     voxels' first-bounce shading with its shadows (DirectShading) and c
//     albedo_guide times the probes' mean shading. A plain mean of a falloff that is convex near
//     a light is too high there (17 % under a light 15 cm above a floor with a 10 cm kernel,
//     0.9 % guided), and G carries the texel's own shading normal and shadows (the Open3D
//     room's held-out error with refinement off: plain 0.108, guided 0.104; with the voxels'
//     shadows in G 0.0996 against 0.1017 without, genscene run's defaults, where the refine
//     stage kept the unrefined mesh).
//  2. each observed texel with shading gets, per channel, the albedo that minimises
//         (a S_t - o_t)^2 + mu s^2 (a - m_k)^2
//     (o_t: its observed colour, texture.mcol; m_k: the mean of its cluster's unregularised
//     o / S; s^2: the mean S_t^2 over the texels; mu: albedo_prior), i.e.
//         a = (o_t S_t + mu s^2 m_k) / (S_t^2 + mu s^2).
//     Texels that no keyframe saw take the same with o_t the texturing's fill (the colour of
//     their observed neighbours, or the texture's mean colour where no neighbour was observed;
//     their cluster's mean m_k differs from it most along the strips an occluding edge hid, which
//     a new view sees: the Open3D room's held-out error without render noise is 0.120 with m_k
//     there, 0.103 with the fill); texels without shading take m_k.
//     The statistics (m_k, s^2, the ceiling's percentile) are the observed texels'.
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
//     alternation; so does a step in which no texel has shading (before its solve).
//  5. with probes, once more after the last kept step: each step's albedo was made for the
//     lights before that step's solve, the renders show the lights after it. The texels take
//     the shading of the final lights (steps 1 and 2, no solve; a ceiling's scale goes into the
//     lights as 1 / scale; when no texel has shading, the last step's albedo stays).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/light_set.h"
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

// Shading probes (step 1 with LightEstimationOptions::albedo_probe_spp > 0): the observed texels
// of mesh `mesh_index` (view_counts as JointAlbedoInputs; empty: all), one per cell of a grid of
// `spacing` (a face-interior texel where the cell has one: the first in texel order, else the
// first edge texel, else the first vertex texel), each kept when the ray from `offset` above it
// along its face normal, back along the normal, meets its own mesh within 3 offsets of the ray's
// start (face and barycentric coordinates of that hit in the result). `tracer`'s scene must hold
// the mesh at `mesh_index`.
std::vector<PixelSurface> ShadingProbes(const render::PathTracer& tracer, const MeshColors& layout,
                                        int mesh_index, const std::vector<int32_t>& view_counts,
                                        double spacing, double offset);
// The shading S = L / a (per channel) at every probe under `lit`'s lights: the mean radiance of
// `spp` paths from `offset` above the probe's point back along its face normal (the hit face of
// ShadingProbes' ray; which face the paths meet first is not checked again), over the albedo of
// the probe's face and point. A Lambertian surface sends the same radiance every way, so the
// probe's ray stands for every camera's. A probe whose albedo is below 0.02 in a channel gets NaN
// (its radiance says too little of the shading; ShadingKernel leaves it out). `lit` is the scene
// of ShadingProbes' tracer with lights.
std::vector<Eigen::Vector3f> ProbeShading(const render::PathTracer& lit,
                                          const std::vector<PixelSurface>& probes, double offset,
                                          const render::RenderOptions& paths, int spp,
                                          uint64_t seed);

// The surface point of every texel of `layout` on mesh `mesh_index` (face and barycentric
// coordinates of MeshColors::SampleFacePoint, position, face normal; hit false for an isolated
// vertex).
std::vector<PixelSurface> TexelSurfaces(const TriangleMesh& mesh, const MeshColors& layout,
                                        int mesh_index);

// The first-bounce shading of `lights`' voxels at points on `mesh`:
//     G = sum_v V_v I_v(w_v) max(0, n . l_v) / (pi (d_v^2 + e^2))
// (I_v(w_v): voxel v's intensity toward the point, l_v the unit direction to v, d_v its
// distance, e the softening; n the renders' shading normal: interpolated vertex normals on a
// smooth-shaded mesh, else the face's; 0 where l_v is behind the face). V_v, the visibility of
// voxel v's centre from the point (offset along the face normal as the renders offset their
// shadow rays), is traced with `visibility`'s scene for the voxels whose largest intensity is at
// least 1e-3 of the strongest voxel's, and 1 for the others and without `visibility`. The same
// first-bounce term as the renders' next-event estimate.
std::vector<Eigen::Vector3f> DirectShading(const VoxelLightGrid& lights,
                                           const render::SceneMesh& mesh,
                                           const std::vector<PixelSurface>& at,
                                           const render::RayTracer* visibility = nullptr);

// A guide for ShadingKernel::Shade: the kernel averages the shading over (guide + floor) and
// multiplies the texel's own (guide + floor) back. With the direct shading as the guide, the
// fast changes near a light (the falloff, the cosine of a curved surface, the shadows of small
// bumps) are the texel's own and only what varies slowly (the indirect light, relative to it) is
// averaged; where the
// guide is small against the floor the kernel is the plain mean.
struct ShadingGuide {
  std::vector<Eigen::Vector3f> samples, texels;  // per kernel sample, per texel
  Eigen::Vector3f floor = Eigen::Vector3f::Zero();
};

// Step 1: the kernel-weighted mean of `pixel_shading` (one per pixel, mesh `mesh` only) at every
// texel of `layout` on `mesh`; `covered` (per texel) tells which texels some pixel reached. A
// texel with fewer than `min_pixels` pixels within `radius` takes the kernel twice, then four
// times as wide (sparse pixels: the shading stays an average, not one pixel's noise).
// ShadingKernel holds what does not change between the alternation's steps (the texels' positions
// and normals, the pixels' point grids); TexelShading is one use of it. `pixels` must outlive it.
// The kernel's normal test: a sample votes for a texel when the normals of their faces agree
// within 45 degrees (sampled pixels: sparse, the kernel wide) or 10 degrees (probes: dense; the
// probes on either side of a fold of the mesh are kept apart).
inline constexpr double kPixelNormalCosine = 0.7071;  // cos 45 degrees
inline constexpr double kProbeNormalCosine = 0.9848;  // cos 10 degrees
class ShadingKernel {
 public:
  ShadingKernel(const TriangleMesh& mesh, const MeshColors& layout, int mesh_index,
                const std::vector<PixelSurface>& pixels, double radius,
                double min_normal_cosine = kPixelNormalCosine);
  ~ShadingKernel();
  // Samples whose shading is not finite are left out. With `guide` (ShadingGuide), the mean
  // is taken of the shading over the sample's guide and scaled by the texel's.
  std::vector<Eigen::Vector3f> Shade(const std::vector<Eigen::Vector3f>& pixel_shading,
                                     int min_pixels, std::vector<uint8_t>* covered,
                                     const ShadingGuide* guide = nullptr) const;

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
