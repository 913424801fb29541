// Mitsuba 3 XML export (ExportMitsubaXml in render/formats/mitsuba_xml.h) and the import of what it
// writes: one shape per mesh with its albedo as PLY colours read through a mesh_attribute texture,
// cameras with fx != fy and off-centre principal points, voxel-light cubes hidden from the camera;
// the exported scene rendered by our path tracer against the original.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>

#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"
#include "core/image_io.h"
#include "core/mesh_colors.h"
#include "core/view_set.h"
#include "render/formats/mitsuba_xml.h"
#include "render/formats/scene_io.h"
#include "render/path_tracer.h"
#include "tests/test_util.h"

namespace genscene::render {
namespace {

using test::ErrorOf;
using test::WriteFile;

namespace fs = std::filesystem;
using Eigen::Vector3d;
using Eigen::Vector3f;

Vector3f UnitFaceNormal(const TriangleMesh& mesh, size_t f) {
  return mesh.FaceNormalScaled(f).normalized();
}

// Intrinsics within `relative`, poses within `absolute` in every matrix entry.
void ExpectSameViews(const std::vector<PosedView>& a, const std::vector<PosedView>& b,
                     double relative, double absolute) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(i);
    const CameraIntrinsics &p = a[i].intrinsics, &q = b[i].intrinsics;
    for (const auto& [x, y] : {std::pair{p.fx, q.fx}, {p.fy, q.fy}, {p.cx, q.cx}, {p.cy, q.cy}})
      EXPECT_NEAR(x, y, relative * std::abs(x));
    EXPECT_EQ(p.width, q.width);
    EXPECT_EQ(p.height, q.height);
    EXPECT_LT(
        (a[i].world_from_camera.matrix() - b[i].world_from_camera.matrix()).cwiseAbs().maxCoeff(),
        absolute);
  }
}

// The albedo of mesh `m` at point p of its surface (on the face nearest p, clamped into it).
Vector3f AlbedoAt(const SceneMesh& m, const Vector3f& p) {
  float best = INFINITY, b1 = 0, b2 = 0;
  int face = 0;
  for (size_t f = 0; f < m.mesh.faces.size(); ++f) {
    const Eigen::Vector3i& t = m.mesh.faces[f];
    const Vector3f a = m.mesh.vertices[t[0]], e1 = m.mesh.vertices[t[1]] - a,
                   e2 = m.mesh.vertices[t[2]] - a;
    Eigen::Matrix<float, 3, 2> basis;
    basis << e1, e2;
    const Eigen::Vector2f b = basis.colPivHouseholderQr().solve(p - a);
    const float outside = std::max({0.0f, -b.x(), -b.y(), b.x() + b.y() - 1.0f});
    const float miss = (a + basis * b - p).norm() + outside * e1.norm();
    if (miss < best) best = miss, face = static_cast<int>(f), b1 = b.x(), b2 = b.y();
  }
  return m.albedo.Eval(m.mesh, face, b1, b2);
}

// The albedo of `b` (the import of `a`) at random points of every face of `a`.
void ExpectSameAlbedo(const SceneMesh& a, const SceneMesh& b, float tolerance) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (size_t f = 0; f < a.mesh.faces.size(); ++f) {
    for (int n = 0; n < 20; ++n) {
      float b1 = u(rng), b2 = u(rng);
      if (b1 + b2 > 1.0f) b1 = 1.0f - b1, b2 = 1.0f - b2;
      const Eigen::Vector3i& t = a.mesh.faces[f];
      const Vector3f p = (1.0f - b1 - b2) * a.mesh.vertices[t[0]] + b1 * a.mesh.vertices[t[1]] +
                         b2 * a.mesh.vertices[t[2]];
      const Vector3f want = a.albedo.Eval(a.mesh, static_cast<int>(f), b1, b2);
      EXPECT_LT((AlbedoAt(b, p) - want).cwiseAbs().maxCoeff(), tolerance)
          << a.name << " face " << f << " at (" << b1 << ", " << b2 << ")";
    }
  }
}

// A quad c, c + u, c + u + v, c + v (two triangles, front towards u x v).
SceneMesh Quad(const std::string& name, const Vector3f& c, const Vector3f& u, const Vector3f& v) {
  SceneMesh m;
  m.name = name;
  m.mesh.vertices = {c, c + u, c + u + v, c + v};
  m.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  m.albedo = SurfaceAlbedo::Constant(Vector3f(0.6f, 0.6f, 0.6f));
  return m;
}

