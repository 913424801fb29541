#include "core/image_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/binary_io.h"
#include "core/check.h"
#include "core/file_util.h"

namespace genscene {

namespace fs = std::filesystem;

namespace {

// OpenCV reads OPENCV_IO_ENABLE_OPENEXR once, at the first EXR call (DESIGN.md §5), and logs
// decoder warnings on stderr; we report our own one-line errors instead.
void ConfigureOpenCvOnce() {
  static const bool configured = [] {
    ::setenv("OPENCV_IO_ENABLE_OPENEXR", "1", /*overwrite=*/0);
    cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
    return true;
  }();
  (void)configured;
}

// The largest image genscene reads: 16384 pixels per side (as the film size) and 2^25 pixels (a
// float RGB copy of 403 MB). Checked from the header, before a decoder allocates by the declared
// size: a few hundred bytes of PNG or EXR can declare (and, compressed, hold) billions of pixels.
constexpr long long kMaxImageSide = 16384;
constexpr long long kMaxImagePixels = 1LL << 25;

void CheckDeclaredSize(const fs::path& path, long long width, long long height) {
  if (width < 1 || height < 1) {
    throw Error(
        Format(path.string(), ": cannot decode image (declares ", width, "x", height, " pixels)"));
  }
  if (width > kMaxImageSide || height > kMaxImageSide || width * height > kMaxImagePixels) {
    throw Error(Format(path.string(), ": image of ", width, "x", height,
                       " pixels is larger than genscene reads (at most ", kMaxImageSide,
                       " per side and ", kMaxImagePixels, " pixels)"));
  }
}

// Walks the chunk structure of a PNG (signature, then length/type/data/CRC chunks up to IEND)
// so that a truncated or mangled file gets our one-line error instead of libpng's stderr output.
// The declared size is checked against the limits above.
void CheckPngStructure(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  static const char kSignature[] = "\x89PNG\r\n\x1a\n";
  if (bytes.size() < 8 || bytes.compare(0, 8, kSignature, 8) != 0) {
    throw Error(Format(path.string(), ": cannot decode image (not a PNG file)"));
  }
  size_t pos = 8;
  while (pos + 12 <= bytes.size()) {
    const size_t length = *LoadBE32(bytes, pos);
    const std::string type = bytes.substr(pos + 4, 4);
    if (length > bytes.size() - pos - 12) break;
    if (type == "IHDR" && length >= 8)
      CheckDeclaredSize(path, *LoadBE32(bytes, pos + 8), *LoadBE32(bytes, pos + 12));
    if (type == "IEND") return;
    pos += 12 + length;
  }
  throw Error(Format(path.string(), ": cannot decode image (truncated or corrupt PNG)"));
}

// Channel names from a file, fit for a one-line error: bytes outside printable ASCII become '?'.
std::string Printable(std::string text) {
  for (char& c : text) {
    if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
  }
  return text;
}

// What the channel list of an OpenEXR header says that genscene refuses before decoding.
struct ExrChannels {
  int count = 0;
  std::string subsampled;  // the first channel with x or y sampling other than 1, if any
  int x_sampling = 1, y_sampling = 1;
};

// The size of an OpenEXR attribute value of `type` starting at bytes[at], as OpenEXR's reader
// consumes it: fixed for the scalar, vector, box and matrix types, parsed for chlist (channels up
// to an empty name) and preview (width x height RGBA); other types (string, vectors, unknown
// ones) are read by their declared size, `declared`, which is returned as it is. SIZE_MAX when the
// value runs past the end of the file or is malformed.
size_t ExrValueSize(const std::string& type, const std::string& bytes, size_t at, uint32_t declared,
                    ExrChannels* channels) {
  static const std::map<std::string, size_t> kFixed = {
      {"box2i", 16},      {"box2f", 16},   {"chromaticities", 32},
      {"compression", 1}, {"double", 8},   {"envmap", 1},
      {"float", 4},       {"int", 4},      {"keycode", 28},
      {"lineOrder", 1},   {"m33f", 36},    {"m33d", 72},
      {"m44f", 64},       {"m44d", 128},   {"rational", 8},
      {"tiledesc", 9},    {"timecode", 8}, {"v2i", 8},
      {"v2f", 8},         {"v2d", 16},     {"v3i", 12},
      {"v3f", 12},        {"v3d", 24},     {"deepImageState", 1}};
  constexpr size_t kBad = SIZE_MAX;
  if (auto it = kFixed.find(type); it != kFixed.end()) return it->second;
  if (type ==
      "chlist") {  // { name\0, int32 type, uint8 linear, 3 reserved, int32 xs, int32 ys }* \0
    size_t p = at;
    int channels_read = 0;
    for (int guard = 0; guard <= 1024; ++guard) {
      const size_t end = bytes.find('\0', p);
      if (end == std::string::npos || end - p > 255) return kBad;
      if (end == p) {
        channels->count = std::max(channels->count, channels_read);
        return end + 1 - at;
      }
      ++channels_read;
      const std::optional<uint32_t> xs = LoadLE32(bytes, end + 9), ys = LoadLE32(bytes, end + 13);
      if (!xs || !ys) return kBad;
      if ((*xs != 1 || *ys != 1) && channels->subsampled.empty()) {
        channels->subsampled = Printable(bytes.substr(p, end - p));
        channels->x_sampling = static_cast<int32_t>(*xs);
        channels->y_sampling = static_cast<int32_t>(*ys);
      }
      p = end + 1 + 16;
      if (p > bytes.size()) return kBad;
    }
    return kBad;
  }
  if (type == "preview") {  // uint32 width, uint32 height, 4 bytes per pixel
    const std::optional<uint32_t> w = LoadLE32(bytes, at), h = LoadLE32(bytes, at + 4);
    if (!w || !h || (*w && *h > (bytes.size() / 4) / *w)) return kBad;
    return 8 + 4 * size_t{*w} * *h;
  }
  return declared;
}

// Walks the header and the line offset table of a scanline OpenEXR file (magic, attributes up to
// the empty name, one offset per chunk, each chunk's y and size within the file), for the same
// reason: OpenCV's EXR decoder prints its own exceptions on stderr. Tiled, multi-part and deep
// files, and unknown compressions, are left to OpenCV after the header.
void CheckExrStructure(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  const auto fail = [&] {
    throw Error(
        Format(path.string(), ": cannot decode image (corrupt, truncated or unsupported format)"));
  };
  const auto u32 = [&](size_t at) {
    const std::optional<uint32_t> v = LoadLE32(bytes, at);
    if (!v) fail();
    return *v;
  };
  if (bytes.size() < 8 || u32(0) != 20000630u) fail();  // 0x762f3101 little-endian
  const uint32_t flags = u32(4);
  size_t pos = 8;
  int compression = -1;
  ExrChannels channels;
  long long x_min = 0, y_min = 0, x_max = -1, y_max = -1;
  bool has_data_window = false;
  // OpenEXR reads a name or type name of at most 31 characters (254 with the long-names flag) and
  // goes on after that many bytes when no NUL came: a longer name would make it read the rest of
  // the header from another position than this walk (a 1.6 GB attribute value, found by fuzz_exr).
  const size_t max_name = (flags & 0x400u) ? 254 : 31;
  const auto read_string = [&] {
    const size_t end = bytes.find('\0', pos);
    if (end == std::string::npos || end - pos > max_name) fail();
    std::string text = bytes.substr(pos, end - pos);
    pos = end + 1;
    return text;
  };
  // A multi-part file (flag 0x1000) holds one header per part, each ending with an empty name, and
  // an empty header after the last; OpenEXR reads them all before any pixel (a part's attribute
  // declaring 1.9 GB in a 755-byte file, found by fuzz_exr), so every header is walked. Only the
  // first part's window and compression are kept: it is the part that is read.
  for (int header = 0;; ++header) {
    if (header > 0) {
      if (!(flags & 0x1000u)) break;
      if (pos >= bytes.size()) fail();
      if (bytes[pos] == '\0') {  // the empty header: the end of the list
        ++pos;
        break;
      }
      if (header > 1000) fail();
    }
    for (int attributes = 0;; ++attributes) {
      if (attributes > 1000) fail();
      const std::string name = read_string();
      if (name.empty()) break;
      const std::string type = read_string();
      const uint32_t size = u32(pos);
      pos += 4;
      if (size > bytes.size() - pos) fail();
      // OpenEXR reads a known type's value by the type's layout, not by the declared size: where
      // the two disagree it goes on from another position than this walk (and has allocated what a
      // misread size said: 1.7 GB, found by fuzz_exr). So the declared size must be the layout's.
      if (ExrValueSize(type, bytes, pos, size, &channels) != size) fail();
      if (name == "dataWindow" && size == 16) {
        const long long window[4] = {
            static_cast<int32_t>(u32(pos)), static_cast<int32_t>(u32(pos + 4)),
            static_cast<int32_t>(u32(pos + 8)), static_cast<int32_t>(u32(pos + 12))};
        if (header == 0) {  // checked after the walk
          x_min = window[0], y_min = window[1], x_max = window[2], y_max = window[3];
          has_data_window = true;
        } else {
          CheckDeclaredSize(path, window[2] - window[0] + 1, window[3] - window[1] + 1);
        }
      }
      if (header == 0 && name == "compression" && size == 1)
        compression = static_cast<unsigned char>(bytes[pos]);
      pos += size;
    }
  }
  // OpenEXR sizes its line buffers by the data window and the channels (a 2 GB buffer for a
  // window 2^27 wide, found by fuzz_exr); OpenCV then allocates the whole image.
  if (!has_data_window) fail();
  CheckDeclaredSize(path, x_max - x_min + 1, y_max - y_min + 1);
  if (channels.count > 16) {
    throw Error(Format(path.string(), ": EXR with ", channels.count,
                       " channels (genscene reads at most 16)"));
  }
  // OpenCV's EXR decoder overruns its buffers on subsampled channels (heap corruption, found by
  // fuzz_exr: a channel with x sampling 8); depth and colour images are never subsampled.
  if (!channels.subsampled.empty()) {
    throw Error(Format(path.string(), ": EXR channel \"", channels.subsampled, "\" is subsampled (",
                       channels.x_sampling, "x", channels.y_sampling,
                       "); genscene reads only full-resolution channels"));
  }
  if (flags & (0x200u | 0x800u | 0x1000u)) return;  // tiled, multi-part, deep
  static const int kLinesPerChunk[] = {1, 1, 1, 16, 32, 16, 32, 32, 32, 256};
  if (compression < 0 || compression > 9) return;  // (the window is at least 1x1 here)
  const long long lines = kLinesPerChunk[compression];
  const long long chunks = (y_max - y_min + 1 + lines - 1) / lines;
  if (chunks > static_cast<long long>((bytes.size() - pos) / 8)) fail();
  for (long long c = 0; c < chunks; ++c) {
    const uint64_t offset = (static_cast<uint64_t>(u32(pos + 8 * c + 4)) << 32) | u32(pos + 8 * c);
    if (offset > bytes.size() || bytes.size() - offset < 8) fail();
    const uint32_t size = u32(offset + 4);
    if (size > bytes.size() - offset - 8) fail();
  }
}

// Reads a checked scanline or tiled OpenEXR file with OpenEXR itself (OpenCV's EXR decoder prints
// its exceptions on stderr, a second line beside our error): R, G, B as a 3-channel float image in
// OpenCV's BGR order, else Y or the only channel (a depth image) as a 1-channel one; `color`
// replicates a 1-channel image to 3 channels, as cv::IMREAD_COLOR does.
cv::Mat ReadExr(const fs::path& path, bool color) {
  const auto corrupt = [&] {
    return Error(
        Format(path.string(), ": cannot decode image (corrupt, truncated or unsupported format)"));
  };
  cv::Mat mat;
  try {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i window = file.header().dataWindow();
    const Imf::ChannelList& channels = file.header().channels();
    std::vector<std::string> names;
    for (auto it = channels.begin(); it != channels.end(); ++it) names.push_back(it.name());
    std::vector<std::string> read;  // in the order of the cv::Mat channels
    if (channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B")) {
      read = {"B", "G", "R"};
    } else if (channels.findChannel("Y")) {
      read = {"Y"};
    } else if (names.size() == 1) {
      read = {names[0]};
    } else {
      std::string list;
      for (const std::string& name : names) list += (list.empty() ? "" : ", ") + name;
      throw Error(Format(path.string(), ": EXR channels (", Printable(list),
                         ") hold neither R, G, B nor Y nor a single channel (depth)"));
    }
    const int width = window.max.x - window.min.x + 1, height = window.max.y - window.min.y + 1;
    const int count = static_cast<int>(read.size());
    mat.create(height, width, CV_32FC(count));
    Imf::FrameBuffer buffer;
    const size_t x_stride = sizeof(float) * count, y_stride = x_stride * width;
    for (int c = 0; c < count; ++c) {
      buffer.insert(read[c],
                    Imf::Slice::Make(Imf::FLOAT, mat.ptr<float>() + c, window, x_stride, y_stride));
    }
    file.setFrameBuffer(buffer);
    file.readPixels(window.min.y, window.max.y);
  } catch (const Error&) {
    throw;
  } catch (const std::exception&) {
    throw corrupt();
  }
  if (color && mat.channels() == 1) cv::merge(std::vector<cv::Mat>{mat, mat, mat}, mat);
  return mat;
}

bool HasExtension(const fs::path& path, const char* extension) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == extension;
}

cv::Mat ReadWithOpenCv(const fs::path& path, int flags) {
  ConfigureOpenCvOnce();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(Format(path.string(), ": file not found"));
  if (fs::is_directory(path, ec)) throw Error(Format(path.string(), ": is a folder, not an image"));
  if (fs::file_size(path, ec) == 0) throw Error(Format(path.string(), ": empty file"));
  if (HasExtension(path, ".png")) CheckPngStructure(path);
  if (HasExtension(path, ".exr")) {
    CheckExrStructure(path);
    return ReadExr(path, flags != cv::IMREAD_UNCHANGED && (flags & cv::IMREAD_COLOR) != 0);
  }
  cv::Mat mat;
  try {
    mat = cv::imread(path.string(), flags);
  } catch (const cv::Exception& e) {
    throw Error(Format(path.string(), ": cannot decode image (", e.err, ")"));
  }
  if (mat.empty()) {
    throw Error(
        Format(path.string(), ": cannot decode image (corrupt, truncated or unsupported format)"));
  }
  return mat;
}

void WriteWithOpenCv(const fs::path& path, const cv::Mat& mat, const std::vector<int>& params) {
  ConfigureOpenCvOnce();
  WriteFileAtomically(path, [&](const fs::path& tmp) {
    bool ok = false;
    try {
      ok = cv::imwrite(tmp.string(), mat, params);
    } catch (const cv::Exception& e) {
      throw Error(Format(path.string(), ": cannot write image (", e.err, ")"));
    }
    if (!ok) throw Error(Format(path.string(), ": cannot write image"));
  });
}

// Integer depth value -> meters, per encoding.
float DecodeDepth(uint16_t raw, const DepthEncoding& encoding) {
  switch (encoding.kind) {
    case DepthEncoding::Kind::kScaled:
      if (static_cast<int>(raw) == encoding.invalid_value) return 0.0f;
      return static_cast<float>(raw / encoding.scale);
    case DepthEncoding::Kind::kNyuDisparity: {
      // NYU raw PGMs hold the disparity little-endian although PGM is big-endian (OpenCV reads
      // it big-endian), so swap the bytes back as Open3D's NYU reader does; 2047 = no reading,
      // and any value giving a non-positive depth is invalid.
      const uint16_t d = static_cast<uint16_t>((raw >> 8) | (raw << 8));
      const double meters = 351.3 / (1092.5 - d);
      return meters > 0.0 ? static_cast<float>(meters) : 0.0f;
    }
    case DepthEncoding::Kind::kSunRotated: {
      const uint16_t rotated = static_cast<uint16_t>((raw >> 3) | (raw << 13));
      return static_cast<float>(rotated / 1000.0);
    }
  }
  return 0.0f;
}

}  // namespace

