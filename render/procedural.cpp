#include "render/procedural.h"

#include <algorithm>

#include "core/synthetic.h"

namespace genscene::render {

namespace {

SceneMesh FromSynthetic(const std::string& name, const SyntheticScene& synthetic) {
  SceneMesh m;
  m.name = name;
  m.mesh = synthetic.ToMesh(4);
  m.albedo = SurfaceAlbedo::FromMesh(m.mesh, Eigen::Vector3f::Constant(0.5f));
  return m;
}

// A horizontal square light of side `side` centred at `center`, facing down.
SceneMesh CeilingLight(const std::string& name, const Eigen::Vector3f& center, float side,
                       const Eigen::Vector3f& radiance) {
  SceneMesh light;
  light.name = name;
  const float h = 0.5f * side;
  for (const auto& [x, y] :
       {std::pair{-h, -h}, std::pair{h, -h}, std::pair{h, h}, std::pair{-h, h}}) {
    light.mesh.vertices.push_back(center + Eigen::Vector3f(x, y, 0.0f));
  }
  light.mesh.faces = {{0, 2, 1}, {0, 3, 2}};  // clockwise seen from above: the front faces down
  light.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Zero());
  light.emission = radiance;
  return light;
}

}  // namespace

SceneMesh MakeQuad(const std::string& name, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                   const Eigen::Vector3f& c, const Eigen::Vector3f& d,
                   const Eigen::Vector3f& albedo) {
  SceneMesh m;
  m.name = name;
  m.mesh.vertices = {a, b, c, d};
  m.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  m.albedo = SurfaceAlbedo::Constant(albedo);
  return m;
}

Scene MakeCornellBoxScene() {
  Scene scene;
  scene.meshes.push_back(FromSynthetic("cornell", MakeCornellScene()));
  scene.meshes.push_back(CeilingLight("light", {0.0f, 0.0f, 1.99f}, 0.5f, {18.0f, 15.0f, 11.0f}));
  return scene;
}

std::vector<PosedView> CornellLightViews(int width, int height) {
  const CameraIntrinsics k = CameraIntrinsics::FromHorizontalFov(width, height, 60.0);
  const std::pair<Eigen::Vector3d, Eigen::Vector3d> eye_target[] = {
      {{0.0, -0.95, 1.0}, {0.0, 0.5, 0.8}},    // training: the whole box from the front
      {{-0.8, -0.9, 1.4}, {0.3, 0.6, 0.5}},    // training: from the left, looking down
      {{0.8, -0.9, 0.6}, {-0.3, 0.5, 1.1}},    // training: from the right, looking up
      {{0.85, 0.85, 1.3}, {-0.5, -0.5, 0.6}},  // novel: from the back corner
      {{-0.9, 0.2, 0.5}, {0.8, -0.2, 1.2}},    // novel: from the red wall towards the green one
  };
  std::vector<PosedView> views;
  for (const auto& [eye, target] : eye_target) views.push_back({k, LookAt(eye, target)});
  return views;
}