// A Mesh Colors field of resolution 4 on each face, random colours in [0.1, 0.9].
SurfaceAlbedo RandomMeshColors(const TriangleMesh& mesh, int seed) {
  MeshColors colors(mesh, std::vector<int>(mesh.faces.size(), 4));
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::uniform_real_distribution<float> u(0.1f, 0.9f);
  for (Vector3f& c : colors.colors()) c = Vector3f(u(rng), u(rng), u(rng));
  return SurfaceAlbedo::FromMeshColors(std::move(colors));
}

// The box [-1, 1]^3 seen from inside: a floor with per-vertex albedo, a smooth wall with a Mesh
// Colors field, a wall with per-face albedo, constant walls; two voxel lights of 2 cm cubes.
Scene Room() {
  Scene scene;
  SceneMesh floor = Quad("floor", {-1, -1, -1}, {2, 0, 0}, {0, 2, 0});
  floor.albedo.kind = SurfaceAlbedo::Kind::kPerVertex;
  floor.albedo.values = {
      {0.8f, 0.2f, 0.2f}, {0.2f, 0.8f, 0.2f}, {0.2f, 0.2f, 0.8f}, {0.7f, 0.7f, 0.1f}};
  scene.meshes.push_back(floor);
  SceneMesh field = Quad("field wall", {-1, 1, -1}, {2, 0, 0}, {0, 0, 2});
  field.mesh.normals.assign(4, Vector3f(0, -1, 0));
  field.smooth_shading = true;
  field.albedo = RandomMeshColors(field.mesh, 3);
  scene.meshes.push_back(field);
  SceneMesh faces = Quad("per-face wall", {1, -1, -1}, {0, 0, 2}, {0, 2, 0});
  faces.albedo.kind = SurfaceAlbedo::Kind::kPerFace;
  faces.albedo.values = {{0.3f, 0.5f, 0.7f}, {0.7f, 0.5f, 0.3f}};
  scene.meshes.push_back(faces);
  scene.meshes.push_back(Quad("ceiling", {-1, -1, 1}, {0, 2, 0}, {2, 0, 0}));
  scene.meshes.push_back(Quad("left", {-1, -1, -1}, {0, 2, 0}, {0, 0, 2}));
  scene.meshes.push_back(Quad("back", {-1, -1, -1}, {0, 0, 2}, {2, 0, 0}));
  // The lights stay 0.55 m from the walls: PathTracer's shadow rays to an area light within about
  // 0.4 m of a surface (along its normal) end on the light itself and miss it (render/
  // path_tracer.cpp measures their length from the surface point, not from the offset origin).
  VoxelLightGrid grid;
  grid.bounds = Eigen::AlignedBox3d(Vector3d(-0.6, -0.6, -0.6), Vector3d(0.6, 0.6, 0.6));
  grid.dims = Eigen::Vector3i(4, 4, 4);
  grid.intensity.assign(64, Vector3f::Zero());
  grid.weights.assign(64, {1, 1, 1, 1, 1, 1});
  grid.intensity[1 + 4 * 2 + 16 * 3] = Vector3f(3.0f, 2.5f, 2.0f);  // (-0.15, 0.15, 0.45)
  grid.intensity[0 + 4 * 1 + 16 * 1] = Vector3f(1.0f, 1.0f, 1.5f);  // (-0.45, -0.15, -0.15)
  grid.weights[0 + 4 * 1 + 16 * 1] = {1, 0.2f, 0.5f, 0.5f, 1, 0};
  grid.cube_size = 0.02;
  scene.voxel_lights = grid;
  return scene;
}

// A camera in the room with fx != fy (within what Mitsuba expresses) and the principal point off
// centre, looking at the field wall.
PosedView RoomView() {
  PosedView view;
  view.intrinsics = {40.0, 40.03, 30.3, 25.6, 64, 48, {}};
  Eigen::Matrix3d r;
  r.col(0) = Vector3d(1, 0, 0);   // image right: world +x
  r.col(1) = Vector3d(0, 0, -1);  // image down: world -z
  r.col(2) = Vector3d(0, 1, 0);   // forward: world +y
  view.world_from_camera.linear() =
      Eigen::AngleAxisd(0.25, Vector3d(0.3, 0.2, 1).normalized()).toRotationMatrix() * r;
  view.world_from_camera.translation() = Vector3d(0.1, -0.7, -0.2);
  return view;
}

// Mean radiance over the image and over its four quadrants.
std::vector<Vector3d> Means(const ImageRgb& image) {
  std::vector<Vector3d> sums(5, Vector3d::Zero());
  std::vector<int> counts(5, 0);
  for (int v = 0; v < image.height(); ++v) {
    for (int u = 0; u < image.width(); ++u) {
      const int q = 1 + (2 * u >= image.width()) + 2 * (2 * v >= image.height());
      for (int k : {0, q}) sums[k] += image(u, v).cast<double>(), ++counts[k];
    }
  }
  for (size_t k = 0; k < 5; ++k) sums[k] /= counts[k];
  return sums;
}

