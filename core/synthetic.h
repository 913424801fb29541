// Analytic test scenes: a room (an inward-facing box), axis-aligned boxes and spheres, each with a
// Lambertian albedo, ray cast exactly. They give depth maps with closed-form ground truth for the
// tests of every stage, and the built-in demo sequence before the path tracer (issue 3) renders
// radiometrically exact ones. Shading here is a simple local model (no shadows, no
// interreflection): colour = albedo * (ambient + (1 - ambient) * max(0, n.l)) for a light point.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "core/camera.h"
#include "core/mesh.h"
#include "core/rgbd_frame.h"
#include "core/trajectory.h"

namespace genscene {

struct SyntheticScene {
  struct Sphere {
    Eigen::Vector3d center;
    double radius = 0.0;
    Eigen::Vector3f albedo;
  };
  struct Box {  // axis-aligned; seen from outside
    Eigen::AlignedBox3d bounds;
    Eigen::Vector3f albedo;
  };
  struct Room {  // axis-aligned; seen from inside; albedo per wall: -x +x -y +y -z(floor) +z(ceiling)
    Eigen::AlignedBox3d bounds;
    std::array<Eigen::Vector3f, 6> albedo;
    bool open_front = false;  // no -y wall (a Cornell box seen from outside its open side)
  };
  std::optional<Room> room;
  std::vector<Box> boxes;
  std::vector<Sphere> spheres;
  Eigen::Vector3d light_position{0.0, 0.0, 1.9};  // world, meters
  double ambient = 0.25;                          // fraction of unshadowed ambient light

  struct Hit {
    double t = 0.0;  // ray parameter: point = origin + t * direction
    Eigen::Vector3d normal;
    Eigen::Vector3f albedo;
  };
  // Nearest hit with t > t_min of the ray origin + t * direction.
  std::optional<Hit> Intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                               double t_min = 1e-9) const;

  // Triangle mesh of the scene (spheres as icospheres with `sphere_subdivisions` levels), face
  // colours = albedo. Walls and box faces are counter-clockwise seen from their visible side.
  TriangleMesh ToMesh(int sphere_subdivisions = 3) const;
};

// A Cornell-box-like room 2 m wide (x in [-1, 1], y in [-1, 1], z in [0, 2]): red left wall (-x),
// green right wall (+x), white elsewhere, a white box and a sphere on the floor. z is up.
SyntheticScene MakeCornellScene();

// Exact planar depth (0 where the ray escapes), shaded linear colour and known pose for one view.
RgbdFrame RenderSyntheticFrame(const SyntheticScene& scene, const CameraIntrinsics& intrinsics,
                               const Eigen::Isometry3d& world_from_camera, double timestamp);

// Camera poses on an arc around `target` at `radius` and height `height`, looking at the target
// (OpenCV axes, z up world), spaced over `arc_degrees`, timestamps 1/30 s apart.
Trajectory MakeOrbitTrajectory(const Eigen::Vector3d& target, double radius, double height,
                               double arc_degrees, int frames);

// Pose of a camera at `eye` looking at `target` with world up +z (OpenCV camera axes).
Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

}  // namespace genscene

namespace genscene {

// Kinect-v1-like depth noise (Nguyen, Izadi, Lovell 2012, axial model):
// sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 meters, Gaussian, seeded per (seed, frame, pixel) so the
// same seed gives the same noise whatever the thread count; invalid pixels stay 0.
void AddKinectDepthNoise(ImageDepth& depth, uint64_t seed, uint64_t frame_index);

}  // namespace genscene
