#include "core/synthetic.h"

#include <cmath>

#include "core/check.h"
#include "core/parallel.h"
#include "core/rng.h"

namespace genscene {

namespace {

// Slab test; returns entry/exit parameters and the axis/sign of the entry and exit faces.
struct SlabHit {
  double t_near, t_far;
  int axis_near, axis_far;
  double sign_near, sign_far;  // outward normal sign along the axis
};

std::optional<SlabHit> IntersectSlabs(const Eigen::AlignedBox3d& box, const Eigen::Vector3d& o,
                                      const Eigen::Vector3d& d) {
  SlabHit h{-INFINITY, INFINITY, -1, -1, 0.0, 0.0};
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < box.min()[a] || o[a] > box.max()[a]) return std::nullopt;
      continue;
    }
    double t0 = (box.min()[a] - o[a]) / d[a];
    double t1 = (box.max()[a] - o[a]) / d[a];
    double s0 = -1.0, s1 = 1.0;  // entering through min face has outward normal -axis
    if (t0 > t1) std::swap(t0, t1), std::swap(s0, s1);
    if (t0 > h.t_near) h.t_near = t0, h.axis_near = a, h.sign_near = s0;
    if (t1 < h.t_far) h.t_far = t1, h.axis_far = a, h.sign_far = s1;
  }
  if (h.t_near > h.t_far) return std::nullopt;
  return h;
}

void Consider(std::optional<SyntheticScene::Hit>& best, double t, const Eigen::Vector3d& n,
              const Eigen::Vector3f& albedo, double t_min) {
  if (t > t_min && (!best || t < best->t)) best = SyntheticScene::Hit{t, n, albedo};
}

}  // namespace

Eigen::Vector3f SyntheticScene::Box::AlbedoAt(const Eigen::Vector3d& p) const {
  if (!(stripe_period > 0.0)) return albedo;
  const double t = 0.5 + 0.5 * std::sin(2.0 * M_PI * (p.x() + p.z()) / stripe_period);
  return albedo + (albedo2 - albedo) * static_cast<float>(t);
}

float SyntheticScene::TextureAt(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const {
  if (!(texture_tile > 0.0)) return 1.0f;
  // Tiles in the surface's plane: the coordinate along the normal is taken out, so that a wall
  // lying on a tile boundary does not flip between two tiles with its rounding.
  const Eigen::Vector3d q = p - n * n.dot(p);
  auto tile = [&](double size, uint64_t stream) {
    const Eigen::Vector3d c = (q / size).array().floor();
    uint64_t h = Mix64(texture_seed ^ stream);
    for (int i = 0; i < 3; ++i) h = Mix64(h ^ static_cast<uint64_t>(static_cast<int64_t>(c[i])));
    return static_cast<float>(h >> 40) * (1.0f / 16777216.0f);
  };
  return (0.15f + 0.85f * tile(texture_tile, 1)) * (0.6f + 0.4f * tile(texture_tile / 3.0, 2));
}

std::optional<SyntheticScene::Hit> SyntheticScene::Intersect(const Eigen::Vector3d& o,
                                                             const Eigen::Vector3d& d,
                                                             double t_min) const {
  std::optional<Hit> best;
  if (room) {
    if (auto h = IntersectSlabs(room->bounds, o, d); h && h->axis_far >= 0) {
      // From inside, the exit face is the visible wall; its inward normal is -outward.
      const int wall = 2 * h->axis_far + (h->sign_far > 0 ? 1 : 0);
      if (!(room->open_front && wall == 2)) {
        Eigen::Vector3d n = Eigen::Vector3d::Zero();
        n[h->axis_far] = -h->sign_far;
        Consider(best, h->t_far, n, room->albedo[wall], t_min);
      }
    }
  }
  for (const Box& box : boxes) {
    if (auto h = IntersectSlabs(box.bounds, o, d); h && h->axis_near >= 0) {
      Eigen::Vector3d n = Eigen::Vector3d::Zero();
      n[h->axis_near] = h->sign_near;
      Consider(best, h->t_near, n, box.AlbedoAt(o + h->t_near * d), t_min);
    }
  }
  for (const Sphere& s : spheres) {
    const Eigen::Vector3d oc = o - s.center;
    const double a = d.squaredNorm();
    const double b = oc.dot(d);
    const double c = oc.squaredNorm() - s.radius * s.radius;
    const double disc = b * b - a * c;
    if (disc < 0.0) continue;
    const double root = std::sqrt(disc);
    for (double t : {(-b - root) / a, (-b + root) / a}) {
      if (t > t_min) {
        Consider(best, t, (o + t * d - s.center) / s.radius, s.albedo, t_min);
        break;
      }
    }
  }
  if (best && texture_tile > 0.0) best->albedo *= TextureAt(o + best->t * d, best->normal);
  return best;
}

namespace {

void AddQuad(TriangleMesh& mesh, const std::array<Eigen::Vector3d, 4>& corners,
             const Eigen::Vector3f& albedo) {
  const int base = static_cast<int>(mesh.vertices.size());
  for (const auto& c : corners) mesh.vertices.push_back(c.cast<float>());
  mesh.faces.emplace_back(base, base + 1, base + 2);
  mesh.faces.emplace_back(base, base + 2, base + 3);
  mesh.face_colors.push_back(albedo);
  mesh.face_colors.push_back(albedo);
}

// The face of `box` on `axis` at its min (side = 0) or max (side = 1), counter-clockwise seen
// from direction `outward_sign` along the axis.
std::array<Eigen::Vector3d, 4> BoxFace(const Eigen::AlignedBox3d& box, int axis, int side,
                                       double outward_sign) {
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  const double w = side ? box.max()[axis] : box.min()[axis];
  auto corner = [&](int iu, int iv) {
    Eigen::Vector3d p;
    p[axis] = w;
    p[u] = iu ? box.max()[u] : box.min()[u];
    p[v] = iv ? box.max()[v] : box.min()[v];
    return p;
  };
  // (u, v, axis) is right-handed, so (0,0) (1,0) (1,1) (0,1) is CCW seen from +axis.
  if (outward_sign > 0) return {corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)};
  return {corner(0, 0), corner(0, 1), corner(1, 1), corner(1, 0)};
}

void AddIcosphere(TriangleMesh& mesh, const SyntheticScene::Sphere& s, int subdivisions) {
  const UnitIcosphere unit = MakeUnitIcosphere(subdivisions);
  const int base = static_cast<int>(mesh.vertices.size());
  for (const auto& x : unit.vertices)
    mesh.vertices.push_back((s.center + s.radius * x).cast<float>());
  for (const auto& t : unit.faces) {
    mesh.faces.push_back(t + Eigen::Vector3i::Constant(base));
    mesh.face_colors.push_back(s.albedo);
  }
}

}  // namespace

