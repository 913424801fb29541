// Camera response: the conversion of stored pixel values to linear radiance, applied once at
// input (DESIGN.md §1). 8-bit images are sRGB-encoded unless told otherwise; float EXR is linear.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>

#include "core/image.h"

namespace genscene {

// sRGB electro-optical transfer (IEC 61966-2-1), value in [0, 1].
float SrgbToLinear(float encoded);
float LinearToSrgb(float linear);
// LinearToSrgb through a table of 16384 steps, for per-pixel loops (at most 4e-4 off, near
// black): the value clamped to [0, 1], NaN and infinities to 0.
float LinearToSrgbTabled(float linear);
// The same table (and the 8-bit codes lround(255 x its values)) for loops that inline the look-up:
// kSrgbTableSize entries, the value x at SrgbTableIndex(x).
inline constexpr size_t kSrgbTableSize = 16384;
const float* SrgbTable();
const uint8_t* Srgb8Table();
inline size_t SrgbTableIndex(float linear) {
  // NaN fails both comparisons; infinities go to 0 as NaN does.
  const float clamped = linear > 0.0f && linear <= std::numeric_limits<float>::max()
                            ? (linear < 1.0f ? linear : 1.0f)
                            : 0.0f;
  return static_cast<size_t>(clamped * static_cast<float>(kSrgbTableSize - 1) + 0.5f);
}

struct CameraResponse {
  enum class Kind { kSrgb, kLinear, kGamma };
  Kind kind = Kind::kSrgb;
  double gamma = 2.2;  // used when kind == kGamma: linear = encoded^gamma

  // Parses "srgb", "linear" or "gamma:G" (e.g. "gamma:2.2"); throws Error naming `where`.
  static CameraResponse Parse(const std::string& text,
                              const std::string& where = "camera response");
  std::string ToString() const;

  // Encoded value in [0, 1] -> linear.
  float ToLinear(float encoded) const;
  // Linear -> encoded value in [0, 1] (clamped).
  float FromLinear(float linear) const;
};

// Luminance of linear RGB (Rec. 709 / sRGB primaries), in the vector's scalar type.
template <typename Derived>
typename Derived::Scalar Luminance(const Eigen::MatrixBase<Derived>& rgb) {
  using S = typename Derived::Scalar;
  return S(0.2126) * rgb.x() + S(0.7152) * rgb.y() + S(0.0722) * rgb.z();
}

// Sharpness of a linear colour image: variance of the 4-neighbour Laplacian of its luminance
// (keyframe selection, texturing weights). 0 for images smaller than 3x3.
double Sharpness(const ImageRgb& color);

}  // namespace genscene