// Renders `view` of both scenes (the import with its own render settings, as genscene-render
// applies them) and compares the mean radiance: over the image within `tolerance` relative per
// channel, over each quadrant within 3 tolerance. Returns the largest relative difference.
double CompareRenders(const Scene& original, const LoadedScene& imported, const PosedView& view,
                      const PosedView& imported_view, double tolerance) {
  RenderOptions options;
  options.spp = 64;
  RenderOptions imported_options = options;
  imported_options.hide_emitters = imported.settings.hide_emitters.value_or(false);
  imported_options.max_depth = imported.settings.max_depth.value_or(-1);
  const ImageRgb a = PathTracer(original).Render(view, options, 11).radiance;
  const ImageRgb b =
      PathTracer(imported.scene).Render(imported_view, imported_options, 11).radiance;
  const std::vector<Vector3d> ma = Means(a), mb = Means(b);
  double worst = 0.0;
  for (size_t k = 0; k < ma.size(); ++k) {
    const Vector3d relative = (mb[k] - ma[k]).cwiseQuotient(ma[k]).cwiseAbs();
    EXPECT_LT(relative.maxCoeff(), k == 0 ? tolerance : 3 * tolerance)
        << (k == 0 ? "image" : "quadrant " + std::to_string(k)) << ": original "
        << ma[k].transpose() << ", exported " << mb[k].transpose();
    if (k == 0) worst = relative.maxCoeff();
  }
  std::printf("mean radiance: original (%.5f %.5f %.5f), exported (%.5f %.5f %.5f): %.3f %%\n",
              ma[0].x(), ma[0].y(), ma[0].z(), mb[0].x(), mb[0].y(), mb[0].z(), 100 * worst);
  return worst;
}

// ------------------------------------------------------------------------------------------------
// Export -> import round trips.

// A flat emitting lamp with constant albedo, a smooth wall with per-face albedo, a point light
// and voxel lights.
Scene LampAndWall() {
  Scene scene;
  SceneMesh lamp;
  lamp.name = "lamp";
  lamp.mesh.vertices = {{0, 0, 2}, {0, 1, 2}, {1, 1, 2}, {1, 0, 2}};
  lamp.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  lamp.albedo = SurfaceAlbedo::Constant(Vector3f(0.1f, 0.2f, 0.3f));
  lamp.emission = Vector3f(5.5f, 4.25f, 0.125f);
  scene.meshes.push_back(lamp);
  SceneMesh wall;
  wall.name = "wall";
  wall.mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0.1f}, {0, 1, 0}, {2, 0.5f, 0}};
  wall.mesh.faces = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
  wall.mesh.ComputeVertexNormals();
  wall.smooth_shading = true;
  wall.albedo.kind = SurfaceAlbedo::Kind::kPerFace;
  wall.albedo.values = {{0.7f, 0.6f, 0.5f}, {0.2f, 0.3f, 0.4f}, {0.7f, 0.6f, 0.5f}};
  scene.meshes.push_back(wall);
  scene.point_lights.push_back({Vector3d(0.1, 0.2, 1.0 / 3.0), Vector3f(7, 8, 9)});
  VoxelLightGrid grid;
  grid.bounds = Eigen::AlignedBox3d(Vector3d(-1, -1, 0), Vector3d(1, 1, 2));
  grid.dims = Eigen::Vector3i(2, 1, 1);
  grid.intensity = {Vector3f(1, 2, 3), Vector3f::Zero()};
  grid.weights = {{1, 0, 0.5f, 0, 0, 2}, {1, 1, 1, 1, 1, 1}};
  scene.voxel_lights = grid;
  return scene;
}

