// The apps as a user meets them: exit codes, one-line errors naming the file or key, no output
// left behind on failure, --help that documents the flags.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <sstream>

#include "core/file_util.h"
#include "core/image_io.h"
#include "core/view_set.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;
using test::AppPath;
using test::RunCommand;

// The last non-empty line of the output (apps print their error last).
std::string LastLine(const std::string& output) {
  std::string text = output;
  while (!text.empty() && text.back() == '\n') text.pop_back();
  const auto nl = text.find_last_of('\n');
  return nl == std::string::npos ? text : text.substr(nl + 1);
}

size_t FilesBelow(const fs::path& dir) {
  size_t n = 0;
  std::error_code ec;
  for (const auto& e : fs::recursive_directory_iterator(dir, ec)) n += e.is_regular_file() ? 1 : 0;
  return n;
}

class Apps : public ::testing::Test {
 protected:
  // A small valid TUM sequence made by genscene-synth.
  void MakeSequence(const fs::path& dir) {
    const auto r =
        RunCommand(AppPath("genscene-synth") + " --frames 3 --size 32x24 --out " + dir.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  // Expects failure with a one-line "app: error: ..." message containing every needle, and no
  // file in `out` (when given).
  void ExpectFailure(const std::string& command, const std::vector<std::string>& needles,
                     const fs::path& out = {}) {
    const auto r = RunCommand(command);
    EXPECT_NE(r.exit_code, 0) << command << "\n" << r.output;
    const std::string line = LastLine(r.output);
    EXPECT_NE(line.find(": error: "), std::string::npos) << r.output;
    for (const auto& needle : needles)
      EXPECT_NE(line.find(needle), std::string::npos) << "'" << needle << "' not in: " << line;
    if (!out.empty()) {
      EXPECT_EQ(FilesBelow(out), 0u) << "output left in " << out;
    }
  }
  test::TempDir dir_;
};

TEST_F(Apps, HelpDocumentsFlagsWithUnitsAndDefaults) {
  const auto r = RunCommand(AppPath("genscene-synth") + " --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* flag :
       {"--frames", "--size", "--noise", "--fov", "--seed", "--threads", "--config", "--out"}) {
    EXPECT_NE(r.output.find(flag), std::string::npos) << flag << " missing from --help";
  }
  EXPECT_NE(r.output.find("[deg]"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("160x120"), std::string::npos) << "default of --size not shown";
  const auto run = RunCommand(AppPath("genscene") + " run --help");
  EXPECT_EQ(run.exit_code, 0);
  for (const char* flag :
       {"--input", "--intrinsics", "--depth-scale", "--camera-response", "--associations"}) {
    EXPECT_NE(run.output.find(flag), std::string::npos) << flag;
  }
  EXPECT_EQ(RunCommand(AppPath("genscene") + " --help").exit_code, 0);
  EXPECT_NE(RunCommand(AppPath("genscene") + " frobnicate").exit_code, 0);
}

// Every app and every genscene command, as a user calls them.
const std::vector<std::string>& AllCommands() {
  static const std::vector<std::string> commands = {
      "genscene demo",    "genscene run",     "genscene report", "genscene inspect",
      "genscene-synth",   "genscene-capture", "genscene-fuse",   "genscene-mesh",
      "genscene-texture", "genscene-albedo",  "genscene-lights", "genscene-refine",
      "genscene-render",  "genscene-view"};
  return commands;
}
std::string CommandPath(const std::string& command) {
  const auto space = command.find(' ');
  return space == std::string::npos ? AppPath(command)
                                    : AppPath(command.substr(0, space)) + command.substr(space);
}

TEST_F(Apps, EveryAppPrintsItsVersion) {
  for (const std::string& command : AllCommands()) {
    const auto r = RunCommand(CommandPath(command) + " --version");
    EXPECT_EQ(r.exit_code, 0) << command << ": " << r.output;
    EXPECT_NE(r.output.find("genscene 0."), std::string::npos) << command << ": " << r.output;
  }
  const auto r = RunCommand(AppPath("genscene") + " --version");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("genscene 0."), std::string::npos) << r.output;
}

// Each flag is listed once, no option is shown as REQUIRED twice (a positional folder and its
// --out alias), and one name has one meaning: path length is --max-depth, the sensor's range
// --range-min / --range-max.
TEST_F(Apps, HelpListsEachFlagOnceWithOneNamePerMeaning) {
  for (const std::string& command : AllCommands()) {
    const auto r = RunCommand(CommandPath(command) + " --help");
    ASSERT_EQ(r.exit_code, 0) << command << ": " << r.output;
    std::map<std::string, int> listed;
    int required = 0;
    std::istringstream lines(r.output);
    for (std::string line; std::getline(lines, line);) {
      const auto first = line.find_first_not_of(' ');
      if (first == std::string::npos) continue;
      if (line.compare(first, 2, "--") == 0 || line.compare(first, 1, "-") == 0) {
        const std::string names = line.substr(first, line.find_first_of(" =", first) - first);
        std::istringstream parts(names);
        for (std::string name; std::getline(parts, name, ',');) {
          name = name.substr(0, name.find('{'));
          ++listed[name];
        }
      }
      if (line.find("REQUIRED") != std::string::npos && line.find("--out") != std::string::npos)
        ++required;
    }
    for (const auto& [name, count] : listed) EXPECT_EQ(count, 1) << command << ": " << name;
    EXPECT_EQ(required, 0) << command << ": --out shown as REQUIRED";
    EXPECT_EQ(listed.count("--depth-max") + listed.count("--depth-min"), 0u) << command;
    // How many frames to read is --max-frames wherever frames are read.
    if (listed.count("--max-frames")) {
      EXPECT_EQ(listed.count("--frames"), 0u) << command;
    }
  }
  const auto run = RunCommand(AppPath("genscene") + " run --help");
  EXPECT_NE(run.output.find("--range-max"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("--lights-max-depth"), std::string::npos) << run.output;
}

// Usage errors exit 2, every other error 1; the folder is the positional or --out, not both.
TEST_F(Apps, UsageErrorsExitTwo) {
  MakeSequence(dir_ / "seq");
  const std::string fuse = AppPath("genscene-fuse") + " --input " + (dir_ / "seq").string();
  const auto unknown = RunCommand(fuse + " --out " + (dir_ / "a").string() + " --frobnicate");
  EXPECT_EQ(unknown.exit_code, 2) << unknown.output;
  EXPECT_NE(LastLine(unknown.output).find("unknown flag --frobnicate"), std::string::npos);
  const auto missing = RunCommand(fuse);
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(LastLine(missing.output).find("workspace is required"), std::string::npos);
  const auto two =
      RunCommand(fuse + " " + (dir_ / "a").string() + " --out " + (dir_ / "b").string());
  EXPECT_EQ(two.exit_code, 2) << two.output;
  EXPECT_NE(LastLine(two.output).find("two folders given"), std::string::npos);
  const auto value = RunCommand(fuse + " --out " + (dir_ / "a").string() + " --voxel-size -1");
  EXPECT_EQ(value.exit_code, 2) << value.output;
  EXPECT_NE(LastLine(value.output).find("voxel_size"), std::string::npos) << value.output;
  const auto config = RunCommand(fuse + " --out " + (dir_ / "a").string() + " --config " +
                                 (dir_ / "no_such.json").string());
  EXPECT_EQ(config.exit_code, 2) << config.output;
  const auto input = RunCommand(AppPath("genscene-fuse") + " --input " +
                                (dir_ / "no_such_folder").string() + " " + (dir_ / "a").string());
  EXPECT_EQ(input.exit_code, 1) << input.output;
  EXPECT_EQ(RunCommand(AppPath("genscene") + " frobnicate").exit_code, 2);
}

// A flag that defaults to true is turned off by --no-<flag>; the positional folder and --out are
// the same folder.
TEST_F(Apps, NoFlagTurnsOffATrueDefault) {
  MakeSequence(dir_ / "seq");
  const std::string fuse =
      AppPath("genscene-fuse") + " --tracking known --input " + (dir_ / "seq").string();
  const auto off = RunCommand(fuse + " " + (dir_ / "off").string() + " --no-feature-tracking");
  ASSERT_EQ(off.exit_code, 0) << off.output;
  const auto on = RunCommand(fuse + " --out " + (dir_ / "on").string());
  ASSERT_EQ(on.exit_code, 0) << on.output;
  EXPECT_NE(ReadTextFile(dir_ / "off" / "fusion.json").find("\"feature_tracking\": false"),
            std::string::npos);
  EXPECT_NE(ReadTextFile(dir_ / "on" / "fusion.json").find("\"feature_tracking\": true"),
            std::string::npos);
}

// (ICP cannot track frames of 32 x 24 pixels: the synthetic poses are fused instead. Lights from
// 200 pixels of 3 such frames fit worse than an ambient light: the refinement's fit gate is off so
// that every stage, the refinement's report included, runs.)
TEST_F(Apps, DemoRunsAndSkipsFreshStages) {
  const fs::path ws = dir_ / "ws";
  const std::string demo =
      AppPath("genscene") +
      " demo --frames 3 --size 32x24 --tracking known --lights-grid 3 --lights-pixels-per-view 200 "
      "--lights-rounds 1 --refine-iterations 1 --refine-spp 2 --refine-pixels-per-view 100 "
      "--no-refine-fit-gate "
      "--evaluate-views 1 --evaluate-truth-spp 4 --evaluate-model-spp 4 --decimate-max-error 0 "
      "--no-report "
      "--out " +
      ws.string();
  auto r = RunCommand(demo);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(ws / "input/rgb.txt"));
  EXPECT_TRUE(fs::exists(ws / "input/groundtruth.txt"));
  EXPECT_TRUE(fs::exists(ws / "input/mesh_gt.ply"));
  EXPECT_TRUE(fs::exists(ws / "sequence.json"));
  EXPECT_TRUE(fs::exists(ws / "trajectory.txt"));
  EXPECT_TRUE(fs::exists(ws / "tsdf.gsv"));
  EXPECT_TRUE(fs::exists(ws / "mesh.ply"));
  EXPECT_NE(r.output.find("3 frames 32x24"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("frames fused"), std::string::npos) << r.output;
  // The report (without its sweeps, which re-run stages) of that workspace.
  const auto report = RunCommand(AppPath("genscene") + " report " + ws.string());
  EXPECT_EQ(report.exit_code, 0) << report.output;
  for (const char* output :
       {"lights.json", "mesh_refined.ply", "export/model.ply", "export/model.xml",
        "export/model.glb", "export/trajectory.txt", "evaluation/evaluation.json", "summary.json",
        "genscene.log", "report/report.md", "report/tracking_time.png",
        "report/refine_error.png"}) {
    EXPECT_TRUE(fs::exists(ws / output)) << output;
  }
  EXPECT_NE(ReadTextFile(ws / "report/report.md").find("## Light estimation"), std::string::npos);
  // PLY colours are named for what they hold: observed colour in the fused, textured and refined
  // meshes (the refined one keeps them), albedo in albedo.ply and the exported model.
  for (const char* observed : {"mesh.ply", "texture.ply", "mesh_refined.ply"}) {
    const std::string header = ReadTextFile(ws / observed).substr(0, 1000);
    EXPECT_NE(header.find("property float color_r"), std::string::npos) << observed;
    EXPECT_EQ(header.find("albedo_r"), std::string::npos) << observed;
  }
  for (const char* albedo : {"albedo.ply", "export/model.ply"}) {
    const std::string header = ReadTextFile(ws / albedo).substr(0, 1000);
    EXPECT_NE(header.find("property float albedo_r"), std::string::npos) << albedo;
  }
  EXPECT_NE(r.output.find("peak MB"), std::string::npos) << r.output;
  // genscene-render renders the workspace's model from its keyframe cameras, lit.
  const auto render = RunCommand(AppPath("genscene-render") + " --scene " + ws.string() +
                                 " --spp 4 --out " + (dir_ / "render").string());
  ASSERT_EQ(render.exit_code, 0) << render.output;
  const std::vector<PosedView> keyframes = ReadViewSet(ws / "keyframes");
  const std::vector<PosedView> rendered = ReadViewSet(dir_ / "render");
  ASSERT_EQ(rendered.size(), keyframes.size());
  for (size_t i = 0; i < rendered.size(); ++i) {
    EXPECT_TRUE(rendered[i].world_from_camera.isApprox(keyframes[i].world_from_camera, 1e-6));
  }
  double sum = 0.0;
  int images = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "render")) {
    if (e.path().extension() != ".exr") continue;
    const ImageRgb image = ReadColorImage(e.path(), CameraResponse::Parse("linear"));
    for (int v = 0; v < image.height(); ++v) {
      for (int u = 0; u < image.width(); ++u) sum += image(u, v).sum();
    }
    ++images;
  }
  EXPECT_EQ(images, static_cast<int>(keyframes.size()));
  EXPECT_GT(sum, 0.0) << "the workspace's renders are black";
  r = RunCommand(demo);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("up to date"), std::string::npos) << r.output;
  EXPECT_EQ(test::CountFilesContaining(ws, ".tmp-"), 0);
}

