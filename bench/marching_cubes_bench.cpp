// Marching cubes speed: cells per second over dense gyroid volumes of a few sizes, with 1 thread
// and all threads, and the decimation table of triangle count against the
// measured one-sided Hausdorff error on an analytic torus. Each time is the best of
// 3 runs after a warm-up. Run by hand:
//   build/bench/bench_marching_cubes [--dump DIR] [--tsdf WS/tsdf.gsv [--decimation]] [sizes...]
// --dump DIR writes each grid as DIR/gyroid_<N>.npy (float32, axes z, y, x: numpy's C order of
// our x-fastest lattice) and our counts and times to DIR/genscene_mc.txt, for
// bench/compare_marching_cubes.py (skimage on the same grids).
// --tsdf meshes a fused volume (a genscene-fuse workspace's tsdf.gsv) in-process, timed without
// the file I/O; with --dump its counts and time go to DIR/genscene_fused.txt (Open3D's
// extract_triangle_mesh in the script). --decimation adds the decimation table for that fused
// scene (each bound is a full decimation: minutes for a mesh of a few 100k triangles).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/analytic_volume.h"
#include "core/mesh_distance.h"
#include "core/parallel.h"
#include "core/tsdf_volume.h"
#include "meshing/marching_cubes.h"

using namespace genscene;

namespace {

// Gyroid with period 32 voxels, scaled to roughly metres of distance near its zero set.
double Gyroid(const Eigen::Vector3i& g, double voxel) {
  const double k = 2.0 * M_PI / 32.0;
  const double x = k * g.x(), y = k * g.y(), z = k * g.z();
  return (std::sin(x) * std::cos(y) + std::sin(y) * std::cos(z) + std::sin(z) * std::cos(x)) /
         (1.5 * k) * voxel;
}

// Writes the N^3 lattice values of the volume (dense, from lattice 0) as a float32 .npy file.
void WriteNpy(const std::filesystem::path& path, const TsdfVolume& volume, int n) {
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(n) +
                       ", " + std::to_string(n) + ", " + std::to_string(n) + "), }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::ofstream out(path, std::ios::binary);
  out.write("\x93NUMPY\x01\x00", 8);
  const uint16_t length = static_cast<uint16_t>(header.size());
  out.write(reinterpret_cast<const char*>(&length), 2);
  out << header;
  for (int z = 0; z < n; ++z) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const float sdf = volume.FindVoxel(Eigen::Vector3i(x, y, z))->sdf;
        out.write(reinterpret_cast<const char*>(&sdf), sizeof(float));
      }
    }
  }
}

