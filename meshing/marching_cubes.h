// Marching cubes over the sparse TSDF, written the way GPU implementations are (DESIGN.md §3):
// small pure kernels run by ParallelFor over flat arrays, with exclusive scans for the output
// offsets, so the output order depends on the volume's block order only, never on threads.
//
// Phases (each a ParallelFor over blocks or over a compacted list):
//   1. classify: the cube index of every cell of every allocated block (a cell is owned by the
//      block of its lower corner; its upper corners may lie in the +x/+y/+z neighbour blocks,
//      found through the block hash). Each block first gathers its 9^3 corner points once; a
//      block whose observed points all lie on one side of the iso level (most of a fused
//      volume's truncation band) has no triangles and is done;
//   2. scan + compaction: triangle count per cell -> exclusive scan -> list of active cells with
//      their first triangle;
//   3. edges: each lattice point owns its +x, +y and +z edges; an edge gets a vertex when its ends
//      are on opposite sides of the iso level and one of its four cells is active. Each active
//      cell marks its crossed edges in their owning points (atomic OR: order-independent). Vertex
//      count per point -> exclusive scan -> first vertex per point, so every vertex is created
//      exactly once and shared by every triangle around it, across block boundaries too;
//   4. vertices: position, normal, colour per active edge;
//   5. triangles: per active cell, the case table's edges -> the owning point's vertex index.
//
// Conventions (see cube_cases.h for the ambiguous faces):
//   - inside is sdf < iso_level; a value exactly at the iso level counts as OUTSIDE. The crossing
//     parameter t along an edge is clamped to [kEdgeClamp, 1 - kEdgeClamp], so a vertex never lies
//     on a lattice point: values exactly at the iso level create neither duplicate vertices nor
//     zero-area triangles, and move the surface by at most kEdgeClamp voxels;
//   - a voxel is observed when weight > 0 and weight >= min_weight; a cell with an unobserved or
//     unallocated corner produces no triangles (the mesh has a boundary there instead);
//   - normals: the normalised TSDF gradient (central differences on the lattice, interpolated
//     along the edge), pointing toward positive sdf (free space); colours: the TSDF colour
//     interpolated along the edge (what trilinear interpolation gives on an edge).
#pragma once

#include <cstdint>

#include "core/mesh.h"
#include "core/options.h"
#include "core/tsdf_volume.h"

namespace genscene::meshing {

struct MeshingOptions {
  double iso_level = 0.0;           // metres; the surface is sdf = iso_level
  double min_weight = 0.0;          // a voxel counts as observed when weight > 0 and weight >= this
  int min_component_triangles = 0;  // remove connected components with fewer triangles (0 = off)
  int denoise_iterations = 0;       // feature-preserving denoising passes (0 = off)
  double denoise_angle = 15.0;      // degrees; creases sharper than about this are kept
  double denoise_max_offset = 0.5;  // voxels; no vertex moves further
  double decimate_max_error = 0.0;  // metres; simplify within this Hausdorff bound (0 = off)

  static constexpr const char* kSection = "meshing";
  template <typename V>
  void Visit(V&& v) {
    v("iso_level", iso_level, "m", "extract the surface sdf = iso_level");
    v("min_weight", min_weight, "",
      "voxels with a smaller fusion weight count as unobserved (no triangles)");
    v("min_component_triangles", min_component_triangles, "triangles",
      "remove connected components with fewer triangles (0 = keep all)");
    v("denoise_iterations", denoise_iterations, "",
      "feature-preserving denoising (bilateral normal filter, then vertices fitted to the "
      "normals): passes, 0 = off");
    v("denoise_angle", denoise_angle, "deg",
      "denoising keeps creases sharper than about this angle");
    v("denoise_max_offset", denoise_max_offset, "voxels",
      "denoising moves no vertex further than this from marching cubes' position");
    v("decimate_max_error", decimate_max_error, "m",
      "simplify (OpenMesh quadric decimater) while every removed point stays this close (0 = off)");
  }
  void Validate() const;
};

struct MeshingStats {
  size_t blocks = 0;        // allocated blocks
  size_t cells = 0;         // cells classified (512 per block)
  size_t active_cells = 0;  // cells with at least one triangle
  size_t vertices = 0;      // after clean-up and decimation
  size_t triangles = 0;     // after clean-up and decimation
  size_t removed_component_triangles = 0;
  size_t removed_components = 0;
  size_t decimated_triangles = 0;  // removed by decimation
  // Wall-clock seconds per phase.
  double seconds_classify = 0.0;  // neighbour table + cell classification
  double seconds_scan = 0.0;      // scans and compaction of cells and edges
  double seconds_vertices = 0.0;  // edge classification + vertex generation
  double seconds_triangles = 0.0;
  double seconds_cleanup = 0.0;  // small components
  double seconds_denoise = 0.0;
  double denoise_mean_offset = 0.0;  // metres, mean distance denoising moved a vertex
  double seconds_decimate = 0.0;
  double seconds_total = 0.0;
};

struct MeshingResult {
  TriangleMesh mesh;  // vertices, normals, vertex_colors, faces
  MeshingStats stats;
};

// Marching cubes over every allocated block of `volume`. Throws Error on invalid options or when
// the mesh would exceed 2^31 - 1 vertices or triangles.
MeshingResult ExtractMesh(const TsdfVolume& volume, const MeshingOptions& options);

// ---- Kernels (pure functions, used by ExtractMesh and testable alone) -------------------------

// A crossing never lies closer than this (in voxels) to a lattice point; see the file comment.
constexpr float kEdgeClamp = 1e-3f;

inline bool IsObserved(const TsdfVoxel& voxel, float min_weight) {
  return voxel.weight > 0.0f && voxel.weight >= min_weight;
}

// Cube index: bit c set when corner c (cube_cases.h order) is inside, sdf[c] < iso.
inline uint8_t CubeIndex(const float sdf[8], float iso) {
  uint8_t index = 0;
  for (int c = 0; c < 8; ++c) index |= static_cast<uint8_t>(sdf[c] < iso) << c;
  return index;
}

// Crossing parameter of the iso level on the edge from sdf0 (t = 0) to sdf1 (t = 1); exactly one
// of the two must be inside. Linear interpolation, clamped to [kEdgeClamp, 1 - kEdgeClamp].
inline float EdgeCrossing(float sdf0, float sdf1, float iso) {
  const float t = (iso - sdf0) / (sdf1 - sdf0);  // sdf1 != sdf0: one is < iso, the other >= iso
  return t < kEdgeClamp ? kEdgeClamp : (t > 1.0f - kEdgeClamp ? 1.0f - kEdgeClamp : t);
}

// Unit normal at the crossing from the sdf gradients at the edge's ends (any scale), or, where
// the interpolated gradient vanishes, the edge direction toward its outside end.
Eigen::Vector3f EdgeNormal(const Eigen::Vector3f& gradient0, const Eigen::Vector3f& gradient1,
                           float t, int axis, bool start_inside);

}  // namespace genscene::meshing
