// Analytic test scenes: a room (an inward-facing box), axis-aligned boxes and spheres, each with a
// Lambertian albedo, ray cast exactly. They give depth maps with closed-form ground truth for the
// tests of every stage, and the built-in demo sequence before the path tracer renders
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
    // Optional smooth stripes (a textured surface): with stripe_period > 0 the albedo at p is
    // albedo + (albedo2 - albedo) * (0.5 + 0.5 sin(2 pi (p.x + p.z) / stripe_period)).
    Eigen::Vector3f albedo2 = Eigen::Vector3f::Zero();
    double stripe_period = 0.0;  // meters; 0 = plain albedo
    Eigen::Vector3f AlbedoAt(const Eigen::Vector3d& p) const;
  };
  struct Room {  // axis-aligned; seen from inside; albedo per wall: -x +x -y +y -z(floor)
                 // +z(ceiling)
    Eigen::AlignedBox3d bounds;
    std::array<Eigen::Vector3f, 6> albedo;
    bool open_front = false;  // no -y wall (a Cornell box seen from outside its open side)
  };
  std::optional<Room> room;
  std::vector<Box> boxes;
  std::vector<Sphere> spheres;
  Eigen::Vector3d light_position{0.0, 0.0, 1.9};  // world, meters
  double ambient = 0.25;                          // fraction of unshadowed ambient light
  // Optional texture on every surface, so that colour features have corners to find (posters,
  // tiles, wood grain in a real room): with texture_tile > 0 m the albedo is scaled by a
  // brightness drawn per square tile of that size in the surface's plane, in [0.15, 1], times one
  // per tile a third that size, in [0.6, 1] (tiles keyed by texture_seed). 0 = plain albedo.
  double texture_tile = 0.0;
  uint64_t texture_seed = 1;
  // The texture's factor at surface point p with normal n (1 without texture).
  float TextureAt(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const;

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

// A 5 x 4 x 2.6 m living room (x in [-2.5, 2.5], y in [-2, 2], z up): off-white walls (the
// +x wall blue-grey), a grey floor, a white ceiling, a table, a sofa against the +y wall, a
// cabinet against the -x wall and a red ball; lit from (0, 0, 2.5). render::MakeRoomScene is its
// path-traced version.
SyntheticScene MakeLivingRoomScene();

// A striped wall (x in [-1.5, 1.5], y in [1, 1.05], z in [0, 2]; albedo varying smoothly between
// (0.1, 0.3, 0.8) and (0.9, 0.7, 0.2) with a 0.5 m period) and a red box 0.4 m in front of it,
// under ambient light only (colour = albedo): the texturing tests' and bench's scene.
SyntheticScene MakeStripedWallScene();

// Exact planar depth (0 where the ray escapes), shaded linear colour and known pose for one view.
RgbdFrame RenderSyntheticFrame(const SyntheticScene& scene, const CameraIntrinsics& intrinsics,
                               const Eigen::Isometry3d& world_from_camera, double timestamp);

// Camera poses on an arc around `target` at `radius` and height `height`, looking at the target
// (OpenCV axes, z up world), spaced over `arc_degrees`, timestamps 1/30 s apart.
Trajectory MakeOrbitTrajectory(const Eigen::Vector3d& target, double radius, double height,
                               double arc_degrees, int frames);

// Like MakeOrbitTrajectory with the slow sway of a hand-held camera: the eye and the point looked
// at drift smoothly (a few low-frequency sines with phases drawn from `seed`) by up to 3 % and
// 5 % of the radius.
Trajectory MakeHandheldTrajectory(const Eigen::Vector3d& target, double radius, double height,
                                  double arc_degrees, int frames, uint64_t seed);

// A camera walked `turns` times around a circle of `radius` about `center` at `height`, looking
// outwards at the walls and 15 degrees down, swaying by up to 5 cm and a few degrees; every whole
// turn ends where it began (a loop for loop closure). Time stamps 1/30 s apart.
Trajectory MakeRoomLoopTrajectory(const Eigen::Vector3d& center, double radius, double height,
                                  double turns, int frames, uint64_t seed);

// Pose of a camera at `eye` looking at `target` with world up +z (OpenCV camera axes).
Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

}  // namespace genscene

namespace genscene {

// A structured-light sensor's depth distortion: depth scaled by 1 + k r^2, r the distance from
// the principal point over cx (1 at the left and right borders). Such sensors' depth errors grow
// towards the image's borders (Herrera et al. 2012, Teichman et al. 2013); a scan through a
// room bends its walls and tracking drifts. Zero depth stays zero.
void AddRadialDepthBias(ImageDepth& depth, const CameraIntrinsics& intrinsics, double k);

// Kinect-v1-like depth degradation, in this order:
//  1. dropouts at depth edges: a pixel whose 4-neighbour is invalid or more than 5 % nearer or
//     farther is lost with probability 0.5 (the projector's shadow and mixed pixels);
//  2. axial Gaussian noise sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 m (Nguyen, Izadi, Lovell 2012);
//  3. disparity quantisation: the sensor measures disparity d = f b / z in 1/8 pixel steps
//     (f = 580 px, baseline b = 0.075 m), so z is rounded to f b / (round(8 d) / 8).
// Random numbers are keyed by (seed, frame, pixel): the same seed gives the same noise whatever
// the thread count. Invalid pixels (0) stay 0.
void AddKinectDepthNoise(ImageDepth& depth, uint64_t seed, uint64_t frame_index);

}  // namespace genscene
