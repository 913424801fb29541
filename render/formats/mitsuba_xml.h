// Mitsuba 3 XML scenes: import of the subset our path tracer renders, and export of any Scene.
// The conventions (with Mitsuba's source lines) are in ../shared/MITSUBA-XML.md; the numbers
// below ("§5") refer to its sections.
//
// The subset, everything else is an Error naming the file, the line and the element:
// - Document: `<scene version=...>` (required); `<default>` and `$name` substitution (§2: first
//   definition wins, document order, longest name first, `\$` escapes); `id` / `<ref>` with
//   forward references (§3); `<include filename>`; `<path value>` search folders.
// - Properties: float, integer, boolean, string, point, vector, rgb (1 or 3 values), spectrum with
//   ONE value (a constant, e.g. the Ignis scenes' `<spectrum name="radiance" value="1"/>`), and
//   transform with translate / rotate / scale / matrix / lookat composed as Mitsuba does (each
//   element left-multiplies, §4). Lists split on commas and spaces only. Values must be finite.
//   As in Mitsuba HEAD, a property a supported plugin does not read is an Error (§1).
// - Shapes: obj, ply, rectangle, cube, sphere (with `to_world`, `face_normals` for meshes,
//   `center` / `radius` for spheres). BSDF: diffuse with rgb / float / constant-spectrum
//   reflectance in [0, 1], or on a ply shape a nested `<texture type="mesh_attribute"
//   name="reflectance">` with `name` vertex_color or face_color (and `scale`, default 1): the
//   PLY's vertex or face colours, interpolated barycentrically / constant per face, in [0, 1]
//   after the scale (see "Mesh colours" below). A shape without BSDF gets Mitsuba's default:
//   diffuse 0.5, or 0 when it carries an emitter (§3). Emitters: area (one-sided radiance >= 0,
//   front = counter-clockwise side), point (`position` or `to_world`, intensity) and one envmap
//   (`filename` of a latitude-longitude image, `scale`, `to_world`; Mitsuba's mapping, see
//   mitsuba_detail::EnvmapDirection), which becomes the voxel lights' distant light: the six
//   lobes of VoxelLightGrid::distant fitted to its texels, exact for the envmaps the export
//   writes, else approximated with a warning. `twosided` and
//   `flip_normals` are not used by any scene in ../shared/data and are rejected.
// - Sensor: perspective (fov / fov_axis or focal_length, default 50 mm; principal_point_offset_x/y;
//   near_clip / far_clip; focus_distance accepted and ignored as Mitsuba's pinhole does), hdrfilm
//   (width, height; pixel_format rgb/rgba; component_format, sample_border and file_format
//   accepted: they do not change the radiance), rfilter box / gaussian, sampler sample_count (the
//   unbiased sampler types independent, stratified, multijitter, orthogonal, ldsampler).
//   Integrator path / direct (max_depth, rr_depth, hide_emitters: camera rays that hit an emitter
//   get no emission, the surface stays where it is; RenderSettings::hide_emitters).
//
// Mesh decisions:
// - Shading as in Mitsuba (§7): vertex normals from the file (PLY nx/ny/nz, OBJ vn) or, when the
//   file has none, angle-weighted normals (Thuermer & Wuethrich) computed here; the mesh is then
//   smooth-shaded. `face_normals=true` drops the normals and shades flat. Rectangles and cubes are
//   flat. PLY face/vertex colours are used only through a mesh_attribute reflectance.
// - Mesh colours, as Mitsuba 3's PLY loader reads them (src/shapes/ply.cpp): vertex_color is the
//   vertex element's r/g/b properties, else its red/green/blue; face_color the same of the face
//   element. Float values are taken as they are (linear RGB, the values the renderer multiplies);
//   unsigned integer values are divided by their largest value (255 for uchar) and sRGB-decoded
//   (Struct::Flags::Gamma). Alpha and signed integer colours are outside the subset. This differs
//   from core/ply_io (which reads float red/green/blue as 8-bit sRGB and prefers albedo_r/g/b),
//   so the colours are read here, not by ReadPly. A face_color PLY must have triangles only
//   (Mitsuba's loader refuses polygons). This is what Mitsuba's RGB variants render; its spectral
//   variants expect rgb2spec coefficients in colour attributes.
// - OBJ: vertices are the distinct (v, vt, vn) corner triples in order of first use by an `f`
//   line, as Mitsuba builds them; `v` lines no face uses are not part of the mesh (Mitsuba drops
//   them too). Polygons are fan-triangulated about their first corner. Other line types are
//   ignored.
// - Degenerate (zero-area) triangles are kept, as Mitsuba keeps them (they are never hit) and as
//   core/ply_io keeps them; each mesh that has some gets one line in `warnings`. Non-manifold
//   meshes load as they are. Triangles whose three vertex normals all point against the winding
//   also get a warning: Mitsuba's front side follows the shading normal, ours the winding.
// - Analytic spheres are tessellated: a geodesic icosphere (subdivided icosahedron, vertices
//   projected onto the sphere) with exact radial vertex normals, smooth-shaded. Interpolated
//   normals on such a triangle equal the radial direction of the hit point exactly, so the only
//   error is the polyhedron lying inside the sphere. Level 5 (20480 triangles, 10242 vertices)
//   keeps every face within 2.9e-4 r of the sphere (tested): the silhouette and the shadow
//   outline move by less than 3e-4 r (0.004 px for the AD-test sphere of 13 px radius) and the
//   projected area by less than 6e-4, well inside the 0.2 % radiance tolerance; level 4 (faces
//   up to 1.1e-3 r inside) would spend 0.2 % of the projected area on its own.
//
// Camera conversion (§5): Mitsuba's camera frame is x left, y up, z forward and its pixel i covers
// [i, i+1); ours is OpenCV (x right, y down, pixel centres at integers). Mitsuba's ray through a
// pixel is to_world * d (perspective.cpp: `ray.d = m_to_world.value() * d`, not renormalised) for
// the local direction d of its square-pixel projection, so a to_world M = R diag(sx, sy, sz)
// (R a rotation, s the column norms of M) is a camera with non-square pixels. With
// t = tan(x_fov / 2):
//   fx = W / (2 t) * sz / sx,  fy = W / (2 t) * sz / sy,
//   cx = (W - 1) / 2 - ppo_x W,  cy = (H - 1) / 2 - ppo_y H,
//   world_from_camera = R * diag(-1, -1, 1) with M's translation.
// Mitsuba refuses a camera to_world with an entry of M M^T - I beyond 1e-3 (has_scale), and so
// does the import; within that, R is snapped to the nearest rotation (shear is dropped), and a
// column norm within 1e-12 of 1 is taken as 1. The export writes s = (sqrt(1 + e), sqrt(1 - e),
// 1) with fx / fy = sqrt((1 - e) / (1 + e)), so an fx / fy within about 1 +- 1e-3 is exact in both
// renderers; a more anisotropic view is written with |e| just under 1e-3 (the same sqrt(fx fy))
// and a warning.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "render/formats/loaded_scene.h"
#include "render/scene.h"