TEST_F(Apps, ReportNeedsAWorkspaceWithOutputs) {
  ExpectFailure(AppPath("genscene") + " report " + (dir_ / "nope").string(),
                {"nope", "no such workspace folder"});
  fs::create_directories(dir_ / "empty");
  ExpectFailure(AppPath("genscene") + " report " + (dir_ / "empty").string(),
                {"empty", "no stage outputs"}, dir_ / "empty");
}

TEST_F(Apps, MissingInput) {
  ExpectFailure(AppPath("genscene") + " run --input " + (dir_ / "nope").string() + " --out " +
                    (dir_ / "ws").string(),
                {"nope", "no such file or folder"}, dir_ / "ws");
}

TEST_F(Apps, EmptyList) {
  MakeSequence(dir_ / "seq");
  std::ofstream(dir_ / "seq/rgb.txt") << "# nothing\n";
  ExpectFailure(AppPath("genscene") + " run --input " + (dir_ / "seq").string() + " --out " +
                    (dir_ / "ws").string(),
                {"rgb.txt", "empty list"}, dir_ / "ws");
}

TEST_F(Apps, CorruptPng) {
  MakeSequence(dir_ / "seq");
  const fs::path victim = fs::directory_iterator(dir_ / "seq/depth")->path();
  std::ofstream(victim, std::ios::binary | std::ios::trunc) << "\x89PNG\r\n\x1a\n garbage";
  ExpectFailure(AppPath("genscene") + " run --input " + (dir_ / "seq").string() + " --out " +
                    (dir_ / "ws").string(),
                {victim.filename().string(), "cannot decode"}, dir_ / "ws");
}

