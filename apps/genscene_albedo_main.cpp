// genscene-albedo: the albedo initialisation, clustering a workspace's observed colour by
// chromaticity (WS/mesh.ply + WS/texture.mcol -> WS/albedo.mcol, WS/albedo.ply, WS/albedo.json).
#include <cstdio>
#include <filesystem>

#include "apps/texture.h"
#include "core/cli.h"

int main(int argc, char** argv) {
  using namespace genscene;
  return RunApp("genscene-albedo", [&] {
    CLI::App app{
        "genscene-albedo: cluster a workspace's observed colour (texture.mcol) by chromaticity "
        "into "
        "piecewise-constant albedo (albedo.mcol, albedo.ply; clusters in albedo.json)"};
    CommandLine cli(app);
    texturing::AlbedoOptions options;
    cli.Add(options, "Albedo");
    std::string ws_path, mesh;
    cli.AddFolder(ws_path, "workspace", "workspace folder holding mesh.ply and texture.mcol");
    app.add_option("--mesh", mesh, "mesh PLY the texture was made for (default: WS/mesh.ply)");
    if (auto code = cli.Parse(argc, argv)) return *code;
    if (!std::filesystem::is_directory(ws_path))
      throw Error(Format(ws_path, ": no such workspace folder"));
    const Workspace ws(ws_path);
    const apps::AlbedoSummary summary = apps::AlbedoWorkspace(mesh, options, ws);
    std::printf("genscene-albedo: %s\ngenscene-albedo: -> %s, %s\n",
                apps::ToString(summary).c_str(), ws.Albedo().string().c_str(),
                ws.AlbedoPly().string().c_str());
    return 0;
  });
}
