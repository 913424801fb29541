#include "core/cli.h"

#include <iostream>

#include "core/parallel.h"

namespace genscene {

CommandLine::CommandLine(CLI::App& app) : app_(app) {
  app_.add_option("--config", config_path_,
                  "JSON config file: {\"section\": {\"key\": value}}, keys as the flags below with "
                  "'_' for '-'; unknown keys are errors; flags given here override it")
      ->group("General");
  app_.add_option("--threads", threads_, "worker threads (0 = all cores)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1024))
      ->group("General");
  app_.add_option("--seed", seed_, "random seed; same seed, same output, whatever --threads")
      ->capture_default_str()
      ->group("General");
}

std::optional<int> CommandLine::Parse(int argc, char** argv) {
  try {
    app_.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app_.exit(e);  // prints the help, returns 0
  } catch (const CLI::CallForAllHelp& e) {
    return app_.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app_.exit(e);
  } catch (const CLI::ParseError& e) {
    // A usage error is one "<app>: error: ..." line like every other error. A misspelt flag
    // often surfaces as a value count error of another option: name the flag instead.
    for (const std::string& arg : app_.remaining()) {
      if (arg.size() > 1 && arg[0] == '-' && !(arg[1] >= '0' && arg[1] <= '9') && arg[1] != '.') {
        throw Error(Format("unknown flag ", arg, " (see --help)"));
      }
    }
    throw Error(Format(e.what(), " (see --help)"));
  }
  std::optional<ConfigFile> config;
  if (!config_path_.empty()) config.emplace(config_path_);
  for (auto& apply : appliers_) apply(config ? &*config : nullptr);
  if (config) config->CheckNoUnknown();
  SetThreadCount(threads_);
  return std::nullopt;
}

int RunApp(const char* app_name, const std::function<int()>& body) {
  try {
    return body();
  } catch (const Error& e) {
    std::cerr << app_name << ": error: " << e.what() << std::endl;
  } catch (const std::exception& e) {
    std::cerr << app_name << ": error: " << e.what() << std::endl;
  }
  return 1;
}

}  // namespace genscene
