#include "core/workspace.h"

#include "core/check.h"

namespace genscene {

namespace fs = std::filesystem;

Workspace::Workspace(fs::path root) : root_(std::move(root)) {
  std::error_code ec;
  if (fs::exists(root_, ec) && !fs::is_directory(root_, ec)) {
    throw Error(Format(root_.string(), ": workspace exists and is not a folder"));
  }
  fs::create_directories(root_, ec);
  if (ec) throw Error(Format(root_.string(), ": cannot create workspace folder (", ec.message(), ")"));
}

namespace {

template <typename Better>
std::optional<fs::file_time_type> ExtremeTime(const fs::path& path, Better better) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  if (!fs::is_directory(path, ec)) return fs::last_write_time(path, ec);
  std::optional<fs::file_time_type> result;
  for (const auto& entry : fs::recursive_directory_iterator(path, ec)) {
    if (!entry.is_regular_file()) continue;
    const auto t = entry.last_write_time();
    if (!result || better(t, *result)) result = t;
  }
  return result;
}

}  // namespace

std::optional<fs::file_time_type> NewestTime(const fs::path& path) {
  return ExtremeTime(path, [](auto a, auto b) { return a > b; });
}

std::optional<fs::file_time_type> OldestTime(const fs::path& path) {
  return ExtremeTime(path, [](auto a, auto b) { return a < b; });
}

bool Workspace::IsFresh(const std::vector<fs::path>& outputs, const std::vector<fs::path>& inputs) {
  if (outputs.empty()) return false;
  std::optional<fs::file_time_type> oldest_output;
  for (const auto& out : outputs) {
    const auto t = OldestTime(out);
    if (!t) return false;
    if (!oldest_output || *t < *oldest_output) oldest_output = t;
  }
  for (const auto& in : inputs) {
    const auto t = NewestTime(in);
    if (!t || *t > *oldest_output) return false;
  }
  return true;
}

}  // namespace genscene
