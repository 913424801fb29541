// Point-to-mesh distances (the surface error of a reconstruction against a ground truth).
#include "core/mesh_distance.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/check.h"

namespace genscene {
namespace {

TriangleMesh OneTriangle() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}};
  return m;
}

TEST(MeshDistance, EveryVoronoiRegionOfATriangle) {
  const TriangleMesh t = OneTriangle();
  const MeshDistance d(t, 10.0);
  EXPECT_NEAR(d.Distance({0.2, 0.2, 0.5}), 0.5, 1e-12);                     // above the face
  EXPECT_NEAR(d.Distance({-1, -1, 0}), std::sqrt(2.0), 1e-12);              // beyond vertex a
  EXPECT_NEAR(d.Distance({2, -1, 0}), std::sqrt(2.0), 1e-12);               // beyond vertex b
  EXPECT_NEAR(d.Distance({0.5, -2, 0}), 2.0, 1e-12);                        // beyond edge ab
  EXPECT_NEAR(d.Distance({1, 1, 0}), std::sqrt(0.5), 1e-12);                // beyond edge bc
  EXPECT_NEAR(d.Distance({-3, 0.5, 4}), 5.0, 1e-12);                        // beyond edge ca
  EXPECT_NEAR(MeshDistance(t, 0.25).Distance({0.2, 0.2, 3}), 0.25, 1e-12);  // cut off
}

TEST(MeshDistance, SurfaceErrorOfAShiftedMesh) {
  TriangleMesh grid;  // a 1 m square of 20 x 20 cells
  const int n = 20;
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) grid.vertices.push_back({x / float(n), y / float(n), 0.0f});
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const int i = y * (n + 1) + x;
      grid.faces.push_back({i, i + 1, i + n + 2});
      grid.faces.push_back({i, i + n + 2, i + n + 1});
    }
  }
  EXPECT_EQ(MeasureSurfaceError(grid, grid).max, 0.0);
  TriangleMesh shifted = grid;
  for (auto& v : shifted.vertices) v.z() += 0.003f;
  const SurfaceError e = MeasureSurfaceError(shifted, grid);
  EXPECT_EQ(e.points, grid.vertices.size());
  EXPECT_NEAR(e.mean, 0.003, 1e-6);
  EXPECT_NEAR(e.rms, 0.003, 1e-6);
  EXPECT_NEAR(e.area_mean, 0.003, 1e-6);
  EXPECT_NEAR(e.area_rms, 0.003, 1e-6);
  // A sliver 2 cm above the grid adds three far vertices but almost no area: the vertex figures
  // move, the surface's hardly.
  TriangleMesh sliver = shifted;
  const int base = static_cast<int>(sliver.vertices.size());
  sliver.vertices.push_back({0.5f, 0.5f, 0.02f});
  sliver.vertices.push_back({0.51f, 0.5f, 0.02f});
  sliver.vertices.push_back({0.5f, 0.51f, 0.02f});
  sliver.faces.push_back({base, base + 1, base + 2});
  const SurfaceError with_sliver = MeasureSurfaceError(sliver, grid);
  const double n_grid = static_cast<double>(grid.vertices.size());
  EXPECT_NEAR(with_sliver.mean, (n_grid * 0.003 + 3 * 0.02) / (n_grid + 3), 1e-6);
  EXPECT_NEAR(with_sliver.area_mean, 0.003 + 0.017 * 5e-5, 1e-6);
  const TriangleMesh empty;
  EXPECT_THROW({ MeshDistance d(empty, 0.1); }, Error);
}

}  // namespace
}  // namespace genscene
