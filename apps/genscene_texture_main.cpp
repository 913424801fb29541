// genscene-texture: the observed colour of a workspace's mesh as Mesh Colors, back-projected from
// its keyframes (WS/mesh.ply + WS/keyframes/ -> WS/texture.mcol, WS/texture.ply).
#include <cstdio>
#include <filesystem>

#include "apps/texture.h"
#include "core/cli.h"
#include "core/parallel.h"

int main(int argc, char** argv) {
  using namespace genscene;
  return RunApp("genscene-texture", [&] {
    CLI::App app{
        "genscene-texture: back-project a workspace's keyframes onto its mesh as Mesh Colors "
        "(texture.mcol) and as vertex colours of the subdivided mesh (texture.ply)"};
    CommandLine cli(app);
    texturing::TexturingOptions options;
    cli.Add(options, "Texturing");
    SourceOptions source;
    source.intrinsics = "";
    std::string ws_path;
    apps::TextureInputs inputs;
    std::string mesh, views, response = source.camera_response;
    cli.AddFolder(ws_path, "workspace", "workspace folder (outputs; inputs unless given below)");
    app.add_option("--mesh", mesh, "mesh PLY (default: WS/mesh.ply)");
    app.add_option("--views", views,
                   "posed colour images: a keyframes folder or view set (default: WS/keyframes)");
    app.add_option("--camera-response", response, "8-bit colour to linear: srgb, linear or gamma:G")
        ->capture_default_str();
    if (auto code = cli.Parse(argc, argv)) return *code;
    if (mesh.empty() && views.empty() && !std::filesystem::is_directory(ws_path)) {
      throw Error(Format(ws_path, ": no such workspace folder"));
    }
    inputs.mesh = mesh;
    inputs.views = views;
    source.camera_response = response;
    const Workspace ws(ws_path);
    const apps::TextureSummary summary = apps::TextureWorkspace(inputs, source, options, ws);
    std::printf("genscene-texture: %s\ngenscene-texture: %d threads -> %s, %s\n",
                apps::ToString(summary).c_str(), ThreadCount(), ws.Texture().string().c_str(),
                ws.TexturePly().string().c_str());
    return 0;
  });
}