TEST(MitsubaXmlExport, RoundTripKeepsGeometryAlbedoEmissionLightsAndViews) {
  test::TempDir dir;
  const Scene scene = LampAndWall();
  const SceneMesh &lamp = scene.meshes[0], &wall = scene.meshes[1];
  std::vector<PosedView> views(3);
  views[0].intrinsics = {300, 300, 150.25, 99.75, 320, 200, {}};
  views[0].world_from_camera =
      Eigen::Translation3d(1, -2, 0.5) * Eigen::AngleAxisd(0.3, Vector3d(1, 2, 3).normalized());
  views[1].intrinsics = {500, 500, 63.5, 47.5, 128, 96, {}};
  views[1].world_from_camera =
      Eigen::Translation3d(0, 0, 4) * Eigen::AngleAxisd(M_PI, Vector3d::UnitX());
  views[2].intrinsics = {517.3, 516.9, 318.6, 255.3, 640, 480, {}};  // fx != fy
  views[2].world_from_camera =
      Eigen::Translation3d(0.5, 1, 2) * Eigen::AngleAxisd(2.0, Vector3d(-1, 3, 1).normalized());
  RenderSettings settings;
  settings.integrator = "path";
  settings.max_depth = 5;
  settings.samples_per_pixel = 64;
  settings.pixel_filter = PixelFilter{PixelFilter::Kind::kGaussian, 0.4};
  settings.near_clip = 0.05;
  settings.far_clip = 100.0;

  // The lamp keeps the cubes visible (hide_emitters would hide it too): the one warning.
  const std::vector<std::string> warnings =
      ExportMitsubaXml(dir / "out.xml", scene, views, settings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_CONTAINS(warnings[0], "visible to the camera");
  const LoadedScene back = ImportMitsubaXml(dir / "out.xml");
  EXPECT_TRUE(back.warnings.empty());
  const std::vector<SceneMesh> cube_faces = VoxelCubeFaces(*scene.voxel_lights);
  ASSERT_EQ(back.scene.meshes.size(), 2 + cube_faces.size());
  const SceneMesh& lamp_back = back.scene.meshes[0];
  EXPECT_EQ(lamp_back.name, "lamp");
  EXPECT_EQ(lamp_back.mesh.vertices, lamp.mesh.vertices);
  EXPECT_EQ(lamp_back.mesh.faces, lamp.mesh.faces);
  EXPECT_FALSE(lamp_back.smooth_shading);
  EXPECT_EQ(lamp_back.albedo.kind, SurfaceAlbedo::Kind::kConstant);
  EXPECT_EQ(lamp_back.albedo.constant, lamp.albedo.constant);
  EXPECT_EQ(lamp_back.emission, lamp.emission);
  // The wall: one shape, its albedo per face exactly.
  const SceneMesh& wall_back = back.scene.meshes[1];
  EXPECT_EQ(wall_back.name, "wall");
  EXPECT_TRUE(wall_back.smooth_shading);
  EXPECT_EQ(wall_back.mesh.vertices, wall.mesh.vertices);
  EXPECT_EQ(wall_back.mesh.faces, wall.mesh.faces);
  for (size_t v = 0; v < wall.mesh.normals.size(); ++v)
    EXPECT_TRUE(wall_back.mesh.normals[v].isApprox(wall.mesh.normals[v], 1e-6f));
  EXPECT_EQ(wall_back.albedo.kind, SurfaceAlbedo::Kind::kPerFace);
  EXPECT_EQ(wall_back.albedo.values, wall.albedo.values);
  // Voxel lights come back as emissive quads equal to VoxelCubeFaces().
  for (size_t i = 0; i < cube_faces.size(); ++i) {
    const SceneMesh& q = back.scene.meshes[2 + i];
    EXPECT_EQ(q.emission, cube_faces[i].emission);
    EXPECT_EQ(q.albedo.constant, Vector3f::Zero());
    EXPECT_TRUE(UnitFaceNormal(q.mesh, 0).isApprox(UnitFaceNormal(cube_faces[i].mesh, 0), 1e-6f));
    for (int k = 0; k < 4; ++k)
      EXPECT_LT((q.mesh.vertices[k] - cube_faces[i].mesh.vertices[k]).norm(), 1e-6f);
  }
  EXPECT_EQ(back.scene.point_lights[0].position, scene.point_lights[0].position);
  EXPECT_EQ(back.scene.point_lights[0].intensity, scene.point_lights[0].intensity);
  ExpectSameViews(views, back.views, 1e-12, 1e-12);
  EXPECT_EQ(back.views[0].intrinsics.fx, back.views[0].intrinsics.fy);  // square stays square
  EXPECT_EQ(back.settings.integrator, settings.integrator);
  EXPECT_EQ(back.settings.max_depth, settings.max_depth);
  EXPECT_EQ(back.settings.samples_per_pixel, settings.samples_per_pixel);
  EXPECT_EQ(back.settings.pixel_filter->stddev, 0.4);
  EXPECT_EQ(back.settings.near_clip, settings.near_clip);
  EXPECT_EQ(back.settings.far_clip, settings.far_clip);
  EXPECT_FALSE(back.settings.hide_emitters.value_or(false));
}

TEST(MitsubaXmlExport, DataSceneSurvivesExportAndImport) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  const LoadedScene a = LoadScene(data / "mitsuba/cbox-rgb/cbox-rgb.xml");
  EXPECT_TRUE(ExportMitsubaXml(dir / "cbox.xml", a.scene, a.views, a.settings).empty());
  const LoadedScene b = ImportMitsubaXml(dir / "cbox.xml");
  ASSERT_EQ(b.scene.meshes.size(), a.scene.meshes.size());
  for (size_t i = 0; i < a.scene.meshes.size(); ++i) {
    EXPECT_EQ(b.scene.meshes[i].name, a.scene.meshes[i].name);
    EXPECT_EQ(b.scene.meshes[i].mesh.vertices, a.scene.meshes[i].mesh.vertices);
    EXPECT_EQ(b.scene.meshes[i].mesh.faces, a.scene.meshes[i].mesh.faces);
    EXPECT_EQ(b.scene.meshes[i].mesh.normals, a.scene.meshes[i].mesh.normals);
    EXPECT_EQ(b.scene.meshes[i].smooth_shading, a.scene.meshes[i].smooth_shading);
    EXPECT_EQ(b.scene.meshes[i].albedo.constant, a.scene.meshes[i].albedo.constant);
    EXPECT_EQ(b.scene.meshes[i].emission, a.scene.meshes[i].emission);
  }
  ExpectSameViews(a.views, b.views, 1e-9, 1e-9 * 800);
  EXPECT_EQ(b.settings.samples_per_pixel, 256);
  EXPECT_EQ(b.settings.max_depth, 6);
  EXPECT_EQ(b.settings.near_clip, 10.0);
  EXPECT_EQ(b.settings.pixel_filter->kind, PixelFilter::Kind::kBox);
}