TEST_F(Apps, DepthIntrinsicsSizeMismatch) {
  MakeSequence(dir_ / "seq");
  std::ofstream(dir_ / "seq/k.txt") << "30 30 159.5 119.5 320 240\n";
  ExpectFailure(AppPath("genscene") + " run --input " + (dir_ / "seq").string() + " --intrinsics " +
                    (dir_ / "seq/k.txt").string() + " --out " + (dir_ / "ws").string(),
                {"depth 32x24 but intrinsics say 320x240"}, dir_ / "ws");
}

TEST_F(Apps, NanInfNegativeDepth) {
  for (float bad : {std::nanf(""), INFINITY, -0.5f}) {
    MakeSequence(dir_ / "seq");
    ImageDepth depth(32, 24, 1.0f);
    depth(5, 6) = bad;
    WriteDepthExr(dir_ / "seq/depth/bad.exr", depth);
    std::ifstream in(dir_ / "seq/depth.txt");
    std::string header, first;
    std::getline(in, header);
    std::getline(in, first);
    std::ofstream(dir_ / "seq/depth.txt") << first.substr(0, first.find(' ')) << " depth/bad.exr\n";
    ExpectFailure(AppPath("genscene") + " run --input " + (dir_ / "seq").string() + " --out " +
                      (dir_ / "ws").string(),
                  {"bad.exr", "NaN, infinite or negative", "pixel (5, 6)"}, dir_ / "ws");
    fs::remove_all(dir_ / "seq");
  }
}

