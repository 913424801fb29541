// genscene-fuse: KinectFusion tracking and sparse TSDF fusion of an RGB-D sequence into a
// workspace (trajectory.txt, tsdf.gsv, keyframes/, fusion.json).
#include <iostream>

#include "apps/fuse.h"
#include "core/cli.h"

int main(int argc, char** argv) {
  return genscene::RunApp("genscene-fuse", [&] {
    CLI::App app{
        "genscene-fuse: track the camera and fuse the depth frames of a sequence into a "
        "sparse TSDF (writes trajectory.txt, tsdf.gsv, keyframes/ and fusion.json into the "
        "workspace)"};
    genscene::CommandLine cli(app);
    genscene::SourceOptions source;
    genscene::fusion::FusionOptions fusion;
    genscene::capture::CaptureOptions camera;
    cli.Add(source, "Input");
    cli.Add(camera, "Camera");
    cli.Add(fusion, "Fusion");
    std::string input, out;
    app.add_option(
           "--input", input,
           "TUM or Redwood folder, view set, .oni recording, or openni2[:URI] (live camera)")
        ->required();
    cli.AddFolder(out, "workspace", "workspace folder (created when missing)");
    if (auto code = cli.Parse(argc, argv)) return *code;

    const genscene::Workspace workspace(out);
    const auto summary = genscene::apps::FuseSequence(input, source, fusion, workspace, camera);
    std::cout << genscene::apps::ToString(summary)
              << "wrote:      " << workspace.Trajectory().string() << ", "
              << workspace.Tsdf().string() << ", " << workspace.Keyframes().string() << "/\n";
    return 0;
  });
}
