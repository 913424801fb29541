// genscene-view: look at a workspace (mesh, Mesh Colors, trajectory, keyframes) in an OpenGL
// window, or render one frame into a PNG with --screenshot (under `xvfb-run -a` without a display).
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "core/cli.h"
#include "core/image_io.h"
#include "viewer/viewer_options.h"
#include "viewer/window.h"

namespace {

using namespace genscene;
using namespace genscene::viewer;

// The requested mode, or the first of observed / albedo / geometry the workspace supports.
ColorMode ChooseMode(const ViewerOptions& options, const ViewData& data) {
  if (!options.mode.empty()) {
    const ColorMode mode = ParseColorMode(options.mode);
    const bool has = mode == ColorMode::kGeometry ||
                     (data.mesh && (mode == ColorMode::kObserved  ? data.observed.has_value()
                                    : mode == ColorMode::kShading ? data.observed && data.albedo
                                                                  : data.albedo.has_value()));
    if (!has) {
      std::printf(
          "genscene-view: --mode %s needs what this workspace lacks (above); showing geometry\n",
          options.mode.c_str());
      return ColorMode::kGeometry;
    }
    return mode;
  }
  if (data.observed) return ColorMode::kObserved;
  if (data.albedo) return ColorMode::kAlbedo;
  return ColorMode::kGeometry;
}

bool HasDisplay() {
  const char* x11 = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  return (x11 && *x11) || (wayland && *wayland);
}

}  // namespace

int main(int argc, char** argv) {
  return RunApp("genscene-view", [&] {
    CLI::App app{
        "genscene-view: show a workspace (mesh.ply with texture.mcol / albedo.mcol evaluated per "
        "fragment, trajectory.txt, keyframes/) in an OpenGL 3.3 window, or render one frame with "
        "--screenshot. Without a display run it under `xvfb-run -a`."};
    CommandLine cli(app);
    ViewerOptions options;
    cli.Add(options, "Viewer");
    std::string ws_path;
    cli.AddFolder(ws_path, "workspace", "workspace folder");
    if (auto code = cli.Parse(argc, argv)) return *code;

    const std::string example = Format("xvfb-run -a genscene-view ", ws_path,
                                       options.screenshot.empty() ? " ..." : " --screenshot ...");
    if (!HasDisplay()) {
      throw Error(
          Format("no display (DISPLAY is not set): run `", example, "`",
                 options.screenshot.empty() ? ", or add --screenshot out.png under it" : ""));
    }

    // Open what exists; say what is missing.
    const ViewData data = LoadWorkspace(ws_path);
    for (const std::string& line : data.missing) std::printf("genscene-view: %s\n", line.c_str());
    if (!data.mesh && data.trajectory.empty() && data.keyframes.empty()) {
      throw Error(Format(ws_path, ": nothing to show (no mesh.ply, trajectory.txt or keyframes/)"));
    }

    DrawOptions draw;
    draw.mode = ChooseMode(options, data);
    draw.lookup = options.lookup == "linear" ? Lookup::kLinear : Lookup::kNearest;
    draw.cull_back_faces = options.cull_back_faces;
    draw.show_overlay = !options.no_overlay;
    draw.show_refined = options.refined;
    if (options.refined && !data.refined_mesh) {
      throw Error(
          Format(ws_path, ": --refined: no mesh_refined.ply to show (run genscene-refine)"));
    }
    const PosedView view =
        ResolveCamera(ParseCameraSpec(options.camera), data, ParseSize(options.size));

    try {
      if (!options.screenshot.empty()) {
        const ImageRgb image = RenderScreenshot(data, view, draw);
        WritePng(options.screenshot, image);
        std::printf("genscene-view: %s, %dx%d, camera %s -> %s\n", ColorModeName(draw.mode),
                    image.width(), image.height(), options.camera.c_str(),
                    options.screenshot.c_str());
        return 0;
      }
      RunInteractive(data, view, draw);
    } catch (const NoDisplayError& e) {
      throw Error(
          Format(e.what(), ": run `", example, "`",
                 options.screenshot.empty() ? ", or add --screenshot out.png under it" : ""));
    }
    return 0;
  });
}
