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
//   reflectance in [0, 1]. A shape without BSDF gets Mitsuba's default: diffuse 0.5, or 0 when it
//   carries an emitter (§3). Emitters: area (one-sided radiance >= 0, front = counter-clockwise
//   side) and point (`position` or `to_world`, intensity). `twosided` and `flip_normals` are not
//   used by any scene in ../shared/data and are rejected.
// - Sensor: perspective (fov / fov_axis or focal_length, default 50 mm; principal_point_offset_x/y;
//   near_clip / far_clip; focus_distance accepted and ignored as Mitsuba's pinhole does), hdrfilm
//   (width, height; pixel_format rgb/rgba; component_format, sample_border and file_format
//   accepted: they do not change the radiance), rfilter box / gaussian, sampler sample_count (the
//   unbiased sampler types independent, stratified, multijitter, orthogonal, ldsampler).
//   Integrator path / direct (max_depth, rr_depth).
//
// Mesh decisions:
// - Shading as in Mitsuba (§7): vertex normals from the file (PLY nx/ny/nz, OBJ vn) or, when the
//   file has none, angle-weighted normals (Thuermer & Wuethrich) computed here; the mesh is then
//   smooth-shaded. `face_normals=true` drops the normals and shades flat. Rectangles and cubes are
//   flat. PLY face/vertex colours are ignored (Mitsuba's diffuse uses its reflectance).
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
// [i, i+1); ours is OpenCV (x right, y down, pixel centres at integers). With t = tan(x_fov / 2):
//   fx = fy = W / (2 t),  cx = (W - 1) / 2 - ppo_x W,  cy = (H - 1) / 2 - ppo_y H,
//   world_from_camera = to_world * diag(-1, -1, 1)
// (to_world must be rigid to 1e-3, as Mitsuba refuses scale; it is snapped to the nearest
// rotation).
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
// - each mesh with constant albedo is one `ply` shape with a diffuse BSDF (and an area emitter
//   when it emits); smooth-shaded meshes carry their normals, flat ones get face_normals=true;
// - per-face albedo cannot be expressed by a plain diffuse BSDF, so such a mesh is split into one
//   shape per distinct albedo value (in order of first appearance; the PLY pieces keep the
//   albedo per face too); per-vertex albedo and albedo fields are first reduced to one value per
//   face (the value at the face centroid), which is an approximation and adds a warning;
// - point lights as `point` emitters; voxel lights as the emissive cube faces of
//   VoxelCubeFaces(), each a `rectangle` with a to_world matrix;
// - views as perspective sensors (x fov, principal point offsets, to_world matrix) with the
//   settings' film, filter, sampler and integrator. Views need fx == fy and no distortion;
//   their timestamps are not kept (an imported file numbers its sensors 0, 1, 2...).
// Returns the warnings (empty when the export is exact).
std::vector<std::string> ExportMitsubaXml(const std::filesystem::path& path, const Scene& scene,
                                          const std::vector<PosedView>& views,
                                          const RenderSettings& settings = RenderSettings());

}  // namespace genscene::render
