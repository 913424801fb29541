// genscene-refine: vertex refinement through the sparse forward-mode differentiated path
// tracer: a workspace's mesh.ply (albedo.mcol, lights.json, keyframes/), or chosen meshes of a
// scene file (--scene, --refine NAME) against a view set (--views). Writes WS/mesh_refined.ply and
// WS/refine/ (per-iteration renders, report.json).
#include <cstdio>
#include <iostream>

#include "apps/refine.h"
#include "core/cli.h"

int main(int argc, char** argv) {
  using namespace genscene;
  return RunApp("genscene-refine", [&] {
    CLI::App app{
        "genscene-refine: refine mesh vertex positions so that path-traced renders match posed "
        "linear images "
        "(Levenberg-Marquardt on a sparse forward-mode auto-differentiated path tracer; visibility "
        "changes are "
        "not differentiated)"};
    CommandLine cli(app);
    inverse::RefineOptions options;
    cli.Add(options, "Vertex refinement");
    std::string ws_path;
    apps::RefineInputs in;
    cli.AddFolder(ws_path, "workspace",
                  "workspace folder (inputs default to its mesh.ply, albedo.mcol, lights.json, "
                  "keyframes/)");
    app.add_option("--scene", in.geometry.scene,
                   "scene file (.xml Mitsuba 3 subset or .json): geometry, albedo and lights");
    app.add_option("--mesh", in.geometry.mesh,
                   "mesh PLY (albedo from per-face/vertex colours unless --albedo)");
    app.add_option("--albedo", in.geometry.albedo, "Mesh Colors albedo (.mcol) for --mesh");
    app.add_option("--lights", in.lights,
                   "voxel lights (lights.json from genscene-lights) added to the scene");
    app.add_option("--views", in.views,
                   "view set or keyframes folder: intrinsics.txt, groundtruth.txt, rgb.txt");
    app.add_option("--refine", in.refine,
                   "name of a mesh to refine (repeat; default: every non-emitting mesh)");
    app.add_option("--truth", in.truth,
                   "PLY with the true positions of the refined vertices (vertex errors reported)");
    app.add_option("--render-spp", in.render_spp,
                   "samples per pixel of the per-iteration renders (0 = none)");
    if (auto code = cli.Parse(argc, argv)) return *code;
    if (in.render_spp < 0) throw Error(Format("--render-spp ", in.render_spp, " must be >= 0"));
    if (!in.geometry.scene.empty() && !in.geometry.mesh.empty())
      throw Error("give --scene or --mesh, not both");
    const Workspace ws(ws_path);
    const apps::RefineSummary summary = apps::RefineWorkspace(in, options, cli.seed(), ws);
    for (const std::string& w : summary.warnings)
      std::cerr << "genscene-refine: warning: " << w << "\n";
    std::printf("genscene-refine: %s\ngenscene-refine: -> %s, %s\n",
                apps::ToString(summary).c_str(), ws.RefinedMesh().string().c_str(),
                (ws.RefineDir()).string().c_str());
    return 0;
  });
}
