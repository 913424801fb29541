// Checked JSON reading for the project's JSON files (scene.json, lights.json, ...): every value is
// checked and every unknown key is an Error naming where it is. Include only from .cpp files.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <string>

namespace genscene::json_util {

using json = nlohmann::ordered_json;  // keeps the documented key order when writing

// Error when `j` is not an object or has a key outside `allowed`.
void CheckKeys(const json& j, std::initializer_list<const char*> allowed, const std::string& where);
double JsonNumber(const json& j, const std::string& where);
// An integer that fits in int: a float (640.5, 4.8e101) or a value beyond 32 bits is an Error
// naming `where` (nlohmann's get<int> converts those with undefined behaviour).
int JsonInt(const json& j, const std::string& where);
json JsonArray(const json& j, const std::string& where);  // a copy: callers pass temporaries
json ToJson(const Eigen::Ref<const Eigen::VectorXd>& v);
// Floats as the double of their shortest decimal text: "0.725", not "0.7250000238418579".
json FloatsToJson(const Eigen::Vector3f& v);
json ParseJsonFile(const std::filesystem::path& path);

[[noreturn]] void ThrowWrongSize(const json& j, int expected, const std::string& where);

template <int N>
Eigen::Matrix<double, N, 1> JsonVector(const json& j, const std::string& where) {
  if (!j.is_array() || j.size() != N) {
    ThrowWrongSize(j, N, where);
  }
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = JsonNumber(j[static_cast<size_t>(i)], where);
  return v;
}

}  // namespace genscene::json_util