TriangleMesh SyntheticScene::ToMesh(int sphere_subdivisions) const {
  TriangleMesh mesh;
  if (room) {
    for (int wall = 0; wall < 6; ++wall) {
      if (room->open_front && wall == 2) continue;
      const int axis = wall / 2, side = wall % 2;
      // Seen from inside: the min wall faces +axis, the max wall faces -axis.
      AddQuad(mesh, BoxFace(room->bounds, axis, side, side ? -1.0 : 1.0), room->albedo[wall]);
    }
  }
  for (const Box& box : boxes) {
    for (int face = 0; face < 6; ++face) {
      const int axis = face / 2, side = face % 2;
      AddQuad(mesh, BoxFace(box.bounds, axis, side, side ? 1.0 : -1.0), box.albedo);
    }
  }
  for (const Sphere& s : spheres) AddIcosphere(mesh, s, sphere_subdivisions);
  mesh.ComputeVertexNormals();
  return mesh;
}

SyntheticScene MakeStripedWallScene() {
  SyntheticScene scene;
  SyntheticScene::Box wall;
  wall.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-1.5, 1.0, 0.0), Eigen::Vector3d(1.5, 1.05, 2.0));
  wall.albedo = Eigen::Vector3f(0.1f, 0.3f, 0.8f);
  wall.albedo2 = Eigen::Vector3f(0.9f, 0.7f, 0.2f);
  wall.stripe_period = 0.5;
  SyntheticScene::Box occluder;
  occluder.bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.3, 0.4, 0.6), Eigen::Vector3d(0.3, 0.6, 1.4));
  occluder.albedo = Eigen::Vector3f(0.9f, 0.05f, 0.05f);
  scene.boxes = {wall, occluder};
  scene.ambient = 1.0;
  return scene;
}

SyntheticScene MakeCornellScene() {
  SyntheticScene scene;
  const Eigen::Vector3f white(0.73f, 0.73f, 0.73f), red(0.63f, 0.065f, 0.05f),
      green(0.14f, 0.45f, 0.091f);
  SyntheticScene::Room room;
  room.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, 0), Eigen::Vector3d(1, 1, 2));
  room.albedo = {red, green, white, white, white, white};
  scene.room = room;
  scene.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(0.1, 0.0, 0.0), Eigen::Vector3d(0.6, 0.5, 1.0)), white});
  scene.spheres.push_back(
      {Eigen::Vector3d(-0.4, -0.2, 0.35), 0.35, Eigen::Vector3f(0.8f, 0.75f, 0.3f)});
  scene.light_position = Eigen::Vector3d(0.0, 0.0, 1.9);
  return scene;
}

