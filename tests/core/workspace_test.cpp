#include "core/workspace.h"

#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "core/check.h"
#include "core/file_util.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

namespace fs = std::filesystem;

void Touch(const fs::path& path, int seconds_ago) {
  std::ofstream(path) << "x";
  fs::last_write_time(path, fs::file_time_type::clock::now() - std::chrono::seconds(seconds_ago));
}

TEST(Workspace, FreshnessFollowsModificationTimes) {
  test::TempDir dir;
  Touch(dir / "input.txt", 100);
  Touch(dir / "output.txt", 50);
  EXPECT_TRUE(Workspace::IsFresh({dir / "output.txt"}, {dir / "input.txt"}));
  Touch(dir / "input.txt", 10);  // input changed after the output was made
  EXPECT_FALSE(Workspace::IsFresh({dir / "output.txt"}, {dir / "input.txt"}));
  EXPECT_FALSE(Workspace::IsFresh({dir / "missing.txt"}, {dir / "input.txt"}));
  EXPECT_FALSE(Workspace::IsFresh({dir / "output.txt"}, {dir / "missing.txt"}));
  // Folders count by their newest file.
  fs::create_directories(dir / "in");
  Touch(dir / "in/a", 200);
  Touch(dir / "in/b", 20);
  Touch(dir / "out.txt", 30);
  EXPECT_FALSE(Workspace::IsFresh({dir / "out.txt"}, {dir / "in"}));
}

TEST(Workspace, AtomicWriteLeavesNothingWhenTheWriterFails) {
  test::TempDir dir;
  EXPECT_THROW(WriteFileAtomically(dir / "out.ply",
                                   [](const fs::path& tmp) {
                                     std::ofstream(tmp) << "half a file";
                                     throw Error("writer failed halfway");
                                   }),
               Error);
  EXPECT_FALSE(fs::exists(dir / "out.ply"));
  EXPECT_EQ(test::CountFilesContaining(dir.path(), "out"), 0);
  // An existing complete output survives a failed rewrite untouched.
  WriteTextFileAtomically(dir / "out.txt", "complete");
  EXPECT_THROW(WriteFileAtomically(dir / "out.txt",
                                   [](const fs::path& tmp) {
                                     std::ofstream(tmp) << "partial";
                                     throw Error("killed");
                                   }),
               Error);
  EXPECT_EQ(ReadTextFile(dir / "out.txt"), "complete");
}

TEST(Workspace, TemporaryNameKeepsExtension) {
  EXPECT_EQ(TemporaryPathFor("a/mesh.ply").extension(), ".ply");
  EXPECT_NE(TemporaryPathFor("a/mesh.ply").filename().string().find(".tmp-"), std::string::npos);
}

TEST(Workspace, RootMustBeAFolder) {
  test::TempDir dir;
  std::ofstream(dir / "file") << "x";
  EXPECT_THROW(Workspace(dir / "file"), Error);
  const Workspace ws(dir / "ws");
  EXPECT_TRUE(fs::is_directory(ws.root()));
  EXPECT_EQ(ws.Mesh().filename(), "mesh.ply");
}

}  // namespace
}  // namespace genscene