TEST(MitsubaXmlExport, AlbedoOfEveryKindComesBackInOneShapeEach) {
  test::TempDir dir;
  const Scene scene = Room();
  const std::vector<std::string> warnings = ExportMitsubaXml(dir / "room.xml", scene, {});
  EXPECT_TRUE(warnings.empty()) << warnings[0];
  const std::string xml = ReadTextFile(dir / "room.xml");
  EXPECT_CONTAINS(xml, "<string name=\"name\" value=\"vertex_color\"/>");
  EXPECT_CONTAINS(xml, "<string name=\"name\" value=\"face_color\"/>");
  const LoadedScene back = ImportMitsubaXml(dir / "room.xml");
  EXPECT_TRUE(back.warnings.empty());
  ASSERT_EQ(back.scene.meshes.size(),
            scene.meshes.size() + VoxelCubeFaces(*scene.voxel_lights).size());
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    SCOPED_TRACE(scene.meshes[i].name);
    const SceneMesh& a = scene.meshes[i];
    const SceneMesh& b = back.scene.meshes[i];
    EXPECT_EQ(b.smooth_shading, a.smooth_shading);
    const SurfaceAlbedo::Kind kind = a.albedo.kind == SurfaceAlbedo::Kind::kField
                                         ? SurfaceAlbedo::Kind::kPerVertex
                                         : a.albedo.kind;
    EXPECT_EQ(b.albedo.kind, kind);
    if (a.albedo.kind != SurfaceAlbedo::Kind::kField) {
      EXPECT_EQ(b.albedo.values, a.albedo.values);
    }
    ExpectSameAlbedo(a, b, 1e-5f);
  }
  // The field wall (resolution 4 on both faces): 16 triangles per face; its smooth normals stay.
  EXPECT_EQ(back.scene.meshes[1].mesh.faces.size(), 32u);
  for (const Vector3f& n : back.scene.meshes[1].mesh.normals) EXPECT_EQ(n, Vector3f(0, -1, 0));
  EXPECT_EQ(back.settings.integrator, "path");  // written for hide_emitters
  EXPECT_EQ(back.settings.hide_emitters, true);
}

// A field that is not piecewise linear: the bake stops at resolution 256, some 3e-3 off.
class Waves : public AlbedoField {
 public:
  Vector3f Eval(int, float b1, float b2) const override {
    return Vector3f::Constant(0.5f + 0.3f * std::sin(70.0f * b1 + 13.0f * b2 + 0.3f));
  }
};

