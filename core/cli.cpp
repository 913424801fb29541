#include "core/cli.h"

#include <iostream>

#include "core/parallel.h"

namespace genscene {

const char* Version() {
  return GENSCENE_VERSION;
}

CommandLine::CommandLine(CLI::App& app) : app_(app) {
  app_.set_version_flag("--version", std::string("genscene ") + Version(),
                        "print the version of genscene and exit");
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

void CommandLine::AddFolder(std::string& folder, const std::string& name, const std::string& help,
                            bool required) {
  folders_.push_back(std::make_unique<Folder>(Folder{&folder, name, "", required, nullptr}));
  Folder& f = *folders_.back();
  const std::string given = required         ? " (required)"
                            : folder.empty() ? ""
                                             : " (default: " + folder + ")";
  f.positional = app_.add_option(name, folder, help + given + "; or give it as --out");
  app_.add_option("--out", f.flag_value, "the same as the positional " + name);
}

std::optional<int> CommandLine::Parse(int argc, char** argv) {
  try {
    ParseUnguarded(argc, argv);
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
        throw UsageError(Format("unknown flag ", arg, " (see --help)"));
      }
    }
    throw UsageError(Format(e.what(), " (see --help)"));
  } catch (const UsageError&) {
    throw;
  } catch (const Error& e) {
    throw UsageError(e.what());  // a config file or option value that cannot be applied
  }
  SetThreadCount(threads_);
  return std::nullopt;
}

void CommandLine::ParseUnguarded(int argc, char** argv) {
  app_.parse(argc, argv);
  for (const auto& f : folders_) {
    if (!f->flag_value.empty()) {
      if (f->positional->count() > 0 && *f->value != f->flag_value) {
        throw UsageError(Format("two folders given: ", f->name, " '", *f->value, "' and --out '",
                                f->flag_value, "' (give one)"));
      }
      *f->value = f->flag_value;
    }
    if (f->required && f->value->empty()) {
      throw UsageError(
          Format(f->name, " is required: give the folder as ", f->name, " or --out (see --help)"));
    }
  }
  std::optional<ConfigFile> config;
  if (!config_path_.empty()) config.emplace(config_path_);
  for (auto& apply : appliers_) apply(config ? &*config : nullptr);
  if (config) config->CheckNoUnknown();
}

int RunApp(const char* app_name, const std::function<int()>& body) {
  try {
    return body();
  } catch (const UsageError& e) {
    std::cerr << app_name << ": error: " << e.what() << std::endl;
    return 2;
  } catch (const Error& e) {
    std::cerr << app_name << ": error: " << e.what() << std::endl;
  } catch (const std::exception& e) {
    std::cerr << app_name << ": error: " << e.what() << std::endl;
  }
  return 1;
}

}  // namespace genscene
