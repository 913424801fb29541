// Optional clean-up after marching cubes: removal of small connected components (fused scenes
// carry specks of noise) and simplification within an error bound. Both are serial and keep the
// order of what they do not remove, so their output is as deterministic as their input.
#pragma once

#include <cstddef>

#include "core/mesh.h"

namespace genscene::meshing {

struct ComponentRemoval {
  size_t components = 0;  // components removed
  size_t triangles = 0;   // triangles removed
};

// Removes every connected component (faces joined through shared vertices) with fewer than
// `min_triangles` triangles, then the vertices no face uses (normals and colours follow).
ComponentRemoval RemoveSmallComponents(TriangleMesh* mesh, int min_triangles);

// Simplifies the mesh with OpenMesh's decimater: halfedge collapses ordered by the quadric error
// (Garland-Heckbert), each allowed only when every point of the original mesh that the collapse
// removes stays within `max_error` metres of the simplified surface (ModHausdorffT, a one-sided
// Hausdorff bound) and no face normal flips. Collapses keep the surviving vertices' positions, so
// their normals and colours stay valid. Vertices where the input is not manifold (where an
// observed region meets an unobserved one at a single edge point) are split for the decimater
// and merged again afterwards.
void Decimate(TriangleMesh* mesh, double max_error);

}  // namespace genscene::meshing
