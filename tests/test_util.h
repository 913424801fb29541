// Shared helpers of the test suite: temporary folders, the shared data folder, running apps.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

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
#define GS_REQUIRE_SHARED_DATA(var)                                                               \
  const auto var##_opt = ::genscene::test::FindSharedData();                                      \
  if (!var##_opt) {                                                                               \
    if (::genscene::test::InCi()) FAIL() << "../shared/data is missing, and CI=true requires it"; \
    GTEST_SKIP() << "../shared/data not found (set GENSCENE_SHARED_DATA); skipping";              \
  }                                                                                               \
  const std::filesystem::path var = *var##_opt

// Barycentric inputs (b1, b2) as the tracers and the refinement produce them: `uniform` points
// in the triangle; per_edge points on each of the three edges (the long edge computed as 1 - b in
// float and in double, so that sums round either way), just past the long edge and a few ulps
// outside the short ones; the vertices, far outside, NaN and infinite.
std::vector<std::pair<float, float>> HardBarycentrics(std::mt19937& rng, int uniform, int per_edge);

// Collects what spdlog logs (every level, formatted "[level] message") while it lives.
class LogCapture {
 public:
  LogCapture();
  ~LogCapture();
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;
  std::string text() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

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
