// genscene-synth: writes a synthetic RGB-D sequence with exact ground truth as a TUM folder.
#include <iostream>

#include "apps/synth.h"
#include "core/cli.h"

int main(int argc, char** argv) {
  return genscene::RunApp("genscene-synth", [&] {
    CLI::App app{
        "genscene-synth: render a synthetic RGB-D sequence (TUM layout + groundtruth.txt + "
        "intrinsics.txt + mesh_gt.ply) with exact ground truth"};
    genscene::CommandLine cli(app);
    genscene::apps::SynthOptions synth;
    cli.Add(synth, "Scene");
    std::string out;
    cli.AddFolder(out, "out", "output folder (created; replaced only if genscene wrote it)");
    if (auto code = cli.Parse(argc, argv)) return *code;

    const auto s = genscene::apps::Synthesize(synth, cli.seed(), out);
    std::cout << "genscene-synth: wrote " << s.frames << " frames of " << s.width << "x" << s.height
              << " (depth " << s.min_depth << " to " << s.max_depth
              << " m) and a ground-truth mesh of " << s.mesh_faces << " triangles to " << out
              << "\n";
    return 0;
  });
}
