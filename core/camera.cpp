#include "core/camera.h"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "core/check.h"
#include "core/file_util.h"
#include "core/json_util.h"

namespace genscene {

std::optional<Eigen::Vector2d> CameraIntrinsics::Project(const Eigen::Vector3d& p_camera) const {
  if (!(p_camera.z() > 0.0)) return std::nullopt;
  return Eigen::Vector2d(fx * p_camera.x() / p_camera.z() + cx,
                         fy * p_camera.y() / p_camera.z() + cy);
}

bool CameraIntrinsics::Contains(const Eigen::Vector2d& uv) const {
  return uv.x() >= -0.5 && uv.y() >= -0.5 && uv.x() < width - 0.5 && uv.y() < height - 0.5;
}

CameraIntrinsics CameraIntrinsics::Centered(int width, int height, double focal) {
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  k.fx = k.fy = focal;
  k.cx = 0.5 * (width - 1);
  k.cy = 0.5 * (height - 1);
  return k;
}

CameraIntrinsics CameraIntrinsics::FromHorizontalFov(int width, int height, double hfov_degrees) {
  return Centered(width, height, 0.5 * width / std::tan(0.5 * hfov_degrees * M_PI / 180.0));
}

CameraIntrinsics CameraIntrinsics::Scaled(double factor) const {
  GS_CHECK_GT(factor, 0.0);
  CameraIntrinsics out = *this;
  out.fx = fx * factor;
  out.fy = fy * factor;
  out.cx = (cx + 0.5) * factor - 0.5;
  out.cy = (cy + 0.5) * factor - 0.5;
  out.width = static_cast<int>(std::floor(width * factor));
  out.height = static_cast<int>(std::floor(height * factor));
  return out;
}

void CameraIntrinsics::Validate(const std::string& source) const {
  for (double v : {fx, fy, cx, cy}) {
    if (!std::isfinite(v))
      throw Error(Format(source, ": non-finite value in intrinsics ", ToString()));
  }
  if (!(fx > 0.0 && fx <= 1e5 && fy > 0.0 && fy <= 1e5)) {
    throw Error(Format(source, ": focal length fx=", fx, " fy=", fy, " px is not in (0, 1e5]"));
  }
  if (width < 1 || height < 1 || width > 16384 || height > 16384) {
    throw Error(Format(source, ": image size ", width, "x", height, " is not in [1, 16384]"));
  }
  if (cx < -0.5 * width || cx > 1.5 * width || cy < -0.5 * height || cy > 1.5 * height) {
    throw Error(Format(source, ": principal point (", cx, ", ", cy, ") is far outside the ", width,
                       "x", height, " image"));
  }
  for (double d : distortion) {
    if (!std::isfinite(d)) throw Error(Format(source, ": non-finite distortion coefficient"));
  }
}

std::string CameraIntrinsics::ToString() const {
  std::ostringstream out;
  out << std::setprecision(10) << fx << " " << fy << " " << cx << " " << cy << " " << width << " "
      << height;
  return out.str();
}

namespace {

CameraIntrinsics ReadOpen3dJson(const std::filesystem::path& path, const std::string& text) {
  json_util::json j;
  try {
    j = json_util::json::parse(text);
  } catch (const std::exception& e) {
    throw Error(Format(path.string(), ": not valid JSON (", e.what(), ")"));
  }
  CameraIntrinsics k;
  try {
    const auto& m = j.at("intrinsic_matrix");  // 3x3, column-major
    if (!m.is_array() || m.size() != 9)
      throw Error(Format(path.string(), ": intrinsic_matrix must have 9 numbers"));
    k.width = json_util::JsonInt(j.at("width"), Format(path.string(), ": width"));
    k.height = json_util::JsonInt(j.at("height"), Format(path.string(), ": height"));
    k.fx = m[0].get<double>();
    k.fy = m[4].get<double>();
    k.cx = m[6].get<double>();
    k.cy = m[7].get<double>();
  } catch (const nlohmann::json::exception& e) {
    throw Error(Format(path.string(), ": not an Open3D camera intrinsic file (", e.what(), ")"));
  }
  return k;
}

}  // namespace

CameraIntrinsics ReadIntrinsicsFile(const std::filesystem::path& path) {
  const std::string text = ReadTextFile(path);
  const auto first = text.find_first_not_of(" \t\r\n");
  CameraIntrinsics k;
  if (first != std::string::npos && text[first] == '{') {
    k = ReadOpen3dJson(path, text);
  } else {
    const auto lines = ReadDataLines(path);
    if (lines.empty()) throw Error(Format(path.string(), ": empty intrinsics file"));
    const auto tokens = SplitWhitespace(lines[0].text);
    const std::string where = Format(path.string(), ":", lines[0].number);
    if (tokens.size() != 6 && tokens.size() != 11) {
      throw Error(Format(where, ": expected 'fx fy cx cy width height' [k1 k2 p1 p2 k3], got ",
                         tokens.size(), " values"));
    }
    k.fx = ParseDouble(tokens[0], where);
    k.fy = ParseDouble(tokens[1], where);
    k.cx = ParseDouble(tokens[2], where);
    k.cy = ParseDouble(tokens[3], where);
    const long long w = ParseInteger(tokens[4], where);
    const long long h = ParseInteger(tokens[5], where);
    if (w < 1 || h < 1 || w > 16384 || h > 16384) {
      throw Error(Format(where, ": image size ", w, "x", h, " is not in [1, 16384]"));
    }
    k.width = static_cast<int>(w);
    k.height = static_cast<int>(h);
    if (tokens.size() == 11) {
      for (int i = 0; i < 5; ++i) k.distortion[i] = ParseDouble(tokens[6 + i], where);
    }
  }
  k.Validate(path.string());
  return k;
}

void WriteIntrinsicsFile(const std::filesystem::path& path, const CameraIntrinsics& intrinsics) {
  intrinsics.Validate(path.string());
  std::ostringstream out;
  out << std::setprecision(17) << intrinsics.fx << " " << intrinsics.fy << " " << intrinsics.cx
      << " " << intrinsics.cy << " " << intrinsics.width << " " << intrinsics.height;
  bool distorted = false;
  for (double d : intrinsics.distortion) distorted |= d != 0.0;
  if (distorted) {
    for (double d : intrinsics.distortion) out << " " << d;
  }
  out << "\n";
  WriteTextFileAtomically(path, out.str());
}

std::optional<CameraIntrinsics> NamedIntrinsics(const std::string& name) {
  // TUM RGB-D calibrations of the RGB cameras
  // (vision.in.tum.de/data/datasets/rgbd-dataset/file_formats).
  CameraIntrinsics k;
  k.width = 640;
  k.height = 480;
  if (name == "tum1") {
    k.fx = 517.3, k.fy = 516.5, k.cx = 318.6, k.cy = 255.3;
    k.distortion = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
  } else if (name == "tum2") {
    k.fx = 520.9, k.fy = 521.0, k.cx = 325.1, k.cy = 249.7;
    k.distortion = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
  } else if (name == "tum3") {
    k.fx = 535.4, k.fy = 539.2, k.cx = 320.1, k.cy = 247.6;
  } else if (name == "primesense") {
    k.fx = 525.0, k.fy = 525.0, k.cx = 319.5, k.cy = 239.5;
  } else {
    return std::nullopt;
  }
  return k;
}

std::string NamedIntrinsicsList() {
  return "tum1, tum2, tum3, primesense";
}

CameraIntrinsics ResolveIntrinsics(const std::string& name_or_path) {
  if (auto named = NamedIntrinsics(name_or_path)) return *named;
  std::error_code ec;
  if (!std::filesystem::exists(name_or_path, ec)) {
    throw Error(Format("intrinsics '", name_or_path, "': neither a file nor one of ",
                       NamedIntrinsicsList()));
  }
  return ReadIntrinsicsFile(name_or_path);
}

}  // namespace genscene