TEST(MitsubaXmlExport, ApproximationsWarnAndDistortionFails) {
  test::TempDir dir;
  Scene scene;
  SceneMesh m = Quad("waves", {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  m.mesh.faces.pop_back();
  m.albedo.kind = SurfaceAlbedo::Kind::kField;
  m.albedo.field = std::make_shared<Waves>();
  scene.meshes.push_back(m);
  PosedView view;
  view.intrinsics = {535.4, 539.2, 320.1, 247.6, 640, 480, {}};  // TUM fr3: 0.7 % anisotropic
  std::vector<std::string> warnings = ExportMitsubaXml(dir / "a.xml", scene, {view});
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_CONTAINS(warnings[0], "fx / fy = 0.99295");
  EXPECT_CONTAINS(warnings[0], "px");
  EXPECT_CONTAINS(warnings[1], "mesh 'waves': albedo field baked into 65536 triangles");
  const LoadedScene back = ImportMitsubaXml(dir / "a.xml");
  const CameraIntrinsics& k = back.views[0].intrinsics;
  EXPECT_NEAR(k.fx * k.fy, 535.4 * 539.2, 1e-6);  // the same sqrt(fx fy), as anisotropic as
  EXPECT_NEAR(k.fy / k.fx, std::sqrt(1.00099 / 0.99901), 1e-5);  // Mitsuba takes
  EXPECT_EQ(k.cx, 320.1);
  view.intrinsics.distortion[0] = 0.1;
  EXPECT_CONTAINS(ErrorOf([&] { ExportMitsubaXml(dir / "b.xml", scene, {view}); }), "distortion");
  EXPECT_FALSE(fs::exists(dir / "b.xml"));
}

// ------------------------------------------------------------------------------------------------
// Renders of the export against renders of the original (acceptance of the export).

TEST(MitsubaXmlExport, ExportedRoomRendersLikeTheOriginal) {
  test::TempDir dir;
  const Scene scene = Room();
  const PosedView view = RoomView();
  EXPECT_TRUE(ExportMitsubaXml(dir / "room.xml", scene, {view}).empty());
  const LoadedScene back = ImportMitsubaXml(dir / "room.xml");
  ASSERT_EQ(back.views.size(), 1u);
  ExpectSameViews({view}, back.views, 1e-12, 1e-12);
  EXPECT_EQ(back.settings.hide_emitters, true);
  CompareRenders(scene, back, view, back.views[0], 0.01);
}

// The room without its ceiling under a distant light (an envmap beside the XML): the import fits
// the same six lobes back and the renders agree.
TEST(MitsubaXmlExport, TheDistantLightGoesOutAsAnEnvmapAndComesBack) {
  test::TempDir dir;
  Scene scene = Room();
  scene.meshes.erase(std::remove_if(scene.meshes.begin(), scene.meshes.end(),
                                    [](const SceneMesh& m) { return m.name == "ceiling"; }),
                     scene.meshes.end());
  VoxelLightGrid& grid = *scene.voxel_lights;
  grid.distant = true;
  grid.distant_intensity = Vector3f(2.0f, 1.8f, 1.2f);
  grid.distant_weights = {0.2f, 0.0f, 0.1f, 0.3f, 1.0f, 0.05f};
  const PosedView view = RoomView();
  EXPECT_TRUE(ExportMitsubaXml(dir / "room.xml", scene, {view}).empty());
  ASSERT_TRUE(fs::exists(dir / "room_distant.exr"));
  EXPECT_CONTAINS(ReadTextFile(dir / "room.xml"), "<emitter type=\"envmap\">");
  const LoadedScene back = ImportMitsubaXml(dir / "room.xml");
  EXPECT_TRUE(back.warnings.empty()) << back.warnings.front();
  ASSERT_TRUE(back.scene.voxel_lights && back.scene.voxel_lights->distant);
  const VoxelLightGrid& read = *back.scene.voxel_lights;
  EXPECT_LT((read.distant_intensity - grid.distant_intensity).norm(), 1e-4f)
      << read.distant_intensity.transpose();
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(read.distant_weights[k], grid.distant_weights[k], 1e-5f);
  CompareRenders(scene, back, view, back.views[0], 0.02);

  // An envmap that is not six lobes (one bright texel) is approximated, with a warning.
  ImageRgb spot(16, 8, Vector3f::Zero());
  spot(3, 2) = Vector3f(50.0f, 50.0f, 50.0f);
  WriteExr(dir / "spot.exr", spot);
  std::ofstream(dir / "spot.xml") << R"(<scene version="3.0.0">
  <emitter type="envmap"><string name="filename" value="spot.exr"/></emitter>
  <shape type="rectangle"/>
</scene>)";
  const LoadedScene approximated = ImportMitsubaXml(dir / "spot.xml");
  ASSERT_EQ(approximated.warnings.size(), 1u);
  EXPECT_CONTAINS(approximated.warnings[0], "approximated by six directional lobes");
  ASSERT_TRUE(approximated.scene.voxel_lights);
  EXPECT_TRUE(approximated.scene.voxel_lights->HasDistantLight());
  std::ofstream(dir / "bad.xml") << R"(<scene version="3.0.0">
  <emitter type="envmap"/>
</scene>)";
  EXPECT_CONTAINS(test::ErrorOf([&] { ImportMitsubaXml(dir / "bad.xml"); }),
                  "missing property 'filename'");
}

