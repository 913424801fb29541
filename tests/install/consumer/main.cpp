// Uses the installed genscene libraries as another project would: fuses a synthetic depth frame
// of a wall 1 m in front of the camera into a TSDF volume (genscene::fusion), raycasts it from a
// second pose and extracts its mesh (genscene::meshing). Exit status 0 when the raycast depth and
// the mesh lie on the wall.
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>

#include "core/camera.h"
#include "core/image.h"
#include "core/tsdf_volume.h"
#include "fusion/integrate.h"
#include "fusion/raycast.h"
#include "meshing/marching_cubes.h"

int main() {
  using namespace genscene;
  constexpr double kWall = 1.0;  // metres, planar depth of the wall
  const CameraIntrinsics k = CameraIntrinsics::Centered(64, 48, 60.0);
  const ImageDepth depth(k.width, k.height, static_cast<float>(kWall));

  TsdfVolumeParams params;
  params.voxel_size = 0.01;
  params.truncation = 0.04;
  TsdfVolume volume(params);
  const fusion::IntegrationStats stats = fusion::IntegrateFrame(
      volume, depth, ImageRgb(), k, Eigen::Isometry3d::Identity(), fusion::IntegrationOptions{});

  // Raycast from 5 cm to the side: the wall is still at 1 m planar depth.
  const Eigen::Isometry3d side(Eigen::Translation3d(0.05, 0.0, 0.0));
  const fusion::RaycastResult ray = fusion::RaycastVolume(volume, k, side);
  int hits = 0;
  double max_error = 0.0;
  for (int v = 12; v < 36; ++v) {
    for (int u = 16; u < 48; ++u) {
      if (ray.depth(u, v) <= 0.0f) continue;
      ++hits;
      max_error = std::max(max_error, std::abs(ray.depth(u, v) - kWall));
    }
  }

  const meshing::MeshingResult mesh = meshing::ExtractMesh(volume, meshing::MeshingOptions{});
  double mesh_error = 0.0;
  for (const Eigen::Vector3f& p : mesh.mesh.vertices) {
    mesh_error = std::max(mesh_error, std::abs(p.z() - kWall));
  }

  std::printf(
      "consumer: %zu blocks, raycast %d of %d centre pixels, max depth error %.2f mm; "
      "mesh %zu triangles, max vertex error %.2f mm\n",
      stats.blocks_allocated, hits, 24 * 32, 1e3 * max_error, mesh.mesh.faces.size(),
      1e3 * mesh_error);
  const bool ok = stats.blocks_allocated > 0 && hits == 24 * 32 && max_error < 2e-3 &&
                  mesh.mesh.faces.size() > 100 && mesh_error < 2e-3;
  if (!ok) std::fprintf(stderr, "consumer: error: the fused wall is not where it was observed\n");
  return ok ? 0 : 1;
}
