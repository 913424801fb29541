// genscene: the whole chain in one command.
//   genscene demo [--out WS]            synthesise a Cornell-box sequence and run the chain on it
//   genscene run --input SRC --out WS   run the chain on a recording
//   genscene inspect --input SRC        read and check a recording, print what it holds
// The chain (apps/chain.h): ingest -> fusion -> meshing -> texturing -> albedo -> lights -> refine
// -> export (-> evaluate, when the input carries a synthetic ground truth). Stages whose outputs
// are up to date are skipped, so a run that was stopped resumes where it stopped.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>

#include "apps/chain.h"
#include "apps/ingest.h"
#include "apps/report.h"
#include "apps/synth.h"
#include "capture/openni2_source.h"
#include "capture/record.h"
#include "core/cli.h"
#include "core/ply_io.h"
#include "core/workspace.h"

namespace {

using genscene::apps::StageRow;

// While `genscene run` records a live camera, Ctrl-C ends the recording (the chain then runs on
// it) instead of the run.
std::atomic<bool> g_recording{false};
std::atomic<bool> g_stop_recording{false};
// What the interrupt message says after the stage; a live run names its recording.
char g_resume_hint[2048] = "; the finished stages are kept: run the same command again to resume\n";

// Records the live camera `input` into WS/capture.oni (until --max-frames, Ctrl-C, or the camera
// ends its stream) and returns the recording's path; the chain then reads the recording, so that
// every stage sees the same frames and a stopped run resumes from them.
std::string RecordLiveCamera(const std::string& input, const genscene::SourceOptions& source,
                             const genscene::capture::CaptureOptions& camera,
                             const genscene::Workspace& ws, std::vector<StageRow>& rows) {
  const auto start = std::chrono::steady_clock::now();
  const std::filesystem::path oni = ws.LiveRecording();
  genscene::capture::RecordSummary summary;
  std::string description;
  {
    auto frames = genscene::capture::OpenAnySource(input, source, camera);
    description = frames->Describe();
    std::cerr << "[0/" << genscene::apps::ChainStages().size() << "] capture: recording "
              << description << " into " << oni.string()
              << " (Ctrl-C ends the recording; the chain then runs on it)\n";
    genscene::capture::RecordSettings settings;
    settings.max_frames = static_cast<size_t>(source.max_frames);
    settings.response = genscene::CameraResponse::Parse(source.camera_response);
    settings.stop = &g_stop_recording;
    settings.progress = [](size_t n, std::optional<size_t> total) {
      std::cerr << "\rrecording: " << n;
      if (total) std::cerr << "/" << *total;
      std::cerr << " frames" << std::flush;
    };
    g_recording = true;
    try {
      summary = genscene::capture::RecordFrames(*frames, {oni, {}}, settings);
    } catch (...) {
      g_recording = false;
      std::cerr << "\n";
      throw;
    }
    g_recording = false;
    std::cerr << "\n";
  }
  rows.push_back({"capture",
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                  genscene::apps::PeakMegabytes(),
                  false,
                  genscene::Format(summary.frames, " frames (t = ", summary.first_timestamp, " .. ",
                                   summary.last_timestamp, " s) from ", description, " into ",
                                   oni.string(), ", ", summary.skipped, " camera frames skipped"),
                  {}});
  std::snprintf(g_resume_hint, sizeof(g_resume_hint),
                "; the finished stages and the recording are kept: genscene run --input %s "
                "--out %s resumes\n",
                oni.c_str(), ws.root().c_str());
  return oni.string();
}

// Runs the chain with the workspace's log open (appended), then prints and logs the summary.
void RunLogged(const std::string& input, const genscene::SourceOptions& source,
               const genscene::apps::ChainOptions& chain, uint64_t seed,
               const genscene::Workspace& ws, bool existed, bool redo, const std::string& until,
               std::vector<StageRow>& rows) {
  const bool fresh_log = !std::filesystem::exists(ws.Log());
  std::ofstream log(ws.Log(), std::ios::app);
  if (!log) throw genscene::Error(ws.Log().string() + ": cannot open the log for writing");
  log << "== genscene on " << input << " (seed " << seed << ")\n" << std::flush;
  try {
    genscene::apps::RunChain(input, source, chain, seed, ws, redo, log, rows, until);
  } catch (...) {
    // Bad input found before any stage finished leaves no file behind (the error is on stderr),
    // and no workspace folder this run made. Otherwise the summary says how far the run came.
    bool finished = false;
    for (const StageRow& r : rows)
      finished = finished || (!r.skipped && !r.failed && r.stage != "synth");
    if (fresh_log && !finished) {
      log.close();
      std::filesystem::remove(ws.Log());
      std::error_code ec;
      if (!existed) std::filesystem::remove(ws.root(), ec);  // only when empty
    } else {
      genscene::apps::WriteSummaryJson(ws, input, seed, rows);
      log << genscene::apps::SummaryTable(rows) << std::flush;
    }
    throw;
  }
  genscene::apps::WriteSummaryJson(ws, input, seed, rows);
  const std::string table = genscene::apps::SummaryTable(rows);
  log << table << std::flush;
  std::cout << "\n"
            << table << "\nworkspace: " << ws.root().string() << " (log: " << ws.Log().string()
            << ")\n";
}

void PrintReport(const std::filesystem::path& markdown) {
  std::cout << "report: " << markdown.string() << "\n";
  const std::filesystem::path html = markdown.parent_path() / "report.html";
  if (std::filesystem::exists(html)) std::cout << "report: " << html.string() << "\n";
}

int Demo(int argc, char** argv) {
  CLI::App app{
      "genscene demo: synthesise a Cornell-box RGB-D sequence with ground truth, run the whole "
      "chain on it and judge the model on novel views against the truth"};
  genscene::CommandLine cli(app);
  genscene::apps::SynthOptions synth;
  synth.frames = 20;
  cli.Add(synth, "Synthetic scene");
  genscene::apps::ChainOptions chain = genscene::apps::DemoChainOptions();
  chain.AddTo(cli);
  std::string out = "genscene-demo";
  bool redo = false, report = true;
  cli.AddFolder(out, "out", "workspace folder", false);
  app.add_flag("!--no-report", report, "do not write the report (WS/report/report.md) at the end");
  std::string until;
  app.add_option("--until", until,
                 "last stage to run: ingest, fusion, meshing, texturing, albedo, lights, refine, "
                 "export, evaluate");
  app.add_flag("--redo", redo, "re-run stages whose outputs are up to date");
  if (auto code = cli.Parse(argc, argv)) return *code;

  const genscene::Workspace ws(out);
  std::vector<StageRow> rows;
  if (!redo && std::filesystem::exists(ws.Input())) {
    rows.push_back({"synth",
                    0.0,
                    genscene::apps::PeakMegabytes(),
                    true,
                    "up to date (" + ws.Input().string() + "), skipped",
                    {}});
  } else {
    std::fprintf(stderr, "[0/%zu] synth\n", genscene::apps::ChainStages().size());
    const auto start = std::chrono::steady_clock::now();
    const auto s = genscene::apps::Synthesize(synth, cli.seed(), ws.Input());
    rows.push_back({"synth",
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
                    genscene::apps::PeakMegabytes(),
                    false,
                    genscene::Format(s.frames, " frames ", s.width, "x", s.height,
                                     ", ground-truth mesh ", s.mesh_faces, " triangles"),
                    {}});
  }
  RunLogged(ws.Input().string(), genscene::SourceOptions(), chain, cli.seed(), ws, true, redo,
            until, rows);
  if (report && until.empty()) {
    genscene::apps::ReportOptions options;
    options.sweep = true;
    std::fprintf(stderr, "report (with the light penalty sweep)\n");
    PrintReport(genscene::apps::WriteReport(ws, options, cli.seed()));
  }
  return 0;
}

int Report(int argc, char** argv) {
  CLI::App app{
      "genscene report: a report with PNG figures of speed against error for every stage a "
      "workspace holds, written to WORKSPACE/report/report.md and, with the model in 3D, "
      "report.html"};
  genscene::CommandLine cli(app);
  std::string workspace;
  genscene::apps::ReportOptions options;
  app.add_option("workspace", workspace, "workspace folder (of genscene run or genscene demo)")
      ->required();
  app.add_flag("--sweep", options.sweep,
               "re-estimate the lights over penalty weights 1e-5 to 1e-1 (the paper's Fig. 3)");
  app.add_option("--sweep-spp", options.sweep_spp, "samples per pixel of the sweep's renders")
      ->capture_default_str()
      ->check(CLI::Range(2, 65536));
  app.add_option("--three-dir", options.three_dir,
                 "three.js for report.html's 3D view (three.min.js, examples/js/)")
      ->capture_default_str();
  if (auto code = cli.Parse(argc, argv)) return *code;
  if (!std::filesystem::is_directory(workspace))
    throw genscene::Error(workspace + ": no such workspace folder");
  const genscene::Workspace ws(workspace);
  PrintReport(genscene::apps::WriteReport(ws, options, cli.seed()));
  return 0;
}

int Run(int argc, char** argv) {
  CLI::App app{
      "genscene run: run the whole chain on a recording into a workspace: ingest, fusion, meshing, "
      "texturing, albedo, lights, refine, export (stages whose outputs are up to date are "
      "skipped)"};
  genscene::CommandLine cli(app);
  genscene::SourceOptions source;
  cli.Add(source, "Input");
  genscene::capture::CaptureOptions camera;
  cli.Add(camera, "Camera");
  genscene::apps::ChainOptions chain = genscene::apps::RunChainOptions();
  chain.AddTo(cli);
  std::string input, out;
  bool redo = false;
  app.add_option("--input", input,
                 "TUM folder, view set, Redwood folder, .oni recording, or openni2[:URI]: a live "
                 "camera, recorded into WORKSPACE/capture.oni until --max-frames or Ctrl-C, then "
                 "the chain runs on the recording")
      ->required();
  cli.AddFolder(out, "out", "workspace folder");
  app.add_flag("--redo", redo, "re-run stages whose outputs are up to date");
  std::string until;
  app.add_option("--until", until,
                 "last stage to run: ingest, fusion, meshing, texturing, albedo, lights, refine, "
                 "export, evaluate");
  if (auto code = cli.Parse(argc, argv)) return *code;

  const bool existed = std::filesystem::exists(out);
  const genscene::Workspace ws(out);
  std::vector<StageRow> rows;
  if (genscene::capture::IsLiveCameraSpec(input)) {
    try {
      input = RecordLiveCamera(input, source, camera, ws, rows);
    } catch (...) {
      std::error_code ec;
      if (!existed) std::filesystem::remove(ws.root(), ec);  // only when empty
      throw;
    }
    // The recording holds exactly the selected frames.
    source.first_frame = 0;
    source.stride = 1;
    source.max_frames = 0;
  }
  RunLogged(input, source, chain, cli.seed(), ws, existed, redo, until, rows);
  return 0;
}

int Inspect(int argc, char** argv) {
  CLI::App app{
      "genscene inspect: read and check every frame of a recording and print what it holds"};
  genscene::CommandLine cli(app);
  genscene::SourceOptions source;
  cli.Add(source, "Input");
  std::string input;
  app.add_option("input,--input", input,
                 "TUM folder, view set, Redwood folder, .oni recording, or a PLY mesh")
      ->required();
  if (auto code = cli.Parse(argc, argv)) return *code;
  if (std::filesystem::path(input).extension() == ".ply") {
    const genscene::TriangleMesh mesh = genscene::ReadPly(input);
    const auto box = mesh.Bounds();
    std::cout << input << ": " << mesh.vertices.size() << " vertices, " << mesh.faces.size()
              << " triangles, bounds (" << box.min().transpose() << ") to ("
              << box.max().transpose() << ") m" << (mesh.normals.empty() ? "" : ", normals")
              << (mesh.vertex_colors.empty() ? "" : ", vertex colours")
              << (mesh.face_colors.empty() ? "" : ", face colours") << "\n";
    return 0;
  }
  const auto s = genscene::apps::IngestSequence(input, source, {});
  std::cout << s.description << "\n" << genscene::apps::Describe(s) << "\n";
  return 0;
}

void PrintUsage() {
  std::cout << "genscene: generative scene models from RGB-D recordings\n\n"
               "usage: genscene <command> [flags]   (genscene <command> --help for its flags)\n\n"
               "commands:\n"
               "  demo      synthesise a Cornell-box sequence and run the chain on it\n"
               "  run       run the chain on a recording: --input SRC --out WORKSPACE\n"
               "  report    write WORKSPACE/report/report.md: speed against error of every stage, "
               "with figures\n"
               "  inspect   read and check a recording (or a PLY mesh) and print what it holds\n";
}

// Ctrl-C: say which stage was interrupted and that the same command resumes (finished stages and
// every output are written atomically, so what is on disk is whole). While a live camera is being
// recorded, Ctrl-C ends the recording instead. Only async-signal-safe calls.
void OnInterrupt(int signal) {
  if (signal == SIGINT && g_recording) {
    g_stop_recording = true;
    return;
  }
  const char* stage = genscene::apps::RunningStage();
  const char head[] = "\ngenscene: interrupted";
  const char mid[] = " in stage ";
  ssize_t ignored = write(STDERR_FILENO, head, sizeof(head) - 1);
  if (stage) {
    ignored = write(STDERR_FILENO, mid, sizeof(mid) - 1);
    ignored = write(STDERR_FILENO, stage, std::strlen(stage));
  }
  ignored = write(STDERR_FILENO, g_resume_hint, std::strlen(g_resume_hint));
  (void)ignored;
  _exit(130);
}

}  // namespace

int main(int argc, char** argv) {
  std::signal(SIGINT, OnInterrupt);
  std::signal(SIGTERM, OnInterrupt);
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
    if (command == "--version") {
      std::cout << "genscene " << genscene::Version() << "\n";
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
    if (command == "report") return Report(n, args.data());
    std::cerr << "genscene: error: unknown command '" << command << "'\n";
    PrintUsage();
    return 2;
  });
}