SyntheticScene MakeLivingRoomScene() {
  SyntheticScene room;
  const Eigen::Vector3f wall(0.78f, 0.76f, 0.72f), floor(0.35f, 0.3f, 0.27f),
      wood(0.45f, 0.3f, 0.18f);
  room.room = SyntheticScene::Room{};
  room.room->bounds =
      Eigen::AlignedBox3d(Eigen::Vector3d(-2.5, -2.0, 0.0), Eigen::Vector3d(2.5, 2.0, 2.6));
  room.room->albedo = {wall,  Eigen::Vector3f(0.55f, 0.65f, 0.75f), wall, wall,
                       floor, Eigen::Vector3f::Constant(0.85f)};
  // Table: top and four legs.
  room.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(-0.6, -0.4, 0.72), Eigen::Vector3d(0.6, 0.4, 0.76)),
       wood});
  for (double x : {-0.55, 0.5}) {
    for (double y : {-0.35, 0.3}) {
      room.boxes.push_back({Eigen::AlignedBox3d(Eigen::Vector3d(x, y, 0.0),
                                                Eigen::Vector3d(x + 0.05, y + 0.05, 0.72)),
                            wood});
    }
  }
  // Sofa against the +y wall, cabinet against the -x wall.
  const Eigen::Vector3f fabric(0.2f, 0.3f, 0.55f);
  room.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(-1.2, 1.2, 0.0), Eigen::Vector3d(1.2, 2.0, 0.45)),
       fabric});
  room.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(-1.2, 1.7, 0.45), Eigen::Vector3d(1.2, 2.0, 0.9)),
       fabric});
  room.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(-2.5, -1.0, 0.0), Eigen::Vector3d(-2.0, 0.2, 1.0)),
       wood});
  room.spheres.push_back(
      {Eigen::Vector3d(0.9, -1.0, 0.2), 0.2, Eigen::Vector3f(0.8f, 0.2f, 0.15f)});
  room.light_position = Eigen::Vector3d(0.0, 0.0, 2.5);
  room.ambient = 0.35;
  return room;
}

RgbdFrame RenderSyntheticFrame(const SyntheticScene& scene, const CameraIntrinsics& intrinsics,
                               const Eigen::Isometry3d& world_from_camera, double timestamp) {
  intrinsics.Validate("synthetic camera");
  RgbdFrame frame;
  frame.timestamp = timestamp;
  frame.intrinsics = intrinsics;
  frame.world_from_camera = world_from_camera;
  frame.color = ImageRgb(intrinsics.width, intrinsics.height, Eigen::Vector3f::Zero());
  frame.depth = ImageDepth(intrinsics.width, intrinsics.height, 0.0f);
  const Eigen::Vector3d origin = world_from_camera.translation();
  for (int v = 0; v < intrinsics.height; ++v) {
    for (int u = 0; u < intrinsics.width; ++u) {
      const Eigen::Vector3d dir_camera = intrinsics.RayDirection(u, v);  // z = 1
      const Eigen::Vector3d dir = world_from_camera.linear() * dir_camera;
      const auto hit = scene.Intersect(origin, dir);
      if (!hit) continue;
      frame.depth(u, v) = static_cast<float>(hit->t);  // t along a z = 1 direction is planar depth
      const Eigen::Vector3d p = origin + hit->t * dir;
      const double cosine = std::max(0.0, hit->normal.dot((scene.light_position - p).normalized()));
      frame.color(u, v) =
          hit->albedo * static_cast<float>(scene.ambient + (1.0 - scene.ambient) * cosine);
    }
  }
  return frame;
}

Eigen::Isometry3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-9) x = Eigen::Vector3d::UnitX();  // looking straight up or down
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);  // image down = world down-ish
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = x;
  pose.linear().col(1) = y;
  pose.linear().col(2) = z;
  pose.translation() = eye;
  return pose;
}

Trajectory MakeOrbitTrajectory(const Eigen::Vector3d& target, double radius, double height,
                               double arc_degrees, int frames) {
  GS_CHECK_GT(frames, 0);
  Trajectory trajectory;
  for (int i = 0; i < frames; ++i) {
    const double s = frames == 1 ? 0.0 : static_cast<double>(i) / (frames - 1) - 0.5;
    const double angle = -M_PI / 2.0 + s * arc_degrees * M_PI / 180.0;  // centred on -y
    const Eigen::Vector3d eye =
        target +
        Eigen::Vector3d(radius * std::cos(angle), radius * std::sin(angle), height - target.z());
    trajectory.Add(i / 30.0, LookAt(eye, target));
  }
  return trajectory;
}

