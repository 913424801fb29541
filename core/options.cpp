#include "core/options.h"

#include <climits>
#include <nlohmann/json.hpp>

#include "core/file_util.h"

namespace genscene {

void RequireOneOf(const char* key, const std::string& value,
                  const std::vector<std::string>& allowed) {
  for (const auto& a : allowed) {
    if (a == value) return;
  }
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  throw Error(Format("option ", key, " = '", value, "' is not one of: ", list));
}

std::string FlagName(const std::string& key) {
  std::string flag = "--" + key;
  for (char& c : flag) {
    if (c == '_') c = '-';
  }
  return flag;
}

const std::vector<std::string>& AllConfigSections() {
  static const std::vector<std::string> sections = {
      "source", "synth",  "fusion", "meshing", "texturing", "albedo", "lights",
      "refine", "render", "viewer", "run",     "evaluate",  "preview"};
  return sections;
}

ConfigFile::ConfigFile(const std::filesystem::path& path)
    : path_(path), json_(std::make_unique<nlohmann::json>()) {
  const std::string text = ReadTextFile(path);
  try {
    *json_ = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // syntax errors, numbers out of range (1e400)
    throw Error(Format(path.string(), ": not valid JSON (", e.what(), ")"));
  }
  if (!json_->is_object()) throw Error(Format(path.string(), ": config must be a JSON object"));
  for (const auto& [section, body] : json_->items()) {
    if (!body.is_object()) {
      throw Error(Format(path.string(), ": section '", section, "' must be an object"));
    }
  }
}

ConfigFile::~ConfigFile() = default;
ConfigFile::ConfigFile(ConfigFile&&) noexcept = default;

const nlohmann::json* ConfigFile::Find(const std::string& section, const std::string& key) {
  auto s = json_->find(section);
  if (s == json_->end()) return nullptr;
  auto k = s->find(key);
  if (k == s->end()) return nullptr;
  used_keys_[section].insert(key);
  return &*k;
}

namespace {

[[noreturn]] void TypeError(const std::filesystem::path& path, const std::string& section,
                            const std::string& key, const char* expected,
                            const nlohmann::json& got) {
  throw Error(Format(path.string(), ": key '", section, ".", key, "' must be ", expected, ", got ",
                     got.dump()));
}

}  // namespace

void ConfigFile::SetValue(const std::string& section, const std::string& key, double* value) {
  if (const auto* j = Find(section, key)) {
    if (!j->is_number()) TypeError(path_, section, key, "a number", *j);
    *value = j->get<double>();
  }
}

void ConfigFile::SetValue(const std::string& section, const std::string& key, int* value) {
  if (const auto* j = Find(section, key)) {
    if (!j->is_number_integer()) TypeError(path_, section, key, "an integer", *j);
    // An unsigned value beyond 2^63 would wrap to a negative long long: refuse it first.
    if (j->is_number_unsigned() && j->get<unsigned long long>() > INT32_MAX) {
      TypeError(path_, section, key, "a 32-bit integer", *j);
    }
    const long long v = j->get<long long>();
    if (v < INT32_MIN || v > INT32_MAX) TypeError(path_, section, key, "a 32-bit integer", *j);
    *value = static_cast<int>(v);
  }
}

void ConfigFile::SetValue(const std::string& section, const std::string& key, long long* value) {
  if (const auto* j = Find(section, key)) {
    if (!j->is_number_integer()) TypeError(path_, section, key, "an integer", *j);
    if (j->is_number_unsigned() &&
        j->get<unsigned long long>() > static_cast<unsigned long long>(LLONG_MAX)) {
      TypeError(path_, section, key, "a 64-bit signed integer", *j);
    }
    *value = j->get<long long>();
  }
}

void ConfigFile::SetValue(const std::string& section, const std::string& key, bool* value) {
  if (const auto* j = Find(section, key)) {
    if (!j->is_boolean()) TypeError(path_, section, key, "true or false", *j);
    *value = j->get<bool>();
  }
}

void ConfigFile::SetValue(const std::string& section, const std::string& key, std::string* value) {
  if (const auto* j = Find(section, key)) {
    if (!j->is_string()) TypeError(path_, section, key, "a string", *j);
    *value = j->get<std::string>();
  }
}

void ConfigFile::CheckNoUnknown(const std::vector<std::string>& also_known) const {
  for (const auto& [section, body] : json_->items()) {
    const bool applied = applied_sections_.count(section) > 0;
    bool known = applied;
    for (const auto& s : also_known) known |= s == section;
    for (const auto& s : AllConfigSections()) known |= s == section;
    if (!known) {
      std::string list;
      for (const auto& s : AllConfigSections()) list += (list.empty() ? "" : ", ") + s;
      throw Error(Format(path_.string(), ": unknown section '", section, "' (known: ", list, ")"));
    }
    if (!applied) continue;
    const auto used = used_keys_.find(section);
    for (const auto& [key, value] : body.items()) {
      if (used == used_keys_.end() || used->second.count(key) == 0) {
        throw Error(Format(path_.string(), ": unknown key '", section, ".", key, "'"));
      }
    }
  }
}

}  // namespace genscene
