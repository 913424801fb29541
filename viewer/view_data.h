// What the viewer shows, loaded from a workspace (DESIGN.md §2), and the flat arrays it hands to
// the GPU. Pure data, no OpenGL: tested without a display.
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/mesh_colors.h"
#include "core/trajectory.h"
#include "core/view_set.h"
#include "viewer/view_camera.h"

namespace genscene::viewer {

// A light drawn as a glyph: a solid octahedron at `position` whose size grows with the cube root
// of the power and whose colour is the power's chromaticity, and six spokes along +x -x +y -y +z
// -z with lengths proportional to the directional weights (the voxel lights of core/light_set.h;
// LoadWorkspace makes one per lit voxel of lights.json).
struct LightGlyph {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world, meters
  Eigen::Vector3f power = Eigen::Vector3f::Ones();     // linear RGB intensity, W/sr
  std::array<float, 6> weights{1, 1, 1, 1, 1, 1};      // directional weights lambda_k >= 0
};

// Everything a workspace holds that the viewer draws; each piece is optional.
struct ViewData {
  std::optional<TriangleMesh> mesh;          // mesh.ply
  std::optional<MeshColors> observed;        // texture.mcol (labels = view counts)
  std::optional<MeshColors> albedo;          // albedo.mcol (labels = cluster ids)
  std::optional<TriangleMesh> refined_mesh;  // mesh_refined.ply (shown instead of mesh when asked)
  Trajectory trajectory;                     // trajectory.txt (empty when missing)
  std::vector<PosedView> keyframes;          // keyframes/ (intrinsics.txt + groundtruth.txt)
  std::vector<LightGlyph> lights;  // lights.json: one per voxel with >= 0.1 % of the top power
  // lights.json's distant light when it has one (position unused: it is drawn around the scene).
  std::optional<LightGlyph> distant;
  // One line per missing or unreadable piece, e.g. "texture.mcol: missing (run genscene-texture)".
  std::vector<std::string> missing;
};

// Loads what exists of workspace `root` and lists what does not (never throws for a missing or
// broken piece: it becomes a line in `missing`). Throws Error when `root` is not a folder.
ViewData LoadWorkspace(const std::filesystem::path& root);

// Mesh Colors laid out for a fragment shader. For face f of resolution R, the global sample
// index of lattice point (i, j) is lattice_index[face_table[2f] + j (R + 1) - j (j - 1) / 2 + i]
// (rows j = 0..R, each of R + 1 - j points), and face_table[2f + 1] = R. So the shader needs no
// edge bookkeeping; shared samples appear once per face that touches them.
struct MeshColorsTables {
  std::vector<int32_t> face_table;     // 2 per face: first entry in lattice_index, R
  std::vector<int32_t> lattice_index;  // MeshColors::SampleIndex for every lattice point
  std::vector<float> rgba;             // 4 per sample: linear RGB, 1
  std::vector<int32_t> labels;         // 1 per sample (-1 when the field has none)
};
MeshColorsTables BuildMeshColorsTables(const MeshColors& colors);

// The box around everything drawn: mesh, refined mesh, camera positions, lights (empty when
// there is nothing).
Eigen::AlignedBox3d SceneBounds(const ViewData& data);

// The overview of a workspace: its model (mesh, else everything drawn) framed as OverviewOrbit
// does, with the keyframe cameras (else the trajectory's) giving up and viewing direction.
OrbitController Overview(const ViewData& data, const CameraIntrinsics& intrinsics);
// The world up of the workspace's cameras (CamerasUp), for orbiting.
Eigen::Vector3d WorkspaceUp(const ViewData& data);

// The camera of --camera for an image of `size` pixels: keyframe N with its intrinsics (rescaled
// per axis, pixel-centre convention, when `size` differs), or the default 60 degree pinhole at the
// overview or at a given pose. Throws Error when keyframe N does not exist.
PosedView ResolveCamera(const CameraSpec& spec, const ViewData& data, const Eigen::Vector2i& size);

// The mesh as separate triangles (3 vertices per face, face order kept, so that gl_PrimitiveID
// is the face index): xyz per vertex.
std::vector<float> UnindexedPositions(const TriangleMesh& mesh);

// Coloured line segments and triangles for the overlay (trajectory, frusta, light glyphs).
struct Overlay {
  std::vector<float> lines;      // 2 vertices per segment, xyz rgb each
  std::vector<float> triangles;  // 3 vertices per triangle, xyz rgb each
};
// The trajectory as a polyline (orange) and each keyframe as a frustum (cyan) `depth` meters deep.
void AddTrajectory(const Trajectory& trajectory, Overlay* overlay);
void AddFrusta(const std::vector<PosedView>& keyframes, double depth, Overlay* overlay);
// Each light's glyph; `scale` is the octahedron radius of the strongest light (meters), the others
// smaller as the cube root of their share of its mean power, so that glyphs stay small however
// bright the estimate.
void AddLightGlyphs(const std::vector<LightGlyph>& lights, double scale, Overlay* overlay);
// The distant light (light from beyond the scan) as arrows coming in from outside `box`: for each
// direction d_k with a weight, a segment from the centre of the box's side on d_k outwards along
// d_k, as long as half the box's diagonal times the weight's share of the largest, with a
// barb at its inner end; coloured by the light's chromaticity.
void AddDistantGlyph(const LightGlyph& distant, const Eigen::AlignedBox3d& box, Overlay* overlay);

}  // namespace genscene::viewer