TEST(MitsubaXmlExport, CyclesBoxRendersLikeTheOriginal) {
  GS_REQUIRE_SHARED_DATA(data);
  test::TempDir dir;
  const Scene scene = LoadCyclesScene(data / "cbox-cycles");
  std::vector<PosedView> views = ReadViewSet(data / "cbox-cycles/views/novel");
  ASSERT_FALSE(views.empty());
  views.resize(1);
  views[0].intrinsics.fy *= 1.0008;  // non-square pixels, principal point off centre
  views[0].intrinsics.cx += 3.3;
  views[0].intrinsics.cy -= 2.1;
  EXPECT_TRUE(ExportMitsubaXml(dir / "cbox.xml", scene, views).empty());
  const LoadedScene back = ImportMitsubaXml(dir / "cbox.xml");
  ASSERT_EQ(back.scene.meshes.size(), scene.meshes.size());  // one shape per object
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    const SurfaceAlbedo &a = scene.meshes[i].albedo, &b = back.scene.meshes[i].albedo;
    EXPECT_EQ(b.kind, a.kind);
    if (a.kind == SurfaceAlbedo::Kind::kConstant) {
      EXPECT_EQ(b.constant, a.constant);
    }
    EXPECT_EQ(b.values, a.values);
    EXPECT_EQ(back.scene.meshes[i].mesh.vertices, scene.meshes[i].mesh.vertices);
  }
  ExpectSameViews(views, back.views, 1e-12, 1e-12);
  EXPECT_FALSE(back.settings.hide_emitters.has_value());  // the light is a mesh: seen, not hidden
  CompareRenders(scene, back, views[0], back.views[0], 0.01);
}

// ------------------------------------------------------------------------------------------------
// The import of what the export writes, by hand.

TEST(MitsubaXmlImport, MeshAttributeReadsPlyColoursAsMitsubaDoes) {
  test::TempDir dir;
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\n";
  // uchar red/green/blue: normalised and sRGB-decoded; faces: float r/g/b (before red/green/blue).
  WriteFile(dir / "a.ply", head +
                               "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                               "element face 1\nproperty list uchar int vertex_indices\n"
                               "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                               "property float r\nproperty float g\nproperty float b\nend_header\n"
                               "0 0 0 255 128 0\n1 0 0 10 20 30\n0 1 0 0 0 0\n"
                               "3 0 1 2 9 9 9 0.25 0.5 0.125\n");
  const auto scene = [&](const char* attribute, const char* scale) {
    WriteFile(dir / "s.xml",
              Format("<scene version=\"3.0.0\"><shape type=\"ply\"><string name=\"filename\" "
                     "value=\"a.ply\"/><bsdf type=\"diffuse\"><texture type=\"mesh_attribute\" "
                     "name=\"reflectance\"><string name=\"name\" value=\"",
                     attribute, "\"/>", scale, "</texture></bsdf></shape></scene>"));
    return ImportMitsubaXml(dir / "s.xml").scene.meshes.at(0).albedo;
  };
  const SurfaceAlbedo vertex = scene("vertex_color", "");
  ASSERT_EQ(vertex.kind, SurfaceAlbedo::Kind::kPerVertex);
  ASSERT_EQ(vertex.values.size(), 3u);
  EXPECT_EQ(vertex.values[0], Vector3f(1.0f, SrgbToLinear(128.0f / 255.0f), 0.0f));
  EXPECT_EQ(vertex.values[1], Vector3f(SrgbToLinear(10 / 255.0f), SrgbToLinear(20 / 255.0f),
                                       SrgbToLinear(30 / 255.0f)));
  const SurfaceAlbedo face = scene("face_color", "<float name=\"scale\" value=\"2\"/>");
  ASSERT_EQ(face.kind, SurfaceAlbedo::Kind::kPerFace);
  EXPECT_EQ(face.values, std::vector<Vector3f>{Vector3f(0.5f, 1.0f, 0.25f)});
  EXPECT_CONTAINS(ErrorOf([&] { scene("face_color", "<float name=\"scale\" value=\"5\"/>"); }),
                  "is not in [0, 1]");
  EXPECT_CONTAINS(ErrorOf([&] { scene("vertex_normal", ""); }),
                  "'vertex_normal' is not in the subset");
}