Trajectory MakeHandheldTrajectory(const Eigen::Vector3d& target, double radius, double height,
                                  double arc_degrees, int frames, uint64_t seed) {
  const Trajectory orbit = MakeOrbitTrajectory(target, radius, height, arc_degrees, frames);
  CounterRng rng(seed, 0x5A7E);  // phases of the sway
  double phase[6];
  for (double& p : phase) p = 2.0 * M_PI * rng.UniformDouble();
  const double frequency[6] = {0.7, 1.3, 0.9, 1.1, 0.6, 1.7};  // cycles over the trajectory
  Trajectory out;
  for (int i = 0; i < frames; ++i) {
    const double s = frames == 1 ? 0.0 : static_cast<double>(i) / (frames - 1);
    auto wave = [&](int k) { return std::sin(2.0 * M_PI * frequency[k] * s + phase[k]); };
    const StampedPose& p = orbit.poses()[i];
    const Eigen::Vector3d eye = p.world_from_camera.translation() +
                                0.03 * radius * Eigen::Vector3d(wave(0), wave(1), 0.5 * wave(2));
    const Eigen::Vector3d look =
        target + 0.05 * radius * Eigen::Vector3d(wave(3), wave(4), 0.5 * wave(5));
    out.Add(p.timestamp, LookAt(eye, look));
  }
  return out;
}

Trajectory MakeRoomLoopTrajectory(const Eigen::Vector3d& center, double radius, double height,
                                  double turns, int frames, uint64_t seed) {
  GS_CHECK_GT(frames, 1);
  CounterRng rng(seed, 0x1009);  // phases of the sway
  double phase[5];
  for (double& p : phase) p = 2.0 * M_PI * rng.UniformDouble();
  Trajectory out;
  for (int i = 0; i < frames; ++i) {
    const double s = static_cast<double>(i) / (frames - 1);  // 0 .. 1
    const double angle = 2.0 * M_PI * turns * s;
    // Whole numbers of cycles per turn, so that every turn ends where it began.
    auto wave = [&](int k, double cycles) {
      return std::sin(2.0 * M_PI * cycles * turns * s + phase[k]);
    };
    const Eigen::Vector3d out_dir(std::cos(angle), std::sin(angle), 0.0);
    const Eigen::Vector3d eye = center + radius * out_dir +
                                Eigen::Vector3d(0.05 * wave(0, 3.0), 0.05 * wave(1, 2.0),
                                                height - center.z() + 0.05 * wave(2, 4.0));
    const double down = (25.0 + 5.0 * wave(3, 3.0)) * M_PI / 180.0;
    const double yaw = angle + 0.2 * wave(4, 2.0);
    const Eigen::Vector3d look(std::cos(yaw) * std::cos(down), std::sin(yaw) * std::cos(down),
                               -std::sin(down));
    out.Add(i / 30.0, LookAt(eye, eye + look));
  }
  return out;
}

void AddRadialDepthBias(ImageDepth& depth, const CameraIntrinsics& intrinsics, double k) {
  GS_CHECK(depth.SameSize(intrinsics.width, intrinsics.height));
  for (int v = 0; v < depth.height(); ++v) {
    for (int u = 0; u < depth.width(); ++u) {
      const double x = (u - intrinsics.cx) / intrinsics.cx, y = (v - intrinsics.cy) / intrinsics.cx;
      depth(u, v) *= static_cast<float>(1.0 + k * (x * x + y * y));
    }
  }
}

void AddKinectDepthNoise(ImageDepth& depth, uint64_t seed, uint64_t frame_index) {
  constexpr double kFocalTimesBaseline = 580.0 * 0.075;  // f b, pixel meters
  const ImageDepth clean = depth;
  const int w = depth.width(), h = depth.height();
  ParallelFor(0, depth.size(), [&](size_t i) {
    const float z = clean.pixels()[i];
    if (z <= 0.0f) return;
    CounterRng rng(seed, frame_index, i);
    const int u = static_cast<int>(i % w), v = static_cast<int>(i / w);
    bool edge = false;
    for (const auto& [du, dv] :
         {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
      const int x = u + du, y = v + dv;
      if (x < 0 || y < 0 || x >= w || y >= h) continue;
      const float n = clean(x, y);
      edge |= n <= 0.0f || std::abs(n - z) > 0.05f * z;
    }
    const bool dropped = rng.Uniform() < (edge ? 0.5f : 0.0f);
    const double sigma = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
    const double noisy = z + sigma * rng.Normal();
    if (dropped || noisy <= 0.0) {
      depth.pixels()[i] = 0.0f;
      return;
    }
    const double disparity = std::round(8.0 * kFocalTimesBaseline / noisy) / 8.0;
    depth.pixels()[i] =
        disparity > 0.0 ? static_cast<float>(kFocalTimesBaseline / disparity) : 0.0f;
  });
}

}  // namespace genscene