ImageRgb ReadColorImage(const fs::path& path, const CameraResponse& response) {
  cv::Mat mat = ReadWithOpenCv(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_COLOR);
  GS_CHECK_EQ(mat.channels(), 3);
  ImageRgb image(mat.cols, mat.rows);
  const int depth = mat.depth();
  const bool is_float = depth == CV_32F || depth == CV_64F || depth == CV_16F;
  if (depth != CV_8U && depth != CV_16U && !is_float) {
    throw Error(Format(path.string(), ": unsupported pixel type (OpenCV depth ", depth, ")"));
  }
  const double scale = depth == CV_8U ? 1.0 / 255.0 : depth == CV_16U ? 1.0 / 65535.0 : 1.0;
  if (depth == CV_8U) {
    // 256 values: each decoded once (the same conversion and response as below).
    cv::Mat codes(1, 256, CV_8U), code_values;
    for (int i = 0; i < 256; ++i) codes.at<uint8_t>(0, i) = static_cast<uint8_t>(i);
    codes.convertTo(code_values, CV_32F, scale);
    float linear[256];
    for (int i = 0; i < 256; ++i) linear[i] = response.ToLinear(code_values.at<float>(0, i));
    for (int v = 0; v < mat.rows; ++v) {
      const cv::Vec3b* row = mat.ptr<cv::Vec3b>(v);
      for (int u = 0; u < mat.cols; ++u) {
        image(u, v) = Eigen::Vector3f(linear[row[u][2]], linear[row[u][1]], linear[row[u][0]]);
      }
    }
    return image;
  }
  cv::Mat as_float;
  mat.convertTo(as_float, CV_32FC3, scale);
  // A NaN or infinite colour (float images only) would poison every sum it enters: texturing's
  // averages, light estimation's normal equations. Negative values are kept (filters with negative
  // lobes give them; they are valid observations of a linear image).
  size_t bad = 0;
  int first_u = -1, first_v = -1;
  float first_value = 0.0f;
  for (int v = 0; v < as_float.rows; ++v) {
    const cv::Vec3f* row = as_float.ptr<cv::Vec3f>(v);
    for (int u = 0; u < as_float.cols; ++u) {
      const cv::Vec3f& bgr = row[u];
      Eigen::Vector3f rgb(bgr[2], bgr[1], bgr[0]);
      if (!is_float) {
        for (int c = 0; c < 3; ++c) rgb[c] = response.ToLinear(rgb[c]);
      } else if (!rgb.allFinite()) {
        if (bad++ == 0) {
          first_u = u, first_v = v;
          first_value = std::isfinite(rgb[0]) ? (std::isfinite(rgb[1]) ? rgb[2] : rgb[1]) : rgb[0];
        }
      }
      image(u, v) = rgb;
    }
  }
  if (bad > 0) {
    throw Error(Format(path.string(), ": ", bad, " pixels have a NaN or infinite colour (first: ",
                       first_value, " at pixel (", first_u, ", ", first_v, "))"));
  }
  return image;
}

