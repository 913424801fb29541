// Scene files: our own JSON scene format, Mitsuba 3 XML (render/formats/mitsuba_xml.h) behind one
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
//     "voxel_lights": {                         optional: VoxelLightGrid (render/scene.h)
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

#include "render/formats/loaded_scene.h"
#include "render/scene.h"

namespace genscene::render {

// `.xml`: Mitsuba 3 XML (ImportMitsubaXml); `.json`: our format. The scene is validated. Throws
// Error naming the file on any problem, and on any other extension.
LoadedScene LoadScene(const std::filesystem::path& path);

// Writes our JSON format atomically, with the meshes as binary PLY files in `<stem>_meshes/` next
// to it. Constant albedo is written into the JSON; per-face / per-vertex albedo goes into the PLY
// ("from_ply"): per-face exactly (float albedo_r/g/b), per-vertex as core/ply_io writes vertex
// colours, 8-bit sRGB (up to 0.0021 off in linear). Albedo fields cannot be stored (Error: bake
// them per vertex or per face first).
void SaveSceneJson(const std::filesystem::path& path, const Scene& scene,
                   const std::vector<PosedView>& views = {},
                   const RenderSettings& settings = RenderSettings());

// The Blender Cycles reference scene of a cbox-cycles folder (the set's root, icosphere_flat/ or
// icosphere_smooth/): `geometry/scene.ply` split into one mesh per object of
// `geometry/objects.json` (its face/vertex ranges; per-face albedo from the PLY, constant when an
// object's faces agree; smooth objects shade with the PLY's vertex normals, flat ones with face
// normals), plus one emissive mesh per `geometry/emitters.json` entry (one-sided quads, corners
// counter-clockwise seen from the emitting side, radiance_rgb, albedo 0).
Scene LoadCyclesScene(const std::filesystem::path& folder);

}  // namespace genscene::render
