#include "core/color.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/check.h"
#include "core/file_util.h"

namespace genscene {

float SrgbToLinear(float encoded) {
  if (encoded <= 0.04045f) return encoded / 12.92f;
  return std::pow((encoded + 0.055f) / 1.055f, 2.4f);
}

float LinearToSrgb(float linear) {
  if (linear <= 0.0031308f) return 12.92f * linear;
  return 1.055f * std::pow(linear, 1.0f / 2.4f) - 0.055f;
}

const float* SrgbTable() {
  static const std::vector<float> kTable = [] {
    std::vector<float> table(kSrgbTableSize);
    for (size_t i = 0; i < table.size(); ++i)
      table[i] = LinearToSrgb(static_cast<float>(i) / static_cast<float>(kSrgbTableSize - 1));
    return table;
  }();
  return kTable.data();
}

const uint8_t* Srgb8Table() {
  static const std::vector<uint8_t> kTable = [] {
    const float* srgb = SrgbTable();
    std::vector<uint8_t> table(kSrgbTableSize);
    for (size_t i = 0; i < table.size(); ++i)
      table[i] = static_cast<uint8_t>(std::lround(255.0f * srgb[i]));
    return table;
  }();
  return kTable.data();
}

float LinearToSrgbTabled(float linear) {
  return SrgbTable()[SrgbTableIndex(linear)];
}

CameraResponse CameraResponse::Parse(const std::string& text, const std::string& where) {
  CameraResponse r;
  if (text == "srgb") {
    r.kind = Kind::kSrgb;
  } else if (text == "linear") {
    r.kind = Kind::kLinear;
  } else if (text.rfind("gamma:", 0) == 0) {
    r.kind = Kind::kGamma;
    r.gamma = ParseDouble(text.substr(6), where);
    if (!(r.gamma > 0.1 && r.gamma < 10.0)) {
      throw Error(Format(where, ": gamma ", r.gamma, " is not in (0.1, 10)"));
    }
  } else {
    throw Error(Format(where, ": '", text, "' is not one of srgb, linear, gamma:G"));
  }
  return r;
}

std::string CameraResponse::ToString() const {
  switch (kind) {
    case Kind::kSrgb:
      return "srgb";
    case Kind::kLinear:
      return "linear";
    case Kind::kGamma:
      return Format("gamma:", gamma);
  }
  return "?";
}

float CameraResponse::ToLinear(float encoded) const {
  switch (kind) {
    case Kind::kSrgb:
      return SrgbToLinear(encoded);
    case Kind::kLinear:
      return encoded;
    case Kind::kGamma:
      return std::pow(std::max(encoded, 0.0f), static_cast<float>(gamma));
  }
  return encoded;
}

float CameraResponse::FromLinear(float linear) const {
  const float clamped = std::clamp(linear, 0.0f, 1.0f);
  switch (kind) {
    case Kind::kSrgb:
      return LinearToSrgb(clamped);
    case Kind::kLinear:
      return clamped;
    case Kind::kGamma:
      return std::pow(clamped, static_cast<float>(1.0 / gamma));
  }
  return clamped;
}

double Sharpness(const ImageRgb& color) {
  const int w = color.width(), h = color.height();
  if (w < 3 || h < 3) return 0.0;
  auto luma = [&](int u, int v) { return static_cast<double>(Luminance(color(u, v))); };
  double sum = 0.0, sum_sq = 0.0;
  size_t n = 0;
  for (int v = 1; v + 1 < h; ++v) {
    for (int u = 1; u + 1 < w; ++u) {
      const double lap =
          luma(u - 1, v) + luma(u + 1, v) + luma(u, v - 1) + luma(u, v + 1) - 4.0 * luma(u, v);
      sum += lap;
      sum_sq += lap * lap;
      ++n;
    }
  }
  const double mean = sum / static_cast<double>(n);
  return sum_sq / static_cast<double>(n) - mean * mean;
}

}  // namespace genscene
