// Image file I/O through OpenCV (kept out of this header). Every reader names the file in its
// errors; every writer writes atomically (file_util.h).
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/color.h"
#include "core/image.h"

namespace genscene {

// Colour image as linear RGB: EXR/HDR (float) is taken as linear; 8- and 16-bit integer images
// (PNG, JPEG, PPM, ...) are scaled to [0, 1] and decoded with `response`. Grey images are
// replicated to three channels; alpha is dropped.
ImageRgb ReadColorImage(const std::filesystem::path& path, const CameraResponse& response);

// Linear RGB as 32-bit float OpenEXR (channels R, G, B).
void WriteExr(const std::filesystem::path& path, const ImageRgb& image);
// Linear RGB as an 8-bit PNG, encoded with `response` (sRGB by default), values clamped to [0, 1].
void WritePng(const std::filesystem::path& path, const ImageRgb& image,
              const CameraResponse& response = CameraResponse());

// 8-bit RGB bytes (width * height * 3, row-major from the top row, already encoded, e.g. sRGB)
// as the bytes of a PNG file, for formats that embed images (glTF). Throws Error on failure.
std::vector<uint8_t> EncodePng(int width, int height, const std::vector<uint8_t>& rgb8);

// How integer depth values map to meters.
struct DepthEncoding {
  enum class Kind {
    kScaled,        // unsigned 16-bit (PNG, PGM): meters = value / scale; 0 = invalid
    kNyuDisparity,  // NYU Depth v2 raw Kinect disparity (PGM, bytes swapped): m = 351.3 / (1092.5 -
                    // d)
    kSunRotated,    // SUN RGB-D: d = (d >> 3) | (d << 13) (16-bit rotate), then millimetres
  };
  Kind kind = Kind::kScaled;
  double scale = 5000.0;  // integer units per meter, kScaled only (TUM: 5000, millimetres: 1000)
  int invalid_value =
      -1;  // kScaled: a raw value that also means "no measurement" (7-Scenes: 65535); -1 = none
};

// Depth image in meters. Float images (EXR) are meters already; integer images are decoded with
// `encoding`. Rejects multi-channel images, and NaN, infinite or negative values with an Error
// that names the file, the count and the first pixel. 0 stays 0 (= no measurement).
ImageDepth ReadDepthImage(const std::filesystem::path& path,
                          const DepthEncoding& encoding = DepthEncoding());

// Depth as 16-bit PNG, value = round(meters * scale); 0 stays 0. Throws when a value does not fit
// in 16 bits at this scale (it would otherwise wrap silently).
void WriteDepthPng(const std::filesystem::path& path, const ImageDepth& depth,
                   double scale = 5000.0);
// Depth as single-channel 32-bit float EXR in meters (bit-exact round trip).
void WriteDepthExr(const std::filesystem::path& path, const ImageDepth& depth);

// Throws Error naming `source` when depth holds NaN, infinite or negative values.
void CheckDepthValues(const ImageDepth& depth, const std::string& source);

}  // namespace genscene