TEST(MitsubaXmlImport, MeshAttributeErrors) {
  test::TempDir dir;
  WriteFile(dir / "plain.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nproperty float red\nproperty float green\nproperty float blue\n"
            "property float alpha\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0 1 1 1 1\n1 0 0 1 1 1 1\n0 1 0 1 1 1 1\n3 0 1 2\n");
  WriteFile(dir / "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const std::string texture =
      "<texture type=\"mesh_attribute\" name=\"reflectance\"><string name=\"name\" "
      "value=\"face_color\"/></texture>";
  const auto error = [&](const std::string& shape, const std::string& bsdf) {
    WriteFile(dir / "s.xml", "<scene version=\"3.0.0\">\n<shape type=\"" + shape +
                                 "\"><string name=\"filename\" value=\"" +
                                 (shape == "obj" ? "t.obj" : "plain.ply") +
                                 "\"/><bsdf type=\"diffuse\">" + bsdf + "</bsdf></shape></scene>");
    return ErrorOf([&] { ImportMitsubaXml(dir / "s.xml"); });
  };
  EXPECT_CONTAINS(error("ply", texture), "no r/g/b or red/green/blue properties");
  EXPECT_CONTAINS(error("ply", texture), "s.xml:2: <shape type=\"ply\">");
  std::string vertex = texture;
  vertex.replace(vertex.find("face_color"), 10, "vertex_color");
  EXPECT_CONTAINS(error("ply", vertex), "with alpha is not in the subset");
  EXPECT_CONTAINS(error("obj", vertex), "needs a ply shape");
  EXPECT_CONTAINS(error("ply", "<rgb name=\"reflectance\" value=\"0.5\"/>" + vertex),
                  "the reflectance is given twice");
  EXPECT_CONTAINS(error("ply", "<texture type=\"bitmap\" name=\"reflectance\"/>"),
                  "a mesh_attribute texture");
  std::string unnamed = vertex;
  unnamed.replace(unnamed.find(" name=\"reflectance\""), 19, "");
  EXPECT_CONTAINS(error("ply", unnamed), "name=\"reflectance\"");
}

TEST(MitsubaXmlImport, ScaledCameraToWorldIsACameraWithNonSquarePixels) {
  test::TempDir dir;
  const auto load = [&](const std::string& transform) {
    WriteFile(dir / "s.xml",
              "<scene version=\"3.0.0\"><sensor type=\"perspective\"><float name=\"fov\" "
              "value=\"90\"/><transform name=\"to_world\">" +
                  transform +
                  "</transform><film type=\"hdrfilm\"><integer name=\"width\" value=\"100\"/>"
                  "<integer name=\"height\" value=\"50\"/></film></sensor></scene>");
    return ImportMitsubaXml(dir / "s.xml").views.at(0);
  };
  // fov 90 on 100 pixels: f = 50; the scale (1.0004, 0.9998, 1.0001) of the local axes.
  const PosedView v = load(
      "<scale x=\"1.0004\" y=\"0.9998\" z=\"1.0001\"/><rotate y=\"1\" angle=\"30\"/>"
      "<translate x=\"1\" y=\"2\" z=\"3\"/>");
  EXPECT_NEAR(v.intrinsics.fx, 50 * 1.0001 / 1.0004, 1e-12);
  EXPECT_NEAR(v.intrinsics.fy, 50 * 1.0001 / 0.9998, 1e-12);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(M_PI / 6, Vector3d::UnitY()).toRotationMatrix() *
                            Eigen::Vector3d(-1, -1, 1).asDiagonal();
  EXPECT_TRUE(v.world_from_camera.linear().isApprox(r, 1e-12));
  EXPECT_TRUE(v.world_from_camera.translation().isApprox(Vector3d(1, 2, 3), 1e-12));
  const PosedView square = load("<rotate y=\"1\" angle=\"30\"/>");
  EXPECT_EQ(square.intrinsics.fx, square.intrinsics.fy);
  EXPECT_CONTAINS(ErrorOf([&] { load("<scale x=\"1.001\"/>"); }),
                  "no scale or shear beyond Mitsuba's tolerance");
}

TEST(MitsubaXmlImport, HideEmittersIsReadFromPathAndDirect) {
  test::TempDir dir;
  for (const char* type : {"path", "direct"}) {
    for (const char* value : {"true", "false"}) {
      WriteFile(dir / "s.xml", Format("<scene version=\"3.0.0\"><integrator type=\"", type,
                                      "\"><boolean name=\"hide_emitters\" value=\"", value,
                                      "\"/></integrator></scene>"));
      EXPECT_EQ(ImportMitsubaXml(dir / "s.xml").settings.hide_emitters,
                std::string(value) == "true");
    }
  }
  WriteFile(dir / "s.xml", "<scene version=\"3.0.0\"/>");
  EXPECT_FALSE(ImportMitsubaXml(dir / "s.xml").settings.hide_emitters.has_value());
}

}  // namespace
}  // namespace genscene::render
