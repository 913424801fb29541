// Distances from points to a triangle mesh (the surface error of a reconstruction against a
// ground-truth mesh): a uniform grid over the triangles, exact point-triangle distances
// (closest point by Voronoi regions, Ericson 2005 §5.1.5), searched within a cut-off radius.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/mesh.h"

namespace genscene {

class MeshDistance {
 public:
  // `max_distance`: distances beyond it are reported as max_distance (the search stops there).
  // Keeps a reference to `mesh`, which must outlive this object.
  MeshDistance(const TriangleMesh& mesh, double max_distance);

  double Distance(const Eigen::Vector3d& point) const;

 private:
  // The grid cell of a point in cell units, clamped to the grid before the cast to int (a point
  // far outside would overflow int, which is undefined behaviour).
  Eigen::Vector3i CellOf(const Eigen::Vector3d& cell_units) const;

  const TriangleMesh& mesh_;
  double max_distance_;
  double cell_ = 1.0;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  Eigen::Vector3i dims_ = Eigen::Vector3i::Ones();
  std::vector<std::vector<int>> cells_;  // triangle indices per cell
};

struct SurfaceError {
  size_t points = 0;
  double mean = 0.0, rms = 0.0, max = 0.0;  // metres, over the vertices
  // Metres, over the surface: each face's points weighted by its area. A decimated mesh keeps
  // few vertices where it is flat and many at its borders and corners, so the vertex figures
  // weigh those far more than the surface does.
  double area_mean = 0.0, area_rms = 0.0;
};

// Distances of every vertex of `mesh` to `truth` (the reconstruction's accuracy), and of the
// face points at barycentric (4,1,1)/6, (1,4,1)/6, (1,1,4)/6 and (1,1,1)/3, weighted by area.
SurfaceError MeasureSurfaceError(const TriangleMesh& mesh, const TriangleMesh& truth,
                                 double max_distance = 0.1);

}  // namespace genscene
