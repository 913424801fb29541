// Scene files: our own JSON scene format, Mitsuba 3 XML (inverse/mitsuba_xml.h) behind one
// LoadScene call, and the Blender Cycles reference scene of ../shared/data/cbox-cycles.
//
// Our JSON scene format ("genscene scene", version 1). Paths are relative to the JSON file (or
// absolute); every key not listed here is an Error naming it; numbers must be finite.
//
//   {
//     "genscene_scene": 1,                      required: format version
//     "meshes": [{                              optional list
//       "name": "floor",                        optional (default "mesh<i>")
//       "ply": "room_meshes/000_floor.ply",     required: the triangle mesh, world frame, metres
//       "albedo": [0.7, 0.7, 0.7],              optional: constant linear RGB in [0, 1] (default
//                 or "from_ply"                 0.5), or the PLY's face albedo (albedo_r/g/b or
//                                               red/green/blue), else its vertex albedo/colours
//       "emission": [0, 0, 0],                  optional: one-sided area-light radiance >= 0
//                                               (front = counter-clockwise side); default 0
//       "smooth": false                         optional: shade with the PLY's vertex normals
//     }],
//     "point_lights": [{"position": [x, y, z], "intensity": [r, g, b]}],     optional, W/sr
//     "voxel_lights": {                         optional: VoxelLightGrid (inverse/scene.h)
//       "bounds_min": [x, y, z], "bounds_max": [x, y, z], "dims": [7, 7, 7],
//       "cube_size": 0.01,                      optional (default 0.01 m)
//       "intensity": [[r, g, b], ...],          L per voxel, x fastest, then y, then z
//       "weights": [[l+x, l-x, l+y, l-y, l+z, l-z], ...]   six lambdas per voxel
//     },
//     "cameras": [{                             optional
//       "intrinsics": "fx fy cx cy width height [k1 k2 p1 p2 k3]",   as intrinsics.txt
//       "pose": "timestamp tx ty tz qx qy qz qw"                      TUM line, world_from_camera
//     }],
//     "render": {                               optional, every field optional
//       "integrator": "path" | "direct", "max_depth": 6, "samples_per_pixel": 256,
//       "pixel_filter": "box" | "gaussian", "gaussian_stddev": 0.5,   (pixels)
//       "near_clip": 0.01, "far_clip": 10000                          (metres)
//     }
//   }
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "inverse/scene.h"

namespace genscene::inverse {

// The pixel reconstruction filter of a render (Mitsuba's rfilter).
struct PixelFilter {
  enum class Kind { kBox, kGaussian };
  Kind kind = Kind::kBox;  // box: each pixel is the plain mean of its own samples
  double stddev = 0.5;     // gaussian: standard deviation in pixels, truncated at 4 stddev
};

// Render settings a scene file may carry; unset = not given.
struct RenderSettings {
  std::optional<std::string> integrator;  // "path" or "direct"
  // Longest path in vertices after the camera, as Mitsuba counts: 1 = emitters seen directly,
  // 2 = direct lighting, -1 = unbounded. "direct" is recorded as 2.
  std::optional<int> max_depth;
  std::optional<int> samples_per_pixel;
  std::optional<PixelFilter> pixel_filter;
  std::optional<double> near_clip;  // metres (scene units) along the camera axis
  std::optional<double> far_clip;
};

struct LoadedScene {
  Scene scene;
  std::vector<View> views;  // in file order; timestamps 0, 1, 2... unless the file gives them
  RenderSettings settings;
  std::vector<std::string> warnings;  // one line each, for the app to print (never fatal)
};

// `.xml`: Mitsuba 3 XML (ImportMitsubaXml); `.json`: our format. The scene is validated. Throws
// Error naming the file on any problem, and on any other extension.
LoadedScene LoadScene(const std::filesystem::path& path);

// Writes our JSON format atomically, with the meshes as binary PLY files in `<stem>_meshes/` next
// to it. Constant albedo is written into the JSON; per-face / per-vertex albedo goes into the PLY
// ("from_ply"): per-face exactly (float albedo_r/g/b), per-vertex as core/ply_io writes vertex
// colours, 8-bit sRGB (up to 0.0021 off in linear). Albedo fields cannot be stored (Error: bake
// them per vertex or per face first).
void SaveSceneJson(const std::filesystem::path& path, const Scene& scene,
                   const std::vector<View>& views = {},
                   const RenderSettings& settings = RenderSettings());

// The Blender Cycles reference scene of a cbox-cycles folder (the set's root, icosphere_flat/ or
// icosphere_smooth/): `geometry/scene.ply` split into one mesh per object of
// `geometry/objects.json` (its face/vertex ranges; per-face albedo from the PLY, constant when an
// object's faces agree; smooth objects shade with the PLY's vertex normals, flat ones with face
// normals), plus one emissive mesh per `geometry/emitters.json` entry (one-sided quads, corners
// counter-clockwise seen from the emitting side, radiance_rgb, albedo 0).
Scene LoadCyclesScene(const std::filesystem::path& folder);

// ------------------------------------------------------------------------------------------------
// Mesh sources shared by the loaders (conventions of ../shared/MITSUBA-XML.md §7).

// A Wavefront OBJ as Mitsuba reads it: `v`, `vt`, `vn`, `f` (corners v, v/vt, v//vn, v/vt/vn,
// 1-based, positive); polygons fan-triangulated about their first corner; one vertex per distinct
// (v, vt, vn) triple in order of first use (unused `v` lines are not part of the mesh); vertex
// normals from `vn` when every corner has one. Other line types are ignored. Throws Error naming
// the file and line (bad number, non-finite value, index out of range, mixed corner forms).
TriangleMesh ReadObj(const std::filesystem::path& path);

// Mitsuba's `rectangle`: the square [-1, 1]^2 at z = 0, front (counter-clockwise side) +z.
TriangleMesh RectangleMesh();
// Mitsuba's `cube`: [-1, 1]^3 as 24 vertices / 12 triangles, fronts outward, one normal per face.
TriangleMesh CubeMesh();
// The unit sphere mapped by `to_world` (rotation, uniform scale, translation; anything else is an
// Error) as a geodesic icosphere of 20 * 4^level triangles, fronts outward, with exact radial
// vertex normals.
TriangleMesh SphereMesh(const Eigen::Matrix4d& to_world, int level);

// Applies an affine `to_world` to the positions and (inverse-transpose, renormalised) normals.
void TransformMesh(const Eigen::Matrix4d& to_world, TriangleMesh* mesh);
// Vertex normals as Mitsuba computes them: the sum of adjacent face normals weighted by the
// corner angle (Thuermer & Wuethrich 1998), normalised; zero-area faces do not contribute.
std::vector<Eigen::Vector3f> AngleWeightedNormals(const TriangleMesh& mesh);
int CountDegenerateFaces(const TriangleMesh& mesh);

}  // namespace genscene::inverse
