// Shared helpers of the test suite: temporary folders, the shared data folder, running apps.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <optional>
#include <string>

#include "core/check.h"

namespace genscene::test {

// A fresh folder under the system temp dir, removed when the object dies.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// ../shared/data next to the source tree (or $GENSCENE_SHARED_DATA), if present.
std::optional<std::filesystem::path> FindSharedData();

// True under CI=true, where missing shared data is an error, not a skip.
bool InCi();

// Use at the top of a test: gives the shared data folder, or skips the test with a reason (fails
// under CI=true).
#define GS_REQUIRE_SHARED_DATA(var)                                                          \
  const auto var##_opt = ::genscene::test::FindSharedData();                                 \
  if (!var##_opt) {                                                                          \
    if (::genscene::test::InCi()) FAIL() << "../shared/data is missing, and CI=true requires it"; \
    GTEST_SKIP() << "../shared/data not found (set GENSCENE_SHARED_DATA); skipping";         \
  }                                                                                          \
  const std::filesystem::path var = *var##_opt

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// Runs a shell command with a timeout in seconds (a hang fails instead of blocking the suite).
CommandResult RunCommand(const std::string& command, int timeout_seconds = 120);

// The message of the genscene::Error that `f` throws, or "<no error>" when it throws none.
template <typename F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "<no error>";
}

#define EXPECT_CONTAINS(text, part) EXPECT_NE((text).find(part), std::string::npos) << (text)

// Path of a built program (genscene, genscene-synth, ...).
std::string AppPath(const std::string& name);

// Writes `text` to `path`, creating the parent folders.
void WriteFile(const std::filesystem::path& path, const std::string& text);

// Number of files (recursively) below `dir` whose name contains `part`.
int CountFilesContaining(const std::filesystem::path& dir, const std::string& part);

}  // namespace genscene::test