IcosphereBox MakeIcosphereBox(bool smooth_shading) {
  IcosphereBox box;
  const Eigen::Vector3f white(0.725f, 0.71f, 0.68f), red(0.63f, 0.065f, 0.05f),
      green(0.14f, 0.45f, 0.091f);
  // Quad with corners a, b, c, d counter-clockwise seen from the inside of the box.
  const auto wall = [&](const std::string& name, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                        const Eigen::Vector3f& c, const Eigen::Vector3f& d,
                        const Eigen::Vector3f& albedo) {
    box.scene.meshes.push_back(MakeQuad(name, a, b, c, d, albedo));
  };
  const float h = 0.5f;
  wall("floor", {-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}, white);
  wall("ceiling", {-h, -h, 1}, {-h, h, 1}, {h, h, 1}, {h, -h, 1}, white);
  wall("back", {-h, h, 0}, {h, h, 0}, {h, h, 1}, {-h, h, 1}, white);
  wall("red", {-h, -h, 0}, {-h, h, 0}, {-h, h, 1}, {-h, -h, 1}, red);
  wall("green", {h, -h, 0}, {h, -h, 1}, {h, h, 1}, {h, h, 0}, green);
  box.scene.meshes.push_back(
      CeilingLight("light", {0.0f, 0.0f, 0.998f}, 0.25f, {30.0f, 24.0f, 18.0f}));

  SceneMesh sphere;
  sphere.name = "icosphere";
  const UnitIcosphere unit = MakeUnitIcosphere(1);
  for (const Eigen::Vector3d& v : unit.vertices)
    sphere.mesh.vertices.push_back((box.center + box.radius * v).cast<float>());
  sphere.mesh.faces = unit.faces;
  sphere.mesh.ComputeVertexNormals();
  sphere.smooth_shading = smooth_shading;
  sphere.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Constant(0.8f));
  box.sphere = static_cast<int>(box.scene.meshes.size());
  box.scene.meshes.push_back(sphere);

  // icosphere_flat/intrinsics.txt and pose.txt (world_from_camera, OpenCV camera frame).
  box.view.intrinsics = CameraIntrinsics{150.0, 150.0, 52.5, 39.5, 106, 80};
  const Eigen::Quaterniond q(0.596890437, -0.802001294, -0.018217897, 0.013558692);  // w, x, y, z
  box.view.world_from_camera = Eigen::Isometry3d::Identity();
  box.view.world_from_camera.linear() = q.normalized().toRotationMatrix();
  box.view.world_from_camera.translation() = Eigen::Vector3d(0.05, -1.1, 0.55);
  return box;
}

SpikeAndDent PerturbFacingVertices(const TriangleMesh& mesh, const Eigen::Vector3d& center,
                                   double radius, const Eigen::Vector3d& eye, double size) {
  SpikeAndDent out;
  out.positions.resize(3 * mesh.vertices.size());
  std::vector<std::pair<double, int>> facing;  // (-cos of the angle to the eye, vertex)
  for (size_t v = 0; v < mesh.vertices.size(); ++v) {
    const Eigen::Vector3d p = mesh.vertices[v].cast<double>();
    out.positions.segment<3>(3 * v) = p;
    facing.push_back({-(p - center).normalized().dot((eye - p).normalized()), static_cast<int>(v)});
  }
  std::sort(facing.begin(), facing.end());
  out.spike = facing.at(0).second;
  out.dent = facing.at(1).second;
  for (const auto& [score, v] : facing) {
    if ((mesh.vertices[v] - mesh.vertices[out.spike]).norm() > 0.75 * radius) {
      out.dent = v;
      break;
    }
  }
  const auto outwards = [&](int v) {
    return Eigen::Vector3d((out.positions.segment<3>(3 * v) - center).normalized());
  };
  out.positions.segment<3>(3 * out.spike) += size * outwards(out.spike);
  out.positions.segment<3>(3 * out.dent) -= size * outwards(out.dent);
  return out;
}

Scene MakeRoomScene() {
  const SyntheticScene room = MakeLivingRoomScene();
  Scene scene;
  scene.meshes.push_back(FromSynthetic("room", room));
  scene.meshes.push_back(
      CeilingLight("ceiling_panel", {0.0f, 0.0f, 2.58f}, 0.8f, {9.0f, 9.0f, 8.5f}));
  scene.meshes.push_back(CeilingLight("lamp", {-2.25f, -0.4f, 1.3f}, 0.15f, {40.0f, 28.0f, 14.0f}));
  // The lamp shade faces down onto the cabinet; a small upward panel lights the ceiling above it.
  SceneMesh up = CeilingLight("lamp_up", {-2.25f, -0.4f, 1.31f}, 0.15f, {20.0f, 14.0f, 7.0f});
  up.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  scene.meshes.push_back(up);
  return scene;
}

}  // namespace genscene::render
