// The options pattern of DESIGN.md §3: one struct per stage, every field with a default, a unit
// and a meaning, a Validate() that rejects bad values with the value in the message, and a
// Visit() that lists the fields once. From that one list:
//   - config files (JSON, one object per section, unknown sections and keys rejected), here;
//   - command-line flags (CLI11, "--" + key with '_' -> '-'), in core/cli.h (apps only).
//
//   struct FooOptions {
//     double voxel_size = 0.01;  // edge of a voxel, meters
//     static constexpr const char* kSection = "foo";
//     template <typename V> void Visit(V&& v) { v("voxel_size", voxel_size, "m", "edge of a
//     voxel"); } void Validate() const { RequireRange("voxel_size", voxel_size, 1e-4, 1.0); }
//   };
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <set>
#include <string>
#include <vector>

#include "core/check.h"

namespace genscene {

// Throws Error("option <key> = <value> is not in [lo, hi]") unless lo <= value <= hi.
template <typename T>
void RequireRange(const char* key, const T& value, const T& lo, const T& hi) {
  if (!(value >= lo && value <= hi)) {
    throw Error(Format("option ", key, " = ", value, " is not in [", lo, ", ", hi, "]"));
  }
}

// Throws unless value is one of `allowed`.
void RequireOneOf(const char* key, const std::string& value,
                  const std::vector<std::string>& allowed);

// "voxel_size" -> "--voxel-size".
std::string FlagName(const std::string& key);

// A parsed JSON config file: {"section": {"key": value, ...}, ...}. Apply() copies the keys of one
// section into an options struct, with type checks; CheckNoUnknown() rejects sections and keys
// that nothing applied, naming the file and the key.
class ConfigFile {
 public:
  // Throws Error naming the file when it is missing or not a JSON object of objects.
  explicit ConfigFile(const std::filesystem::path& path);
  ~ConfigFile();
  ConfigFile(ConfigFile&&) noexcept;

  template <typename Options>
  void Apply(Options& options) {
    const std::string section = Options::kSection;
    options.Visit([&](const char* key, auto& value, const char* /*unit*/, const char* /*help*/) {
      SetValue(section, key, &value);
    });
    applied_sections_.insert(section);
  }

  // Sections of other stages that a shared config may carry are passed as `also_known`; they are
  // not rejected, only ignored. Every key of an applied section must have been used.
  void CheckNoUnknown(const std::vector<std::string>& also_known = {}) const;

  const std::filesystem::path& path() const { return path_; }

 private:
  void SetValue(const std::string& section, const std::string& key, double* value);
  void SetValue(const std::string& section, const std::string& key, int* value);
  void SetValue(const std::string& section, const std::string& key, bool* value);
  void SetValue(const std::string& section, const std::string& key, std::string* value);
  void SetValue(const std::string& section, const std::string& key, long long* value);
  const nlohmann::json* Find(const std::string& section, const std::string& key);

  std::filesystem::path path_;
  std::unique_ptr<nlohmann::json> json_;
  std::set<std::string> applied_sections_;
  std::map<std::string, std::set<std::string>> used_keys_;
};

// Every section name used by some stage; a shared config may hold all of them.
const std::vector<std::string>& AllConfigSections();

}  // namespace genscene
