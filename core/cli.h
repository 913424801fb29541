// Command-line side of the options pattern (core/options.h), for apps only: it pulls in CLI11.
//
//   CLI::App app{"what the app does"};
//   genscene::CommandLine cli(app);
//   SourceOptions source;  cli.Add(source, "Input");
//   GENSCENE_PARSE(cli, argc, argv);   // --help, --config, flags, Validate()
//
// Precedence: defaults < --config FILE < flags given on the command line.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "core/options.h"

namespace genscene {

class CommandLine {
 public:
  // Adds --version, --config, --threads and --seed to `app`.
  explicit CommandLine(CLI::App& app);

  // The folder an app writes (or reads and writes), given as the positional `name` or as --out
  // (one option each in --help); an error when both are given and differ, and when `required` and
  // neither is given (else `folder` keeps its value).
  void AddFolder(std::string& folder, const std::string& name, const std::string& help,
                 bool required = true);

  // Registers one flag per field of `options` (help text "<help> [unit]", default shown). With a
  // `prefix`, flags are --<prefix>-<key> (for apps that take two stages with the same keys); the
  // config file's keys stay as they are, in the stage's section.
  template <typename Options>
  void Add(Options& options, const std::string& group, const std::string& prefix = "") {
    const auto flag = [prefix](const char* key) {
      return FlagName(prefix.empty() ? key : prefix + "_" + key);
    };
    options.Visit([&](const char* key, auto& value, const char* unit, const char* help) {
      using T = std::decay_t<decltype(value)>;
      std::string text = help;
      if (unit && *unit) text += Format(" [", unit, "]");
      CLI::Option* opt = nullptr;
      if constexpr (std::is_same_v<T, bool>) {
        // Unbound options (no variable): values are copied in after the config is applied. A
        // flag that defaults to true is turned off by --no-<flag> (or --<flag>=false).
        const std::string names = value ? flag(key) + ",!--no-" + flag(key).substr(2) : flag(key);
        opt = app_.add_flag(names)->description(text);
        opt->default_str(value ? "true" : "false");
      } else {
        opt = app_.add_option(flag(key))->description(text);
        std::ostringstream def;
        def << value;
        opt->default_str(def.str());
        if constexpr (std::is_arithmetic_v<T>)
          opt->type_name("NUMBER");
        else
          opt->type_name("TEXT");
      }
      opt->group(group);
    });
    appliers_.push_back([this, &options, flag](ConfigFile* config) {
      if (config) config->Apply(options);
      options.Visit([&](const char* key, auto& value, const char*, const char*) {
        CLI::Option* opt = app_.get_option_no_throw(flag(key));
        if (!opt || opt->count() == 0) return;
        try {
          opt->results(value);
        } catch (const CLI::Error&) {
          throw Error(Format(flag(key), ": '", opt->as<std::string>(), "' is not a valid value"));
        }
      });
      options.Validate();
    });
  }

  // Parses argv. Returns 0 when the app should stop now (after --help or --version),
  // std::nullopt when it should go on. Applies the config file and the flags to every registered
  // struct and validates them; throws UsageError on a usage error or a bad value.
  std::optional<int> Parse(int argc, char** argv);

  // True when the flag of `key` (e.g. "max_depth") was given on the command line.
  bool Given(const std::string& key) const {
    const CLI::Option* opt = app_.get_option_no_throw(FlagName(key));
    return opt && opt->count() > 0;
  }

  int threads() const { return threads_; }
  unsigned long long seed() const { return seed_; }
  const std::string& config_path() const { return config_path_; }

 private:
  CLI::App& app_;
  std::string config_path_;
  int threads_ = 0;
  unsigned long long seed_ = 0;
  std::vector<std::function<void(ConfigFile*)>> appliers_;
  struct Folder {
    std::string* value;
    std::string name;
    std::string flag_value;
    bool required;
    CLI::Option* positional;
  };
  std::vector<std::unique_ptr<Folder>> folders_;
  void ParseUnguarded(int argc, char** argv);
};

// The version of genscene the apps print with --version.
const char* Version();

// Runs an app's body, turning genscene::Error (and any std::exception) into one line on stderr
// ("<app>: error: <message>") and exit code 1; a UsageError exits 2.
int RunApp(const char* app_name, const std::function<int()>& body);

}  // namespace genscene
