#include "core/json_util.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <vector>

#include "core/check.h"
#include "core/file_util.h"

namespace genscene::json_util {

void CheckKeys(const json& j, std::initializer_list<const char*> allowed,
               const std::string& where) {
  if (!j.is_object()) throw Error(Format(where, ": must be a JSON object"));
  for (const auto& item : j.items()) {
    const std::string& key = item.key();
    if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; })) {
      throw Error(Format(where, ": unknown key '", key, "'"));
    }
  }
}

double JsonNumber(const json& j, const std::string& where) {
  if (!j.is_number() || !std::isfinite(j.get<double>())) {
    throw Error(Format(where, ": expected a finite number, got ", j.dump()));
  }
  return j.get<double>();
}

int JsonInt(const json& j, const std::string& where) {
  if (!j.is_number_integer()) throw Error(Format(where, ": expected an integer, got ", j.dump()));
  const bool fits = j.is_number_unsigned()
                        ? j.get<unsigned long long>() <=
                              static_cast<unsigned long long>(std::numeric_limits<int>::max())
                        : j.get<long long>() >= std::numeric_limits<int>::min() &&
                              j.get<long long>() <= std::numeric_limits<int>::max();
  if (!fits) throw Error(Format(where, ": ", j.dump(), " is out of range (not a 32-bit integer)"));
  return static_cast<int>(j.get<long long>());
}

void ThrowWrongSize(const json& j, int expected, const std::string& where) {
  throw Error(Format(where, ": expected ", expected, " numbers, got ", j.dump()));
}

json JsonArray(const json& j, const std::string& where) {
  if (!j.is_array()) throw Error(Format(where, ": expected a list"));
  return j;
}

json ToJson(const Eigen::Ref<const Eigen::VectorXd>& v) {
  return std::vector<double>(v.data(), v.data() + v.size());
}

json FloatsToJson(const Eigen::Vector3f& v) {
  std::vector<double> out;
  for (float x : {v.x(), v.y(), v.z()}) {
    char text[32];
    *std::to_chars(text, text + sizeof(text) - 1, x).ptr = '\0';
    out.push_back(std::strtod(text, nullptr));
  }
  return out;
}

json ParseJsonFile(const std::filesystem::path& path) {
  try {
    return json::parse(ReadTextFile(path));
  } catch (const json::exception& e) {  // syntax errors, and numbers out of range (1e400: 406)
    throw Error(Format(path.string(), ": malformed JSON (", e.what(), ")"));
  }
}

}  // namespace genscene::json_util