TEST_F(Apps, TruncatedPly) {
  const fs::path ws = dir_ / "ws";
  ASSERT_EQ(RunCommand(AppPath("genscene-synth") + " --frames 2 --size 16x12 --out " +
                       (ws / "input").string())
                .exit_code,
            0);
  std::ifstream in(ws / "input/mesh_gt.ply", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  std::ofstream(dir_ / "cut.ply", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  ExpectFailure(AppPath("genscene") + " inspect " + (dir_ / "cut.ply").string(), {"cut.ply"});
  const auto ok =
      RunCommand(AppPath("genscene") + " inspect " + (ws / "input/mesh_gt.ply").string());
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_NE(ok.output.find("triangles"), std::string::npos) << ok.output;
}

TEST_F(Apps, UnknownConfigKey) {
  std::ofstream(dir_ / "c.json") << R"({"synth": {"frames": 2, "frame_count": 3}})";
  ExpectFailure(AppPath("genscene-synth") + " --config " + (dir_ / "c.json").string() + " --out " +
                    (dir_ / "out").string(),
                {"c.json", "unknown key 'synth.frame_count'"});
  EXPECT_FALSE(fs::exists(dir_ / "out"));
}

TEST_F(Apps, ConfigValuesAndFlagPrecedence) {
  std::ofstream(dir_ / "c.json") << R"({"synth": {"frames": 2, "size": "16x12"}})";
  // The flag overrides the config's frames; the config's size stays.
  const auto r = RunCommand(AppPath("genscene-synth") + " --config " + (dir_ / "c.json").string() +
                            " --frames 4 --out " + (dir_ / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("wrote 4 frames of 16x12"), std::string::npos) << r.output;
}

TEST_F(Apps, OutOfRangeOptions) {
  ExpectFailure(AppPath("genscene-synth") + " --frames 0 --out " + (dir_ / "out").string(),
                {"frames = 0"});
  ExpectFailure(AppPath("genscene-synth") + " --size 4x4 --out " + (dir_ / "out").string(),
                {"size = '4x4'"});
  ExpectFailure(AppPath("genscene-synth") + " --noise loud --out " + (dir_ / "out").string(),
                {"noise = 'loud'"});
  ExpectFailure(AppPath("genscene-synth") + " --frames many --out " + (dir_ / "out").string(),
                {"--frames", "many"});
  EXPECT_FALSE(fs::exists(dir_ / "out"));
  MakeSequence(dir_ / "seq");
  ExpectFailure(AppPath("genscene") + " run --input " + (dir_ / "seq").string() +
                    " --stride 0 --out " + (dir_ / "ws").string(),
                {"stride = 0"}, dir_ / "ws");
  // The training views' renders need two halves to take their noise out.
  ExpectFailure(AppPath("genscene") + " run --input " + (dir_ / "seq").string() +
                    " --preview-lights-spp 1 --out " + (dir_ / "ws").string(),
                {"lights_spp = 1 is not in [2, 65536]"}, dir_ / "ws");
}

TEST_F(Apps, SameSeedSameOutputWhateverTheThreadCount) {
  const std::string base =
      AppPath("genscene-synth") + " --frames 2 --size 24x16 --noise kinect --seed 9 ";
  ASSERT_EQ(RunCommand(base + "--threads 1 --out " + (dir_ / "a").string()).exit_code, 0);
  ASSERT_EQ(RunCommand(base + "--threads 2 --out " + (dir_ / "b").string()).exit_code, 0);
  const auto cmp = RunCommand("diff -r " + (dir_ / "a").string() + " " + (dir_ / "b").string());
  EXPECT_EQ(cmp.exit_code, 0) << cmp.output;
}

TEST_F(Apps, RenderAViewSetFromASynthScene) {
  MakeSequence(dir_ / "seq");
  const fs::path out = dir_ / "render";
  const auto r =
      RunCommand(AppPath("genscene-render") + " --scene " + (dir_ / "seq/scene.json").string() +
                 " --views " + (dir_ / "seq").string() + " --spp 4 --aovs --export-xml " +
                 (dir_ / "export/scene.xml").string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The exported Mitsuba scene renders again, with the views it carries.
  const auto again =
      RunCommand(AppPath("genscene-render") + " --scene " + (dir_ / "export/scene.xml").string() +
                 " --spp 2 --out " + (dir_ / "render2").string());
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(test::CountFilesContaining(dir_ / "render2", ".exr"), 3);
  EXPECT_NE(r.output.find("3 views, 4 spp"), std::string::npos) << r.output;
  // The output is a view set: three EXR + PNG named by timestamp, in list order.
  EXPECT_TRUE(fs::exists(out / "rgb.txt"));
  EXPECT_TRUE(fs::exists(out / "groundtruth.txt"));
  EXPECT_TRUE(fs::exists(out / "intrinsics.txt"));
  EXPECT_EQ(test::CountFilesContaining(out, "_depth.exr"), 3);
  EXPECT_EQ(test::CountFilesContaining(out, "_normal.exr"), 3);
  EXPECT_EQ(test::CountFilesContaining(out, ".png"), 3);
  EXPECT_TRUE(fs::exists(out / "0000000000.000000.exr"));
  EXPECT_EQ(test::CountFilesContaining(out, ".tmp-"), 0);
}

TEST_F(Apps, RenderRejectsBadScenes) {
  std::ofstream(dir_ / "broken.xml") << "<scene version=\"3.0.0\"><shape type=\"ply\">";
  ExpectFailure(AppPath("genscene-render") + " --scene " + (dir_ / "broken.xml").string() +
                    " --out " + (dir_ / "out").string(),
                {"broken.xml"});
  std::ofstream(dir_ / "missing.xml")
      << "<scene version=\"3.0.0\"><shape type=\"ply\">"
         "<string name=\"filename\" value=\"nope.ply\"/></shape></scene>";
  ExpectFailure(AppPath("genscene-render") + " --scene " + (dir_ / "missing.xml").string() +
                    " --out " + (dir_ / "out").string(),
                {"nope.ply"});
  std::ofstream(dir_ / "negative.xml")
      << "<scene version=\"3.0.0\"><shape type=\"rectangle\"><emitter type=\"area\">"
         "<rgb name=\"radiance\" value=\"1, -1, 1\"/></emitter></shape></scene>";
  ExpectFailure(AppPath("genscene-render") + " --scene " + (dir_ / "negative.xml").string() +
                    " --out " + (dir_ / "out").string(),
                {"negative.xml"});
  ExpectFailure(AppPath("genscene-render") + " --scene " + (dir_ / "missing.xml").string() +
                    " --pose \"0 0 0 0 0 0 1\" --out " + (dir_ / "out").string(),
                {"nope.ply"});
  EXPECT_FALSE(fs::exists(dir_ / "out"));
}

}  // namespace
}  // namespace genscene
