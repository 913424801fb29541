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
  if (ec)
    throw Error(Format(root_.string(), ": cannot create workspace folder (", ec.message(), ")"));
}

}  // namespace genscene
