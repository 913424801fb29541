#include "tests/test_util.h"

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

namespace genscene::test {

namespace fs = std::filesystem;

TempDir::TempDir() {
  static std::atomic<int> counter{0};
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "test";
  for (char& c : name) {
    if (c == '/') c = '_';
  }
  path_ = fs::temp_directory_path() /
          ("genscene-" + name + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
  fs::remove_all(path_);
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

std::vector<std::pair<float, float>> HardBarycentrics(std::mt19937& rng, int uniform,
                                                      int per_edge) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<std::pair<float, float>> out;
  for (int k = 0; k < uniform; ++k) {
    float a = u(rng), b = u(rng);
    if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
    out.emplace_back(a, b);
  }
  for (int k = 0; k < per_edge; ++k) {
    const double t = u(rng);
    const float tf = static_cast<float>(t);
    out.emplace_back(tf, 1.0f - tf);                    // long edge, float
    out.emplace_back(tf, static_cast<float>(1.0 - t));  // long edge, double
    out.emplace_back(std::nextafter(tf, 2.0f), std::nextafter(1.0f - tf, 2.0f));  // just past it
    out.emplace_back(tf, 0.0f);
    out.emplace_back(0.0f, tf);
    out.emplace_back(tf, -1e-7f);
    out.emplace_back(-1e-7f, tf);
  }
  const float inf = std::numeric_limits<float>::infinity(),
              nan = std::numeric_limits<float>::quiet_NaN();
  for (auto p : std::vector<std::pair<float, float>>{{0, 0},
                                                     {1, 0},
                                                     {0, 1},
                                                     {1, 1},
                                                     {-1, -1},
                                                     {2, 0.5f},
                                                     {0.5f, 2},
                                                     {1e30f, 1e30f},
                                                     {inf, 0},
                                                     {0, inf},
                                                     {inf, inf},
                                                     {-inf, 0.5f},
                                                     {nan, 0.5f},
                                                     {0.5f, nan},
                                                     {nan, nan},
                                                     {0.205793679f, 0.794206858f}}) {
    out.push_back(p);
  }
  return out;
}

struct LogCapture::Impl {
  std::ostringstream stream;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink;
};

LogCapture::LogCapture() : impl_(std::make_unique<Impl>()) {
  impl_->sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(impl_->stream);
  impl_->sink->set_pattern("[%l] %v");
  impl_->sink->set_level(spdlog::level::trace);
  spdlog::default_logger()->sinks().push_back(impl_->sink);
}

LogCapture::~LogCapture() {
  auto& sinks = spdlog::default_logger()->sinks();
  sinks.erase(std::remove(sinks.begin(), sinks.end(), impl_->sink), sinks.end());
}

std::string LogCapture::text() const {
  impl_->sink->flush();
  return impl_->stream.str();
}

bool InCi() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

std::optional<fs::path> FindSharedData() {
  if (const char* env = std::getenv("GENSCENE_SHARED_DATA")) {
    if (fs::is_directory(env)) return fs::path(env);
    return std::nullopt;
  }
  const fs::path candidate = fs::path(GENSCENE_SOURCE_DIR) / ".." / "shared" / "data";
  if (fs::is_directory(candidate)) return candidate.lexically_normal();
  return std::nullopt;
}

CommandResult RunCommand(const std::string& command, int timeout_seconds) {
  CommandResult result;
  const std::string wrapped =
      "timeout --kill-after=5 " + std::to_string(timeout_seconds) + " sh -c '" + command + "' 2>&1";
  FILE* pipe = ::popen(wrapped.c_str(), "r");
  if (!pipe) return result;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
    result.output.append(buffer.data(), n);
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

std::string AppPath(const std::string& name) {
  return (fs::path(GENSCENE_BINARY_DIR) / "apps" / name).string();
}

void WriteFile(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

int CountFilesContaining(const fs::path& dir, const std::string& part) {
  int count = 0;
  std::error_code ec;
  for (const auto& entry : fs::recursive_directory_iterator(dir, ec)) {
    if (entry.path().filename().string().find(part) != std::string::npos) ++count;
  }
  return count;
}

}  // namespace genscene::test
