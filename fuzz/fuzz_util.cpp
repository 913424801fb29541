#include "fuzz/fuzz_util.h"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <system_error>

namespace genscene::fuzz {

namespace fs = std::filesystem;

namespace {

struct ScratchFolder {
  fs::path path;
  ScratchFolder() {
    // Memory-backed /dev/shm when there is one: a file written per execution on a disk costs
    // I/O waits (on our CI machine, 60 exec/s on /tmp against thousands on /dev/shm).
    const char* tmp = std::getenv("GENSCENE_FUZZ_TMPDIR");
    fs::path base = tmp && *tmp ? fs::path(tmp) : fs::path("/dev/shm");
    std::error_code ec;
    if (!fs::is_directory(base, ec) || ::access(base.c_str(), W_OK) != 0) base = "/tmp";
    path = base / ("genscene-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(path);
  }
  ~ScratchFolder() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

}  // namespace

const fs::path& ScratchDir() {
  static ScratchFolder folder;
  return folder.path;
}

fs::path Scratch(const std::string& name, const uint8_t* data, size_t size) {
  const fs::path path = ScratchDir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) std::abort();  // the harness itself cannot work
  return path;
}

void MaybeWriteSeeds(const std::function<void(const fs::path&)>& write) {
  const char* dir = std::getenv("GENSCENE_FUZZ_SEEDS");
  if (!dir || !*dir) return;
  fs::create_directories(dir);
  write(dir);
  std::exit(0);
}

}  // namespace genscene::fuzz