void WriteExr(const fs::path& path, const ImageRgb& image) {
  GS_CHECK(!image.empty());
  cv::Mat mat(image.height(), image.width(), CV_32FC3);
  for (int v = 0; v < image.height(); ++v) {
    cv::Vec3f* row = mat.ptr<cv::Vec3f>(v);
    for (int u = 0; u < image.width(); ++u) {
      const Eigen::Vector3f& rgb = image(u, v);
      row[u] = cv::Vec3f(rgb[2], rgb[1], rgb[0]);
    }
  }
  WriteWithOpenCv(path, mat, {cv::IMWRITE_EXR_TYPE, cv::IMWRITE_EXR_TYPE_FLOAT});
}

void WritePng(const fs::path& path, const ImageRgb& image, const CameraResponse& response) {
  GS_CHECK(!image.empty());
  cv::Mat mat(image.height(), image.width(), CV_8UC3);
  for (int v = 0; v < image.height(); ++v) {
    cv::Vec3b* row = mat.ptr<cv::Vec3b>(v);
    for (int u = 0; u < image.width(); ++u) {
      const Eigen::Vector3f& rgb = image(u, v);
      for (int c = 0; c < 3; ++c) {
        const float encoded = response.FromLinear(std::isfinite(rgb[c]) ? rgb[c] : 0.0f);
        row[u][2 - c] = static_cast<uint8_t>(std::lround(encoded * 255.0f));
      }
    }
  }
  WriteWithOpenCv(path, mat, {});
}