namespace genscene::render {

struct MitsubaImportOptions {
  // Like Mitsuba's `-D name=value`: wins over the file's <default> values.
  std::map<std::string, std::string> parameters;
  // Subdivision level of the icosphere that replaces an analytic sphere (see above).
  int sphere_subdivision_level = 5;
};

// Loads a Mitsuba 3 XML scene of the subset. Views come in sensor order; the render settings are
// what Mitsuba would use (its defaults filled in) for the first sensor and the integrator.
// Throws Error naming the file, line and element on anything outside the subset.
LoadedScene ImportMitsubaXml(const std::filesystem::path& path,
                             const MitsubaImportOptions& options = MitsubaImportOptions());

// Writes `scene` as a Mitsuba 3 XML (version 3.0.0) at `path`, atomically, with its meshes as
// binary PLY files in the folder `<stem>_meshes/` next to it:
// - each mesh is one `ply` shape with a diffuse BSDF (and an area emitter when it emits);
//   smooth-shaded meshes carry their normals, flat ones get face_normals=true. Constant albedo is
//   an rgb reflectance; per-face / per-vertex albedo are the PLY's float red/green/blue face /
//   vertex colours, the reflectance a mesh_attribute texture of face_color / vertex_color (exact
//   in both renderers). An albedo field (Mesh Colors) is baked into the vertex colours of the mesh
//   subdivided face by face along the lattice of the smallest power-of-two resolution (up to 256)
//   at which the interpolated colours match the field within 1e-4, checked at every point of the
//   face's 256 lattice (coarser on meshes of more than about 4000 faces), so exact for Mesh
//   Colors; a warning says by how much it is missed otherwise (also when the mesh would pass 2^22
//   triangles, where the finest faces are coarsened);
// - point lights as `point` emitters; voxel lights as the emissive cube faces of
//   VoxelCubeFaces(), each a `rectangle` with a to_world matrix. Our renderer never shows voxel
//   lights to the camera: when no mesh emits, the integrator gets hide_emitters=true (as it does
//   when settings.hide_emitters is true); otherwise the cubes stay visible, with a warning. The
//   cubes (side cube_size) still stand where the lights are: hidden, they are black and shadow a
//   little, which the voxel lights do not;
// - the voxel lights' distant light (VoxelLightGrid::distant) as an `envmap` emitter reading
//   <stem>_distant.exr beside the XML (64 x 32 texels of its radiance; hide_emitters hides it
//   from camera rays, as our renderer does);
// - views as perspective sensors (x fov, principal point offsets, to_world matrix with the scale
//   of the camera conversion above for fx != fy) with the settings' film, filter (box when
//   unset, our renderer's default; Mitsuba's would be Gaussian), sampler and integrator. Views need
//   no distortion (an Error otherwise); their timestamps are not kept (an imported file numbers its
//   sensors 0, 1, 2...).
// Returns the warnings (empty when the export is exact).
std::vector<std::string> ExportMitsubaXml(const std::filesystem::path& path, const Scene& scene,
                                          const std::vector<PosedView>& views,
                                          const RenderSettings& settings = RenderSettings());

}  // namespace genscene::render
