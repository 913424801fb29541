// genscene: the whole chain in one command.
//   genscene demo [--out WS]            synthesise a Cornell-box sequence and run the chain on it
//   genscene run --input SRC --out WS   run the chain on a recording
//   genscene inspect --input SRC        read and check a recording, print what it holds
// Stages land one by one (lights and refinement to come); today the chain reads and checks the
// input (ingest, sequence.json), fuses it (fusion), extracts the mesh (meshing), back-projects the
// keyframes onto it (texturing) and clusters the observed colour into albedo (albedo).
#include <chrono>
#include <cstdio>
#include <iostream>

#include "apps/fuse.h"
#include "apps/ingest.h"
#include "apps/synth.h"
#include "apps/texture.h"
#include "core/cli.h"
#include "core/ply_io.h"
#include "core/tsdf_volume.h"
#include "meshing/marching_cubes.h"
#include "core/workspace.h"

namespace {

using genscene::apps::IngestSummary;

struct StageRow {
  std::string stage;
  double seconds;
  std::string result;
};

void PrintSummary(const std::vector<StageRow>& rows) {
  std::printf("\n%-10s %9s  %s\n", "stage", "seconds", "result");
  for (const auto& r : rows) std::printf("%-10s %9.2f  %s\n", r.stage.c_str(), r.seconds, r.result.c_str());
}

template <typename F>
auto Timed(double* seconds, F&& f) {
  const auto start = std::chrono::steady_clock::now();
  auto result = f();
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string Describe(const IngestSummary& s) {
  return genscene::Format(s.frames, " frames ", s.width, "x", s.height, ", depth ", s.min_depth, "-",
                          s.max_depth, " m, ", 100.0 * s.valid_depth_fraction, "% valid, ",
                          s.frames_with_pose, " with pose");
}

// The stages' options, as flags and config sections of `genscene run` and `genscene demo`.
struct ChainOptions {
  genscene::fusion::FusionOptions fusion;
  genscene::meshing::MeshingOptions meshing;
  genscene::texturing::TexturingOptions texturing;
  genscene::texturing::AlbedoOptions albedo;
  void AddTo(genscene::CommandLine& cli) {
    cli.Add(fusion, "Fusion");
    cli.Add(meshing, "Meshing");
    cli.Add(texturing, "Texturing");
    cli.Add(albedo, "Albedo");
  }
};

// Runs the stages that exist on `input` into workspace `ws`, appending to `rows`. A stage whose
// outputs are newer than its inputs is skipped unless `redo`.
void RunChain(const std::string& input, const genscene::SourceOptions& source, const ChainOptions& options,
              const genscene::Workspace& ws, bool redo, std::vector<StageRow>& rows) {
  using genscene::Format;
  using genscene::Workspace;
  const auto summary_path = ws.root() / "sequence.json";
  double seconds = 0.0;
  if (!redo && Workspace::IsFresh({summary_path}, {input})) {
    rows.push_back({"ingest", 0.0, "up to date (" + summary_path.string() + "), skipped"});
  } else {
    const auto s = Timed(&seconds, [&] { return genscene::apps::IngestSequence(input, source, summary_path); });
    rows.push_back({"ingest", seconds, Describe(s)});
  }

  const std::vector<std::filesystem::path> fused = {ws.Trajectory(), ws.Tsdf(), ws.root() / "fusion.json"};
  if (!redo && Workspace::IsFresh(fused, {input})) {
    rows.push_back({"fusion", 0.0, "up to date (" + ws.Tsdf().string() + "), skipped"});
  } else {
    const auto s = Timed(&seconds, [&] { return genscene::apps::FuseSequence(input, source, options.fusion, ws); });
    std::string result = Format(s.fused, "/", s.frames, " frames fused (", s.lost, " lost, ", s.degenerate,
                                " degenerate, ", s.blank, " blank), ", s.blocks, " blocks (", s.megabytes,
                                " MB), ", s.keyframes, " keyframes");
    if (s.ate) result += Format(", ATE ", 100.0 * s.ate->rmse, " cm");
    rows.push_back({"fusion", seconds, result});
  }

  if (!redo && Workspace::IsFresh({ws.Mesh()}, {ws.Tsdf()})) {
    rows.push_back({"meshing", 0.0, "up to date (" + ws.Mesh().string() + "), skipped"});
  } else {
    const auto result = Timed(&seconds, [&] {
      const genscene::TsdfVolume volume = genscene::ReadTsdfVolume(ws.Tsdf());
      auto r = genscene::meshing::ExtractMesh(volume, options.meshing);
      if (r.mesh.empty()) throw genscene::Error(Format(ws.Tsdf().string(), ": the volume holds no surface; no mesh written"));
      genscene::WritePly(ws.Mesh(), r.mesh);
      return r;
    });
    rows.push_back({"meshing", seconds, Format(result.stats.vertices, " vertices, ", result.stats.triangles,
                                               " triangles (", ws.Mesh().string(), ")")});
  }

  if (!redo && Workspace::IsFresh({ws.Texture(), ws.TexturePly()}, {ws.Mesh(), ws.Keyframes()})) {
    rows.push_back({"texturing", 0.0, "up to date (" + ws.Texture().string() + "), skipped"});
  } else {
    genscene::SourceOptions keyframes;
    keyframes.camera_response = source.camera_response;
    const auto s = Timed(&seconds, [&] {
      return genscene::apps::TextureWorkspace({}, keyframes, options.texturing, ws);
    });
    rows.push_back({"texturing", seconds, genscene::apps::ToString(s)});
  }

  if (!redo && Workspace::IsFresh({ws.Albedo(), ws.AlbedoPly()}, {ws.Mesh(), ws.Texture()})) {
    rows.push_back({"albedo", 0.0, "up to date (" + ws.Albedo().string() + "), skipped"});
  } else {
    const auto s = Timed(&seconds, [&] { return genscene::apps::AlbedoWorkspace({}, options.albedo, ws); });
    rows.push_back({"albedo", seconds, genscene::apps::ToString(s)});
  }
}

int Demo(int argc, char** argv) {
  CLI::App app{"genscene demo: synthesise a Cornell-box RGB-D sequence with ground truth and run "
               "the chain on it"};
  genscene::CommandLine cli(app);
  genscene::apps::SynthOptions synth;
  synth.frames = 20;
  cli.Add(synth, "Synthetic scene");
  ChainOptions chain;
  chain.AddTo(cli);
  std::string out = "genscene-demo";
  bool redo = false;
  app.add_option("out,--out", out, "workspace folder")->capture_default_str();
  app.add_flag("--redo", redo, "re-run stages whose outputs are up to date");
  if (auto code = cli.Parse(argc, argv)) return *code;

  const genscene::Workspace ws(out);
  std::vector<StageRow> rows;
  if (!redo && std::filesystem::exists(ws.Input())) {
    rows.push_back({"synth", 0.0, "up to date (" + ws.Input().string() + "), skipped"});
  } else {
    double seconds = 0.0;
    const auto s = Timed(&seconds, [&] { return genscene::apps::Synthesize(synth, cli.seed(), ws.Input()); });
    rows.push_back({"synth", seconds, genscene::Format(s.frames, " frames ", s.width, "x", s.height,
                                                       ", ground-truth mesh ", s.mesh_faces, " triangles")});
  }
  RunChain(ws.Input().string(), genscene::SourceOptions(), chain, ws, redo, rows);
  PrintSummary(rows);
  std::cout << "\nworkspace: " << ws.root().string() << "\n";
  return 0;
}

int Run(int argc, char** argv) {
  CLI::App app{"genscene run: run the chain on a recording into a workspace"};
  genscene::CommandLine cli(app);
  genscene::SourceOptions source;
  cli.Add(source, "Input");
  ChainOptions chain;
  chain.AddTo(cli);
  std::string input, out;
  bool redo = false;
  app.add_option("--input", input, "TUM folder, view set, Redwood folder, .oni recording or openni2[:URI]")->required();
  app.add_option("out,--out", out, "workspace folder")->required();
  app.add_flag("--redo", redo, "re-run stages whose outputs are up to date");
  if (auto code = cli.Parse(argc, argv)) return *code;

  const genscene::Workspace ws(out);
  std::vector<StageRow> rows;
  RunChain(input, source, chain, ws, redo, rows);
  PrintSummary(rows);
  return 0;
}

int Inspect(int argc, char** argv) {
  CLI::App app{"genscene inspect: read and check every frame of a recording and print what it holds"};
  genscene::CommandLine cli(app);
  genscene::SourceOptions source;
  cli.Add(source, "Input");
  std::string input;
  app.add_option("input,--input", input, "TUM folder, view set, Redwood folder, .oni recording, or a PLY mesh")->required();
  if (auto code = cli.Parse(argc, argv)) return *code;
  if (std::filesystem::path(input).extension() == ".ply") {
    const genscene::TriangleMesh mesh = genscene::ReadPly(input);
    const auto box = mesh.Bounds();
    std::cout << input << ": " << mesh.vertices.size() << " vertices, " << mesh.faces.size()
              << " triangles, bounds (" << box.min().transpose() << ") to (" << box.max().transpose() << ") m"
              << (mesh.normals.empty() ? "" : ", normals") << (mesh.vertex_colors.empty() ? "" : ", vertex colours")
              << (mesh.face_colors.empty() ? "" : ", face colours") << "\n";
    return 0;
  }
  const auto s = genscene::apps::IngestSequence(input, source, {});
  std::cout << s.description << "\n" << Describe(s) << "\n";
  return 0;
}

void PrintUsage() {
  std::cout << "genscene: generative scene models from RGB-D recordings\n\n"
               "usage: genscene <command> [flags]   (genscene <command> --help for its flags)\n\n"
               "commands:\n"
               "  demo      synthesise a Cornell-box sequence and run the chain on it\n"
               "  run       run the chain on a recording: --input SRC --out WORKSPACE\n"
               "  inspect   read and check a recording (or a PLY mesh) and print what it holds\n";
}

}  // namespace

int main(int argc, char** argv) {
  return genscene::RunApp("genscene", [&] {
    if (argc < 2) {
      PrintUsage();
      return 2;
    }
    const std::string command = argv[1];
    if (command == "--help" || command == "-h" || command == "help") {
      PrintUsage();
      return 0;
    }
    // The sub-command sees argv without the program name.
    const std::string name = "genscene " + command;
    std::vector<char*> args(argv + 1, argv + argc);
    args[0] = const_cast<char*>(name.c_str());
    const int n = static_cast<int>(args.size());
    if (command == "demo") return Demo(n, args.data());
    if (command == "run") return Run(n, args.data());
    if (command == "inspect") return Inspect(n, args.data());
    std::cerr << "genscene: error: unknown command '" << command << "'\n";
    PrintUsage();
    return 2;
  });
}