void CheckDepthValues(const ImageDepth& depth, const std::string& source) {
  size_t bad = 0;
  int first_u = -1, first_v = -1;
  float first_value = 0.0f;
  for (int v = 0; v < depth.height(); ++v) {
    for (int u = 0; u < depth.width(); ++u) {
      const float d = depth(u, v);
      if (std::isfinite(d) && d >= 0.0f) continue;
      if (bad++ == 0) first_u = u, first_v = v, first_value = d;
    }
  }
  if (bad > 0) {
    throw Error(Format(source, ": ", bad, " depth values are NaN, infinite or negative (first: ",
                       first_value, " at pixel (", first_u, ", ", first_v, "))"));
  }
}

ImageDepth ReadDepthImage(const fs::path& path, const DepthEncoding& encoding) {
  if (encoding.kind == DepthEncoding::Kind::kScaled && !(encoding.scale > 0.0)) {
    throw Error(Format(path.string(), ": depth scale ", encoding.scale, " must be positive"));
  }
  const cv::Mat mat = ReadWithOpenCv(path, cv::IMREAD_UNCHANGED);
  if (mat.channels() != 1) {
    throw Error(Format(path.string(), ": depth image has ", mat.channels(),
                       " channels, expected 1 (16-bit PNG/PGM or float EXR)"));
  }
  ImageDepth depth(mat.cols, mat.rows);
  if (mat.depth() == CV_16U) {
    for (int v = 0; v < mat.rows; ++v) {
      const uint16_t* row = mat.ptr<uint16_t>(v);
      for (int u = 0; u < mat.cols; ++u) depth(u, v) = DecodeDepth(row[u], encoding);
    }
  } else if (mat.depth() == CV_32F) {
    for (int v = 0; v < mat.rows; ++v) {
      const float* row = mat.ptr<float>(v);
      for (int u = 0; u < mat.cols; ++u) depth(u, v) = row[u];
    }
  } else {
    throw Error(Format(path.string(), ": depth image must be 16-bit integer or 32-bit float, got ",
                       mat.depth() == CV_8U ? "8-bit" : "another type",
                       " (an 8-bit image is probably a colour or visualisation image)"));
  }
  CheckDepthValues(depth, path.string());
  return depth;
}