double BestSeconds(const TsdfVolume& volume, meshing::MeshingResult* result) {
  *result = meshing::ExtractMesh(volume, meshing::MeshingOptions());  // warm-up
  double best = 1e300;
  for (int run = 0; run < 3; ++run) {
    const auto start = std::chrono::steady_clock::now();
    *result = meshing::ExtractMesh(volume, meshing::MeshingOptions());
    best = std::min(
        best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return best;
}

void DecimationTable() {
  analytic::AnalyticVolumeSpec spec;  // 2 cm voxels
  const auto torus = [](const Eigen::Vector3d& p) {
    return analytic::TorusSdf(p, {0.0113, -0.0071, 0.0047}, 0.28, 0.11);
  };
  const TsdfVolume volume = analytic::MakeAnalyticVolume(spec, torus);
  const TriangleMesh full = meshing::ExtractMesh(volume, meshing::MeshingOptions()).mesh;
  std::printf(
      "\nDecimation of an analytic torus (R 0.28 m, r 0.11 m, 2 cm voxels): one-sided Hausdorff =\n"
      "max distance of the full mesh's vertices to the simplified mesh; max |sdf| of face "
      "centroids\n");
  std::printf("%12s %10s %10s %14s %16s %10s\n", "bound mm", "triangles", "vertices",
              "Hausdorff mm", "centroid sdf mm", "seconds");
  for (double bound : {0.0, 0.0005, 0.001, 0.002, 0.005, 0.01}) {
    meshing::MeshingOptions options;
    options.decimate_max_error = bound;
    const meshing::MeshingResult r = meshing::ExtractMesh(volume, options);
    double hausdorff = 0.0, centroid = 0.0;
    for (const Eigen::Vector3f& v : full.vertices) {
      hausdorff = std::max(hausdorff, analytic::DistanceToMesh(v.cast<double>(), r.mesh));
    }
    for (const Eigen::Vector3i& f : r.mesh.faces) {
      const Eigen::Vector3f c =
          (r.mesh.vertices[f[0]] + r.mesh.vertices[f[1]] + r.mesh.vertices[f[2]]) / 3.0f;
      centroid = std::max(centroid, std::abs(torus(c.cast<double>())));
    }
    std::printf("%12.2f %10zu %10zu %14.3f %16.3f %10.3f\n", bound * 1e3, r.mesh.faces.size(),
                r.mesh.vertices.size(), hausdorff * 1e3, centroid * 1e3, r.stats.seconds_decimate);
  }
}

// A fused volume: marching cubes timed in-process (1 thread and all threads), then decimation at
// several bounds with the one-sided Hausdorff error measured (every vertex of the full mesh to the
// simplified one, exact point-triangle distances).
void FusedScene(const std::filesystem::path& tsdf, const std::filesystem::path& dump,
                bool decimation) {
  const TsdfVolume volume = ReadTsdfVolume(tsdf);
  std::printf("\nFused volume %s: %zu blocks, voxel %.4f m; best of 3 after a warm-up\n",
              tsdf.string().c_str(), volume.num_blocks(), volume.voxel_size());
  std::printf("%8s %12s %10s %10s %10s %10s   phases ms: %s\n", "threads", "cells", "vertices",
              "triangles", "ms", "Mcells/s", "classify scan vertices triangles");
  meshing::MeshingResult full;
  for (int threads : {1, 0}) {
    SetThreadCount(threads);
    const double seconds = BestSeconds(volume, &full);
    const meshing::MeshingStats& s = full.stats;
    std::printf("%8d %12zu %10zu %10zu %10.1f %10.1f   %.1f %.1f %.1f %.1f\n", ThreadCount(),
                s.cells, s.vertices, s.triangles, seconds * 1e3, s.cells / seconds / 1e6,
                s.seconds_classify * 1e3, s.seconds_scan * 1e3, s.seconds_vertices * 1e3,
                s.seconds_triangles * 1e3);
    if (!dump.empty() && threads == 0) {
      std::ofstream(dump / "genscene_fused.txt")
          << ThreadCount() << " " << s.vertices << " " << s.triangles << " " << seconds << "\n";
    }
  }
  SetThreadCount(0);
  if (!decimation) return;
  std::printf(
      "\nDecimation of the fused scene: one-sided Hausdorff = max distance of the full mesh's "
      "vertices to the simplified mesh\n");
  std::printf("%12s %10s %10s %14s %14s %10s\n", "bound mm", "triangles", "vertices",
              "Hausdorff mm", "mean dist mm", "seconds");
  std::printf("%12s %10zu %10zu %14s %14s %10s\n", "off", full.mesh.faces.size(),
              full.mesh.vertices.size(), "0", "0", "-");
  for (double bound : {0.0005, 0.001, 0.002, 0.003, 0.005, 0.01}) {
    meshing::MeshingOptions options;
    options.decimate_max_error = bound;
    const meshing::MeshingResult r = meshing::ExtractMesh(volume, options);
    const MeshDistance distance(r.mesh, 10 * bound);
    double hausdorff = 0.0, sum = 0.0;
    for (const Eigen::Vector3f& v : full.mesh.vertices) {
      const double d = distance.Distance(v.cast<double>());
      hausdorff = std::max(hausdorff, d);
      sum += d;
    }
    std::printf("%12.2f %10zu %10zu %14.3f %14.4f %10.3f\n", bound * 1e3, r.mesh.faces.size(),
                r.mesh.vertices.size(), hausdorff * 1e3, sum / full.mesh.vertices.size() * 1e3,
                r.stats.seconds_decimate);
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::filesystem::path dump, tsdf;
  bool decimation = false;
  std::vector<int> sizes;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--dump") == 0 && i + 1 < argc)
      dump = argv[++i];
    else if (std::strcmp(argv[i], "--tsdf") == 0 && i + 1 < argc)
      tsdf = argv[++i];
    else if (std::strcmp(argv[i], "--decimation") == 0)
      decimation = true;
    else
      sizes.push_back(std::atoi(argv[i]));
  }
  if (sizes.empty()) sizes = {64, 128, 192};
  if (!dump.empty()) std::filesystem::create_directories(dump);
  std::ofstream summary;
  if (!dump.empty()) summary.open(dump / "genscene_mc.txt");

  std::printf("Dense gyroid volumes (period 32 voxels, all blocks allocated); best of 3\n");
  std::printf("%6s %8s %12s %10s %10s %10s %8s %10s %12s\n", "N", "threads", "cells", "active",
              "vertices", "triangles", "ms", "Mcells/s", "classify ms");
  for (int n : sizes) {
    n = (n + kTsdfBlockSide - 1) / kTsdfBlockSide * kTsdfBlockSide;
    analytic::AnalyticVolumeSpec spec;
    spec.voxel_size = 0.01;
    spec.truncation = 0.05;
    spec.sparse = false;
    spec.lo = Eigen::Vector3i::Zero();
    spec.hi = Eigen::Vector3i::Constant(n - 1);
    const TsdfVolume volume = analytic::MakeAnalyticVolume(
        spec, nullptr, [&](const Eigen::Vector3i& g) { return Gyroid(g, spec.voxel_size); });
    if (!dump.empty()) WriteNpy(dump / ("gyroid_" + std::to_string(n) + ".npy"), volume, n);
    for (int threads : {1, 0}) {
      SetThreadCount(threads);
      meshing::MeshingResult result;
      const double seconds = BestSeconds(volume, &result);
      const meshing::MeshingStats& s = result.stats;
      std::printf("%6d %8d %12zu %10zu %10zu %10zu %8.1f %10.1f %12.1f\n", n, ThreadCount(),
                  s.cells, s.active_cells, s.vertices, s.triangles, seconds * 1e3,
                  s.cells / seconds / 1e6, s.seconds_classify * 1e3);
      if (summary.is_open()) {
        summary << n << " " << ThreadCount() << " " << s.vertices << " " << s.triangles << " "
                << seconds << "\n";
      }
    }
  }
  SetThreadCount(0);
  DecimationTable();
  if (!tsdf.empty()) FusedScene(tsdf, dump, decimation);
  return 0;
}
