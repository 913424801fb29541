// An options struct's values as a JSON object keyed as in its config section, for the reports
// stages write next to their outputs (fusion.json, texture.json, albedo.json). Header-only and
// apart from options.h, which keeps nlohmann/json out of widely included headers.
#pragma once

#include <nlohmann/json.hpp>

namespace genscene {

template <typename Options>
nlohmann::json OptionsToJson(Options options) {  // a copy: Visit is not const
  nlohmann::json j = nlohmann::json::object();
  options.Visit(
      [&](const char* key, const auto& value, const char*, const char*) { j[key] = value; });
  return j;
}

}  // namespace genscene
