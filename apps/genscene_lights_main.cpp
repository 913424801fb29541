// genscene-lights: voxel light estimation from geometry, albedo and posed images:
// a workspace (WS/mesh.ply + WS/albedo.mcol + WS/keyframes/), or --scene / --mesh with --views.
// Writes WS/lights.json, renders of the views with the estimate in WS/lights/, and a Mitsuba 3
// scene WS/lights/scene.xml.
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "apps/lights.h"
#include "core/cli.h"

int main(int argc, char** argv) {
  using namespace genscene;
  return RunApp("genscene-lights", [&] {
    CLI::App app{
        "genscene-lights: estimate voxel lights (RGB + six directional weights per voxel) from "
        "known geometry, "
        "albedo and posed linear images, by path tracing with cached coefficients"};
    CommandLine cli(app);
    inverse::LightEstimationOptions options;
    cli.Add(options, "Light estimation");
    std::string ws_path;
    apps::LightsInputs in;
    cli.AddFolder(ws_path, "workspace",
                  "workspace folder (inputs default to its mesh.ply, albedo.mcol, keyframes/)");
    app.add_option(
        "--scene", in.scene,
        "scene file (.xml Mitsuba 3 subset or .json): geometry and albedo; emitters ignored");
    app.add_option("--mesh", in.mesh,
                   "mesh PLY (albedo from per-face/vertex colours unless --albedo)");
    app.add_option("--albedo", in.albedo, "Mesh Colors albedo (.mcol) for --mesh");
    app.add_option("--views", in.views,
                   "view set or keyframes folder: intrinsics.txt, groundtruth.txt, rgb.txt");
    app.add_option("--novel", in.novel,
                   "another view set to judge the estimate on (rendered, RMSE reported)");
    app.add_option("--render-spp", in.render_spp,
                   "samples per pixel of the renders written to WS/lights/");
    if (auto code = cli.Parse(argc, argv)) return *code;
    if (in.render_spp < 2) throw Error(Format("--render-spp ", in.render_spp, " must be >= 2"));
    if (!in.scene.empty() && !in.mesh.empty()) throw Error("give --scene or --mesh, not both");
    const Workspace ws(ws_path);
    const apps::LightsSummary summary = apps::LightsWorkspace(in, options, cli.seed(), ws);
    for (const std::string& w : summary.warnings)
      std::cerr << "genscene-lights: warning: " << w << "\n";
    std::printf("genscene-lights: %s\ngenscene-lights: -> %s, %s\n",
                apps::ToString(summary).c_str(), ws.Lights().string().c_str(),
                (ws.LightsDir()).string().c_str());
    return 0;
  });
}