void WriteDepthPng(const fs::path& path, const ImageDepth& depth, double scale) {
  GS_CHECK(!depth.empty());
  GS_CHECK_GT(scale, 0.0);
  CheckDepthValues(depth, path.string());
  cv::Mat mat(depth.height(), depth.width(), CV_16UC1);
  for (int v = 0; v < depth.height(); ++v) {
    uint16_t* row = mat.ptr<uint16_t>(v);
    for (int u = 0; u < depth.width(); ++u) {
      const double value = std::round(depth(u, v) * scale);
      if (value > 65535.0) {
        throw Error(Format(path.string(), ": depth ", depth(u, v), " m at pixel (", u, ", ", v,
                           ") does not fit in 16 bits at scale ", scale));
      }
      row[u] = static_cast<uint16_t>(value);
    }
  }
  WriteWithOpenCv(path, mat, {});
}

void WriteDepthExr(const fs::path& path, const ImageDepth& depth) {
  GS_CHECK(!depth.empty());
  cv::Mat mat(depth.height(), depth.width(), CV_32FC1, const_cast<float*>(depth.data()));
  WriteWithOpenCv(path, mat, {cv::IMWRITE_EXR_TYPE, cv::IMWRITE_EXR_TYPE_FLOAT});
}

std::vector<uint8_t> EncodePng(int width, int height, const std::vector<uint8_t>& rgb8) {
  if (width <= 0 || height <= 0 || rgb8.size() != static_cast<size_t>(width) * height * 3) {
    throw Error(Format("EncodePng: ", rgb8.size(), " bytes for a ", width, "x", height, " image"));
  }
  cv::Mat bgr(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y) {
    const uint8_t* in = rgb8.data() + static_cast<size_t>(y) * width * 3;
    uint8_t* out = bgr.ptr<uint8_t>(y);
    for (int x = 0; x < width; ++x) {
      out[3 * x] = in[3 * x + 2], out[3 * x + 1] = in[3 * x + 1], out[3 * x + 2] = in[3 * x];
    }
  }
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", bgr, png)) {
    throw Error(Format("cannot encode a ", width, "x", height, " image as PNG"));
  }
  return png;
}

}  // namespace genscene
