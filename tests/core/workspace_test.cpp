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

// What the chain's resume compares: the same content gives the same fingerprint whatever its time
// stamps or where the folder lies; a changed byte, a renamed or an added file changes it.
TEST(Workspace, ContentFingerprintFollowsContentNotTimes) {
  test::TempDir dir;
  fs::create_directories(dir / "a" / "sub");
  Touch(dir / "a" / "x.txt", 100);
  Touch(dir / "a" / "sub" / "y.txt", 50);
  const uint64_t a = ContentFingerprint(dir / "a");
  fs::copy(dir / "a", dir / "b", fs::copy_options::recursive);
  Touch(dir / "b" / "x.txt", 5);  // same bytes, newer
  EXPECT_EQ(ContentFingerprint(dir / "b"), a);
  std::ofstream(dir / "b" / "x.txt") << "y";
  EXPECT_NE(ContentFingerprint(dir / "b"), a);
  fs::remove_all(dir / "b");
  fs::copy(dir / "a", dir / "b", fs::copy_options::recursive);
  fs::rename(dir / "b" / "x.txt", dir / "b" / "z.txt");
  EXPECT_NE(ContentFingerprint(dir / "b"), a);
  Touch(dir / "a" / "w.txt", 1);
  EXPECT_NE(ContentFingerprint(dir / "a"), a);
  EXPECT_EQ(ContentFingerprint(dir / "a" / "sub" / "y.txt"), Fnv1a64("x"));
  EXPECT_CONTAINS(test::ErrorOf([&] { ContentFingerprint(dir / "missing"); }),
                  "missing: cannot read");
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
