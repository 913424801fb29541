// glTF 2.0 binary (.glb) export of a scene model, for Blender, three.js, Babylon.js and other
// viewers: the mesh with its albedo as a texture, the observed colour as a material variant, the
// keyframe cameras and the voxel lights as point lights.
//
// File: the GLB container (12-byte header "glTF", version 2, total length; a JSON chunk padded
// with spaces; a BIN chunk padded with zeros, holding every buffer view), written atomically.
//
// Contents:
// - One mesh of one triangle primitive. Mesh Colors have no UV parameterisation, so they are baked
//   into a per-face texture atlas (core/mesh_colors_atlas.h) and the vertices are split per face
//   corner: 3 per face, with POSITION (with min/max), NORMAL (when the mesh has vertex normals;
//   normalised, a zero or non-finite one replaced by the face normal), TEXCOORD_0 (the atlas UVs)
//   and uint32 indices. Positions are in the genscene world frame, meters, unchanged (glTF's "+Y
//   up" is a viewer convention; the model keeps the frame of model.ply, model.xml and
//   trajectory.txt).
// - Material 0 "albedo": pbrMetallicRoughness with baseColorTexture = the albedo atlas (PNG,
//   sRGB), metallicFactor 0, roughnessFactor 1 (Lambertian as far as glTF goes). The sampler is
//   LINEAR / LINEAR_MIPMAP_LINEAR with CLAMP_TO_EDGE.
// - Material 1 "observed" (when observed colours are given): the observed colour (shading baked
//   in) as the base colour texture of a KHR_materials_unlit material, baked into the same atlas
//   layout and sharing TEXCOORD_0 (the layout takes the finer of the two resolutions per face). The
//   primitive selects it through KHR_materials_variants: variant 0 "albedo" (the default
//   material), variant 1 "observed". Readers without the extension show the albedo and list the
//   second material unused.
// - Cameras: one perspective camera per view, yfov = 2 atan(height / (2 fy)), aspectRatio =
//   width / height, znear = options.znear, no zfar (infinite). Camera nodes carry
//   world_from_camera turned by 180 degrees about the camera's x axis (OpenCV cameras look down
//   +Z with +Y down, glTF cameras down -Z with +Y up) as translation + rotation quaternion.
// - Lights: one KHR_lights_punctual point light per active voxel (VoxelLightGrid::ActiveVoxels),
//   a node at the voxel centre under a node "voxel_lights". A point light radiates the same in
//   every direction; it gets the voxel's radiant power, pi L sum_k lambda_k (light_set.h), spread
//   over 4 pi sr: I = L sum_k lambda_k / 4 = 1.5 L mean(lambda). glTF splits that into
//   `intensity` = its largest channel and `color` = I / intensity. The value is written in the
//   project's linear radiometric units (what the renderer and lights.json use), not converted to
//   candela: a reader in physical units would scale it by its own exposure.
// - extras: each camera keeps fx, fy, cx, cy, width, height and the view's timestamp; each light
//   keeps its voxel index, L and the six weights; the root keeps the atlas size and downscale.
//
// What glTF cannot hold, so a glTF viewer does not show it:
// - fx != fy and an off-centre principal point (glTF has one field of view and a centred optical
//   axis); lens distortion (none after ingest). Each such camera adds a warning; extras keep the
//   true intrinsics.
// - The directional emission of a voxel (the six weights): the point light is isotropic with the
//   voxel's power. Voxels below the active threshold are left out.
// - Mesh Colors exactly: the atlas reproduces the samples at their points and bilinear
//   interpolation between them (core/mesh_colors_atlas.h); the per-sample labels are not exported.
// - The trajectory: only the given views (the keyframes) become cameras.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/light_set.h"
#include "core/mesh.h"
#include "core/mesh_colors.h"
#include "core/view_set.h"

namespace genscene::render {

struct GltfExportOptions {
  int atlas_max_size =
      8192;              // largest atlas width or height (AtlasOptions in core/mesh_colors_atlas.h)
  int atlas_gutter = 2;  // texels around each chart
  double znear = 0.01;   // camera near plane, meters
};

struct GltfExportSummary {
  int atlas_width = 0, atlas_height = 0;
  int atlas_downscale = 0;  // face resolutions were halved this many times to fit the atlas
  size_t bytes = 0;         // size of the .glb file
  int cameras = 0, lights = 0;
  bool observed = false;              // the "observed" material variant was written
  std::vector<std::string> warnings;  // the atlas downscale, cameras glTF cannot express
};

// Writes `mesh` with `albedo` (and `observed` when not null), the active voxels of `lights` (when
// not null) and `views` as `path` (.glb). Throws Error naming the file when the Mesh Colors were
// made for another mesh, the mesh or a camera is invalid, or the file cannot be written.
GltfExportSummary ExportGltf(const std::filesystem::path& path, const TriangleMesh& mesh,
                             const MeshColors& albedo, const MeshColors* observed,
                             const VoxelLightGrid* lights, const std::vector<PosedView>& views,
                             const GltfExportOptions& options = GltfExportOptions());

}  // namespace genscene::render
