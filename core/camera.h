// Pinhole camera intrinsics, OpenCV convention (DESIGN.md §1): camera x right, y down, z forward;
// integer pixel coordinates (u, v) are pixel CENTRES; the ray through (u, v) has camera-frame
// direction ((u - cx) / fx, (v - cy) / fy, 1). Depth is planar z along the camera axis.
#pragma once

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <optional>
#include <string>

namespace genscene {

struct CameraIntrinsics {
  double fx = 0.0;  // focal length in pixels, x
  double fy = 0.0;  // focal length in pixels, y
  double cx =
      0.0;  // principal point in pixels (pixel-centre convention: centred image has (W-1)/2)
  double cy = 0.0;
  int width = 0;  // image size in pixels
  int height = 0;
  // Lens distortion k1 k2 p1 p2 k3 (OpenCV order). Sources take it out at ingest
  // (core/frame_source.h Undistorted): every stage sees a camera without distortion.
  std::array<double, 5> distortion{};

  // Camera-frame direction through pixel (u, v), with z = 1.
  Eigen::Vector3d RayDirection(double u, double v) const {
    return {(u - cx) / fx, (v - cy) / fy, 1.0};
  }
  // The 3D point in the camera frame seen at pixel (u, v) with planar depth z (meters).
  Eigen::Vector3d Unproject(double u, double v, double z) const { return RayDirection(u, v) * z; }
  // Pixel coordinates of a camera-frame point; std::nullopt when it is not in front of the camera.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_camera) const;
  // True when pixel coordinates (u, v) fall inside the image (pixel footprints [-0.5, W-0.5)).
  bool Contains(const Eigen::Vector2d& uv) const;

  // A centred camera (cx = (W-1)/2, cy = (H-1)/2) with square pixels of focal length `focal` px.
  static CameraIntrinsics Centered(int width, int height, double focal);
  // The same with the focal length that gives a horizontal field of view of hfov_degrees.
  static CameraIntrinsics FromHorizontalFov(int width, int height, double hfov_degrees);

  // Intrinsics of the same camera with the image resized by `factor` (e.g. 0.5 for one level of
  // an image pyramid): focal lengths scale, and the principal point keeps the pixel-centre
  // convention, c' = (c + 0.5) * factor - 0.5. Sizes are rounded down.
  CameraIntrinsics Scaled(double factor) const;

  // Throws genscene::Error naming `source` when a value is absurd: non-finite, focal length not in
  // (0, 1e5] px, size not in [1, 16384], principal point more than half an image outside.
  void Validate(const std::string& source = "intrinsics") const;

  // "fx fy cx cy width height" as in the intrinsics file.
  std::string ToString() const;
};

// Reads an intrinsics file: one line `fx fy cx cy width height` (optionally followed by the five
// distortion coefficients), or an Open3D PinholeCameraIntrinsic JSON file (`width`, `height`,
// column-major `intrinsic_matrix`). Throws Error naming the file on any problem.
CameraIntrinsics ReadIntrinsicsFile(const std::filesystem::path& path);
// Writes the one-line format, atomically.
void WriteIntrinsicsFile(const std::filesystem::path& path, const CameraIntrinsics& intrinsics);

// Well-known calibrations, by name: "tum1", "tum2", "tum3" (TUM RGB-D freiburg1/2/3, 640x480,
// with their distortion), "primesense" (525, 525, 319.5, 239.5; 640x480, Open3D's default).
std::optional<CameraIntrinsics> NamedIntrinsics(const std::string& name);
// Names accepted by NamedIntrinsics, for help texts.
std::string NamedIntrinsicsList();
// A name from NamedIntrinsics or a path to a file readable by ReadIntrinsicsFile.
CameraIntrinsics ResolveIntrinsics(const std::string& name_or_path);

}  // namespace genscene
