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

struct DenoiseStats {
  double mean_offset = 0.0;  // metres, mean distance a vertex moved
};

// Feature-preserving denoising: bilateral filtering of the face normals (Zheng et al. 2011,
// "Bilateral normal filtering for mesh denoising", local scheme), then the vertices moved to fit
// the filtered normals (Sun et al. 2007). Each of `iterations` normal passes replaces a face's
// unit normal by the normalised sum over the faces sharing a vertex with it (itself included) of
//     A_j exp(-|c_i - c_j|^2 / 2 sigma_c^2) exp(-|n_i - n_j|^2 / 2 sigma_s^2) n_j
// (A: area, c: centroid; sigma_c the mean distance between neighbouring faces' centroids,
// sigma_s = 2 sin(feature_angle / 2), the chord between unit normals `feature_angle` apart): a
// noisy plane smooths, a crease sharper than about feature_angle stays. Then 2 x `iterations`
// vertex passes each move a vertex by the mean over its faces of n_f (n_f . (c_f - x)); no vertex
// ends further than `max_offset` metres from where it started (the data decide the surface; the
// filter only removes what is within the noise). The vertex normals become the area-weighted
// mean of the filtered face normals. Jacobi passes (every update reads the previous pass):
// deterministic whatever the thread count. Colours and the face list are unchanged.
DenoiseStats Denoise(TriangleMesh* mesh, int iterations, double feature_angle_degrees,
                     double max_offset);

// Simplifies the mesh with OpenMesh's decimater: halfedge collapses ordered by the quadric error
// (Garland-Heckbert), each allowed only when every point of the original mesh that the collapse
// removes stays within `max_error` metres of the simplified surface (ModHausdorffT, a one-sided
// Hausdorff bound) and no face normal flips. Collapses keep the surviving vertices' positions, so
// their normals and colours stay valid. Vertices where the input is not manifold (where an
// observed region meets an unobserved one at a single edge point) are split for the decimater
// and merged again afterwards.
void Decimate(TriangleMesh* mesh, double max_error);

}  // namespace genscene::meshing
