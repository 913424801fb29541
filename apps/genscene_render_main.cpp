// genscene-render: renders a scene (Mitsuba XML, our JSON, or a workspace's model) from the views
// of a view set, one given pose, or the scene file's own cameras. Writes one linear EXR and one
// sRGB PNG per view, named by the view's timestamp so that names sort in list order, optional
// depth/normal passes, and rgb.txt + groundtruth.txt + intrinsics.txt so that the output is itself
// a view set.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "core/cli.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/se3.h"
#include "core/trajectory.h"
#include "core/view_set.h"
#include "render/formats/mitsuba_xml.h"
#include "render/formats/scene_io.h"
#include "render/formats/workspace_scene.h"
#include "render/path_tracer.h"

namespace {

using namespace genscene;
using namespace genscene::render;

std::string StampName(double timestamp) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%017.6f", timestamp);  // fixed width: names sort in order
  return buffer;
}

// The views to render: a view set, one --pose with --intrinsics, or the scene's cameras.
std::vector<PosedView> ChooseViews(const std::string& views_dir, const std::string& pose,
                                   const std::string& intrinsics, const LoadedScene& loaded) {
  if (!views_dir.empty()) return ReadViewSet(views_dir);
  if (!pose.empty()) {
    if (intrinsics.empty()) throw Error("--pose needs --intrinsics FILE");
    std::istringstream in(pose);
    double v[7];
    for (double& x : v) {
      if (!(in >> x)) throw Error(Format("--pose '", pose, "': expected 'tx ty tz qx qy qz qw'"));
    }
    PosedView view;
    view.intrinsics = ResolveIntrinsics(intrinsics);
    view.world_from_camera = PoseFromTranslationQuaternion(
        {v[0], v[1], v[2]}, Eigen::Quaterniond(v[6], v[3], v[4], v[5]));
    return {view};
  }
  if (loaded.views.empty())
    throw Error("the scene has no cameras: give --views DIR or --pose with --intrinsics");
  return loaded.views;
}

// Scene-file settings apply to the options the command line did not set.
void ApplySceneSettings(const RenderSettings& s, const CommandLine& cli, RenderOptions* options) {
  if (s.max_depth && !cli.Given("max_depth")) options->max_depth = *s.max_depth;
  if (s.samples_per_pixel && !cli.Given("spp")) options->spp = *s.samples_per_pixel;
  if (s.hide_emitters && !cli.Given("hide_emitters")) options->hide_emitters = *s.hide_emitters;
  if (s.pixel_filter && !cli.Given("filter")) {
    options->filter = s.pixel_filter->kind == PixelFilter::Kind::kBox ? "box" : "gaussian";
    if (!cli.Given("filter_stddev")) options->filter_stddev = s.pixel_filter->stddev;
  }
  options->Validate();
}

}  // namespace

int main(int argc, char** argv) {
  return RunApp("genscene-render", [&] {
    CLI::App app{
        "genscene-render: path-trace a scene (Mitsuba 3 XML subset or genscene JSON) into linear "
        "EXR "
        "and sRGB PNG images"};
    CommandLine cli(app);
    RenderOptions options;
    cli.Add(options, "Rendering");
    std::string scene_path, views_dir, pose, intrinsics, out;
    bool aovs = false;
    app.add_option("--scene", scene_path,
                   "scene file: .xml (Mitsuba 3 subset) or .json (genscene), or a workspace folder "
                   "(its model: mesh, albedo, lights; its keyframe cameras)")
        ->required();
    app.add_option("--views", views_dir,
                   "view set folder (intrinsics.txt, groundtruth.txt, rgb.txt)");
    app.add_option("--pose", pose, "one camera pose 'tx ty tz qx qy qz qw' (world_from_camera)");
    app.add_option("--intrinsics", intrinsics,
                   "intrinsics for --pose: file or tum1|tum2|tum3|primesense");
    cli.AddFolder(out, "out", "output folder");
    app.add_flag("--aovs", aovs,
                 "also write <stamp>_depth.exr (planar z, m) and <stamp>_normal.exr (world)");
    std::string export_xml, export_json;
    app.add_option("--export-xml", export_xml,
                   "also write the scene and views as Mitsuba 3 XML (meshes as PLY beside it)");
    app.add_option("--export-json", export_json,
                   "also write the scene and views in genscene's JSON format");
    if (auto code = cli.Parse(argc, argv)) return *code;

    const LoadedScene loaded = LoadSceneOrWorkspace(scene_path);
    for (const std::string& w : loaded.warnings)
      std::cerr << "genscene-render: warning: " << w << "\n";
    ApplySceneSettings(loaded.settings, cli, &options);
    const std::vector<PosedView> views = ChooseViews(views_dir, pose, intrinsics, loaded);
    const PathTracer tracer(loaded.scene);
    if (!export_xml.empty()) {
      for (const std::string& w :
           ExportMitsubaXml(export_xml, loaded.scene, views, loaded.settings)) {
        std::cerr << "genscene-render: warning: " << w << "\n";
      }
    }
    if (!export_json.empty()) SaveSceneJson(export_json, loaded.scene, views, loaded.settings);

    // Every image goes in under a temporary name; the lists last, so a complete rgb.txt means a
    // complete view set.
    std::ostringstream rgb_list;
    rgb_list << "# timestamp filename (linear EXR)\n";
    Trajectory poses;
    const auto start = std::chrono::steady_clock::now();
    uint64_t rays = 0;
    for (size_t i = 0; i < views.size(); ++i) {
      const PosedView& view = views[i];
      const RenderOutput image = tracer.Render(view, options, cli.seed() + i);
      rays += image.rays.total();
      const std::string stamp = StampName(view.timestamp);
      const std::filesystem::path dir(out);
      WriteExr(dir / (stamp + ".exr"), image.radiance);
      WritePng(dir / (stamp + ".png"), image.radiance);
      if (aovs) {
        WriteDepthExr(dir / (stamp + "_depth.exr"), image.depth);
        WriteExr(dir / (stamp + "_normal.exr"), image.normal);
      }
      rgb_list << stamp << " " << stamp << ".exr\n";
      poses.Add(view.timestamp, view.world_from_camera);
      std::cerr << "\rrendered " << i + 1 << "/" << views.size() << " views" << std::flush;
    }
    std::cerr << "\n";
    const std::filesystem::path dir(out);
    bool same_intrinsics = true;
    for (const PosedView& v : views)
      same_intrinsics &= v.intrinsics.ToString() == views.front().intrinsics.ToString();
    if (same_intrinsics) {
      WriteIntrinsicsFile(dir / "intrinsics.txt", views.front().intrinsics);
      WriteTumTrajectory(dir / "groundtruth.txt", poses);
      WriteTextFileAtomically(dir / "rgb.txt", rgb_list.str());
    } else {
      std::cerr
          << "genscene-render: the views have different intrinsics; no view-set lists written\n";
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf(
        "genscene-render: %zu views, %d spp, max depth %d, filter %s: %.2f s, %.2f Mrays/s -> %s\n",
        views.size(), options.spp, options.max_depth, options.filter.c_str(), seconds,
        rays / seconds / 1e6, out.c_str());
    return 0;
  });
}
