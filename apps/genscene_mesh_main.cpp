// genscene-mesh: marching cubes on a workspace's TSDF volume (WS/tsdf.gsv -> WS/mesh.ply).
#include <cstdio>
#include <filesystem>

#include "core/cli.h"
#include "core/parallel.h"
#include "core/ply_io.h"
#include "core/tsdf_volume.h"
#include "core/workspace.h"
#include "meshing/marching_cubes.h"

int main(int argc, char** argv) {
  using namespace genscene;
  return RunApp("genscene-mesh", [&] {
    CLI::App app{
        "genscene-mesh: extract the surface of a workspace's TSDF volume (tsdf.gsv) as a binary "
        "PLY "
        "mesh with shared vertices, normals and colours (mesh.ply)"};
    CommandLine cli(app);
    meshing::MeshingOptions options;
    cli.Add(options, "Meshing");
    std::string ws_path;
    cli.AddFolder(ws_path, "workspace", "workspace folder holding tsdf.gsv");
    if (auto code = cli.Parse(argc, argv)) return *code;

    // Check the input before Workspace() would create a missing folder.
    if (!std::filesystem::is_directory(ws_path))
      throw Error(Format(ws_path, ": no such workspace folder"));
    const Workspace ws(ws_path);
    if (!std::filesystem::exists(ws.Tsdf())) {
      throw Error(
          Format(ws.Tsdf().string(), ": missing (run genscene-fuse on this workspace first)"));
    }
    const TsdfVolume volume = ReadTsdfVolume(ws.Tsdf());
    const meshing::MeshingResult result = meshing::ExtractMesh(volume, options);
    if (result.mesh.empty()) {
      throw Error(Format(ws.Tsdf().string(), ": the volume (", volume.num_blocks(),
                         " blocks) holds no surface at iso level ", options.iso_level,
                         " m; no mesh written"));
    }
    WritePly(ws.Mesh(), result.mesh, {true, PlyColors::kObserved});

    const meshing::MeshingStats& s = result.stats;
    std::printf("genscene-mesh: %zu blocks, %zu cells (%zu active) -> %zu vertices, %zu triangles",
                s.blocks, s.cells, s.active_cells, s.vertices, s.triangles);
    if (s.removed_components > 0) {
      std::printf(" (removed %zu small components, %zu triangles)", s.removed_components,
                  s.removed_component_triangles);
    }
    if (options.denoise_iterations > 0)
      std::printf(" (denoising moved vertices %.2f mm on average)", 1e3 * s.denoise_mean_offset);
    if (options.decimate_max_error > 0)
      std::printf(" (decimation removed %zu triangles)", s.decimated_triangles);
    std::printf(
        "\ngenscene-mesh: %.3f s (classify %.3f, scan %.3f, vertices %.3f, triangles %.3f, "
        "clean-up %.3f, denoise %.3f, decimate %.3f) on %d threads -> %s\n",
        s.seconds_total, s.seconds_classify, s.seconds_scan, s.seconds_vertices,
        s.seconds_triangles, s.seconds_cleanup, s.seconds_denoise, s.seconds_decimate,
        ThreadCount(), ws.Mesh().string().c_str());
    return 0;
  });
}
