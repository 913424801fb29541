// Mitsuba 3 XML import (render/formats/mitsuba_xml.h; the export is tested in
// mitsuba_export_test.cpp). Expected numbers are worked out by hand from the XML files and
// ../shared/MITSUBA-XML.md, whose checks against Mitsuba's own reference renders they repeat
// (camera projection, emitter side, default fov).
#include "render/formats/mitsuba_xml.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "core/check.h"
#include "core/ply_io.h"
#include "render/formats/mesh_sources.h"
#include "render/formats/scene_io.h"
#include "tests/test_util.h"

namespace genscene::render {
namespace {

using test::ErrorOf;
using test::WriteFile;

namespace fs = std::filesystem;
using Eigen::Vector3d;
using Eigen::Vector3f;

// A scene file with `body` inside <scene version="3.0.0">.
fs::path WriteScene(const test::TempDir& dir, const std::string& body,
                    const std::string& name = "scene.xml") {
  WriteFile(dir / name, "<scene version=\"3.0.0\">\n" + body + "\n</scene>\n");
  return dir / name;
}

// Pixel (OpenCV convention) where a world point appears in a view.
Eigen::Vector2d Pixel(const PosedView& view, const Vector3d& world) {
  return *view.intrinsics.Project(view.world_from_camera.inverse() * world);
}

Vector3f UnitFaceNormal(const TriangleMesh& mesh, size_t f) {
  return mesh.FaceNormalScaled(f).normalized();
}

const SceneMesh& MeshNamed(const Scene& scene, const std::string& name) {
  for (const SceneMesh& m : scene.meshes) {
    if (m.name == name) return m;
  }
  throw Error("no mesh " + name);
}

// ------------------------------------------------------------------------------------------------
// The data scenes.

struct DataScene {
  const char* file;
  int meshes, emitters, point_lights, width;
  const char* integrator;
  int max_depth, spp;
};

TEST(MitsubaXmlData, EverySubsetSceneLoadsWithTheExpectedContents) {
  GS_REQUIRE_SHARED_DATA(data);
  const DataScene scenes[] = {
      {"ad-integrator-refs/area_light_radiance.xml", 3, 1, 0, 128, "path", 2, 12000},
      {"ad-integrator-refs/directly_visible_area_light_radiance.xml", 1, 1, 0, 128, "path", 2,
       12000},
      {"ad-integrator-refs/point_light_intensity.xml", 2, 0, 1, 128, "path", 2, 12000},
      {"ad-integrator-refs/rotate_shading_normals_plane.xml", 2, 1, 0, 128, "path", 2, 12000},
      {"ad-integrator-refs/scale_sphere_emitter_on_black.xml", 1, 1, 0, 64, "path", 2, 12000},
      {"ad-integrator-refs/translate_occluder_area_light.xml", 3, 1, 0, 128, "path", 2, 12000},
      {"ad-integrator-refs/translate_plane_and_area_emitter.xml", 2, 1, 0, 128, "path", 2, 12000},
      {"ad-integrator-refs/translate_rectangle_emitter_on_black.xml", 1, 1, 0, 128, "path", 2,
       12000},
      {"ad-integrator-refs/translate_self_shadowing_right_angle.xml", 3, 1, 0, 128, "path", 2,
       12000},
      {"ad-integrator-refs/translate_shadow_receiver_area_light.xml", 3, 1, 0, 128, "path", 2,
       12000},
      {"ad-integrator-refs/translate_sphere_emitter_on_black.xml", 1, 1, 0, 128, "path", 2, 12000},
      {"ignis-evaluation/evaluation/point.xml", 1, 0, 1, 256, "path", 4, 4096},
      {"ignis-evaluation/evaluation/emissive-plane.xml", 2, 1, 0, 256, "path", 4, 4096},
      {"ignis-evaluation/evaluation/emissive-plane-scale.xml", 2, 1, 0, 256, "path", 4, 4096},
      {"cbox-rgb/cbox-rgb.xml", 8, 1, 0, 256, "path", 6, 256},
      {"cbox-rgb/cbox-rgb-flat.xml", 8, 1, 0, 256, "path", 6, 256},
      {"simple-teapot/simple.xml", 1, 0, 2, 256, "direct", 2, 256},
  };
  for (const DataScene& s : scenes) {
    SCOPED_TRACE(s.file);
    const LoadedScene loaded = LoadScene(data / "mitsuba" / s.file);
    int emitters = 0;
    for (const SceneMesh& m : loaded.scene.meshes) emitters += m.IsEmitter() ? 1 : 0;
    EXPECT_EQ(static_cast<int>(loaded.scene.meshes.size()), s.meshes);
    EXPECT_EQ(emitters, s.emitters);
    EXPECT_EQ(static_cast<int>(loaded.scene.point_lights.size()), s.point_lights);
    ASSERT_EQ(loaded.views.size(), 1u);
    EXPECT_EQ(loaded.views[0].intrinsics.width, s.width);
    EXPECT_EQ(loaded.settings.integrator, std::optional<std::string>(s.integrator));
    EXPECT_EQ(loaded.settings.max_depth, s.max_depth);
    EXPECT_EQ(loaded.settings.samples_per_pixel, s.spp);
    ASSERT_TRUE(loaded.settings.pixel_filter.has_value());
    EXPECT_EQ(loaded.settings.pixel_filter->kind, PixelFilter::Kind::kBox);
    // No degenerate faces, unattached emitters or normals against the winding in the data.
    for (const std::string& w : loaded.warnings) ADD_FAILURE() << w;
  }
}

TEST(MitsubaXmlData, CboxTutorialIsOutsideTheSubsetAndSaysWhere) {
  GS_REQUIRE_SHARED_DATA(data);
  const std::string message = ErrorOf([&] { LoadScene(data / "mitsuba/cbox-tutorial/cbox.xml"); });
  EXPECT_CONTAINS(message, "cbox.xml:28:");
  EXPECT_CONTAINS(message, "<rfilter type=\"tent\">");
  EXPECT_CONTAINS(message, "not in the subset");
  EXPECT_EQ(message.find('\n'), std::string::npos);
}

// point_light_intensity: MITSUBA-XML.md §5 checked that world (0.5, 0.5, 0) lands at
// (u, v) * 128 = (90.15, 37.85) in Mitsuba's [i, i+1) pixel coordinates with the default
// x_fov 34.0221 deg (tan(x_fov/2) = 0.305941): (89.65, 37.35) with pixel centres at integers.
TEST(MitsubaXmlData, DefaultFovCameraProjectsAKnownPoint) {
  GS_REQUIRE_SHARED_DATA(data);
  const LoadedScene s = LoadScene(data / "mitsuba/ad-integrator-refs/point_light_intensity.xml");
  const PosedView& view = s.views[0];
  EXPECT_NEAR(view.intrinsics.fx, 64.0 / 0.305941, 1e-3);
  EXPECT_EQ(view.intrinsics.fx, view.intrinsics.fy);
  EXPECT_EQ(view.intrinsics.cx, 63.5);
  EXPECT_EQ(view.intrinsics.cy, 63.5);
  const Eigen::Vector2d uv = Pixel(view, Vector3d(0.5, 0.5, 0.0));
  EXPECT_NEAR(uv.x(), 90.15 - 0.5, 0.005);
  EXPECT_NEAR(uv.y(), 37.85 - 0.5, 0.005);
  EXPECT_TRUE(view.world_from_camera.translation().isApprox(Vector3d(0, 0, 4)));
  // The point light and the analytic sphere (scale 0.25 of the unit sphere).
  EXPECT_EQ(s.scene.point_lights[0].position, Vector3d(1.25, 0.0, 1.0));
  EXPECT_EQ(s.scene.point_lights[0].intensity, Vector3f(5, 5, 5));
  const SceneMesh& sphere = MeshNamed(s.scene, "sphere");
  EXPECT_TRUE(sphere.smooth_shading);
  EXPECT_EQ(sphere.albedo.constant, Vector3f::Constant(0.5f));
  for (const Vector3f& v : sphere.mesh.vertices) EXPECT_NEAR(v.norm(), 0.25f, 1e-6f);
}

// cbox-rgb: fov 39.3077 on the smaller axis of a square film = x; lookat (278, 273, -800) -> +z.
// SOURCE.txt measured the luminaire's front edge (z = 227, y = 548.8 - 0.5) at row 31.925 of the
// Mitsuba reference ([i, i+1) rows), i.e. 31.425 with centres at integers; world +x is image left.
TEST(MitsubaXmlData, CboxCameraMatchesTheReferenceImage) {
  GS_REQUIRE_SHARED_DATA(data);
  const LoadedScene s = LoadScene(data / "mitsuba/cbox-rgb/cbox-rgb.xml");
  const PosedView& view = s.views[0];
  EXPECT_NEAR(view.intrinsics.fx, 128.0 / std::tan(39.3077 / 2 * M_PI / 180), 1e-9);
  EXPECT_NEAR(Pixel(view, Vector3d(278, 548.3, 227)).y(), 31.425, 0.02);
  EXPECT_NEAR(Pixel(view, Vector3d(278, 548.3, 332)).y(), 40.84 - 0.5, 0.02);
  EXPECT_LT(Pixel(view, Vector3d(556, 273, 0)).x(), 127.5);  // red wall on the left
  EXPECT_GT(Pixel(view, Vector3d(0, 273, 0)).x(), 127.5);    // green wall on the right
  EXPECT_EQ(s.settings.near_clip, 10.0);
  EXPECT_EQ(s.settings.far_clip, 2800.0);
  // The luminaire: forward <ref> to the area emitter declared after the include; emits down.
  const SceneMesh& light = MeshNamed(s.scene, "cbox_luminaire");
  EXPECT_EQ(light.emission, Vector3f(18.387f, 10.9873f, 2.75357f));
  EXPECT_EQ(light.albedo.constant, Vector3f(0.936461f, 0.740433f, 0.705267f));
  for (size_t f = 0; f < light.mesh.faces.size(); ++f)
    EXPECT_TRUE(UnitFaceNormal(light.mesh, f).isApprox(Vector3f(0, -1, 0)));
  for (const Vector3f& v : light.mesh.vertices) EXPECT_FLOAT_EQ(v.y(), 548.3f);
  // The fragment-based file and the flattened copy describe the same scene.
  const LoadedScene flat = LoadScene(data / "mitsuba/cbox-rgb/cbox-rgb-flat.xml");
  ASSERT_EQ(flat.scene.meshes.size(), s.scene.meshes.size());
  for (size_t i = 0; i < flat.scene.meshes.size(); ++i) {
    EXPECT_EQ(flat.scene.meshes[i].mesh.vertices, s.scene.meshes[i].mesh.vertices);
    EXPECT_EQ(flat.scene.meshes[i].albedo.constant, s.scene.meshes[i].albedo.constant);
    EXPECT_EQ(flat.scene.meshes[i].emission, s.scene.meshes[i].emission);
  }
  EXPECT_TRUE(flat.views[0].world_from_camera.isApprox(view.world_from_camera, 0.0));
}

// directly_visible_area_light_radiance: the reference shows the rectangle's left edge at
// 11.70 px ([i, i+1) coordinates), 11.20 with centres at integers (MITSUBA-XML.md §10).
TEST(MitsubaXmlData, RectangleEdgeLandsWhereTheReferenceShowsIt) {
  GS_REQUIRE_SHARED_DATA(data);
  const LoadedScene s =
      LoadScene(data / "mitsuba/ad-integrator-refs/directly_visible_area_light_radiance.xml");
  const Eigen::AlignedBox3f box = s.scene.meshes[0].mesh.Bounds();
  EXPECT_NEAR(Pixel(s.views[0], box.min().cast<double>()).x(), 11.70 - 0.5, 0.005);
  EXPECT_NEAR(Pixel(s.views[0], box.max().cast<double>()).x(), 127 - (11.70 - 0.5), 0.005);
  EXPECT_EQ(s.scene.meshes[0].emission, Vector3f(1, 1, 1));
  EXPECT_TRUE(
      UnitFaceNormal(s.scene.meshes[0].mesh, 0).isApprox(Vector3f(0, 0, 1)));  // faces the camera
}

TEST(MitsubaXmlData, ShapeTransformsFollowMitsubasCompositionOrder) {
  GS_REQUIRE_SHARED_DATA(data);
  const fs::path ad = data / "mitsuba/ad-integrator-refs";
  // rotate y -90 (maps +z to -x), then translate (1.25, 0, 1): the light faces the plane centre.
  const LoadedScene area = LoadScene(ad / "area_light_radiance.xml");
  const SceneMesh& light = MeshNamed(area.scene, "light");
  EXPECT_EQ(light.emission, Vector3f(3, 3, 3));
  EXPECT_EQ(light.albedo.constant, Vector3f::Zero());  // emitter without BSDF: black
  for (const Vector3f& v : light.mesh.vertices) {
    EXPECT_NEAR(v.x(), 1.25f, 1e-6f);
    EXPECT_NEAR(std::abs(v.y()), 1.0f, 1e-6f);
    EXPECT_NEAR(std::abs(v.z() - 1.0f), 1.0f, 1e-6f);
  }
  EXPECT_TRUE(UnitFaceNormal(light.mesh, 0).isApprox(Vector3f(-1, 0, 0)));
  // scale 0.25, then lookat origin (0,0,-1) target (0,-1,0): centre (0,0,-1), normal along
  // target - origin, side 0.5 (area 0.25).
  const Scene s = LoadScene(ad / "translate_plane_and_area_emitter.xml").scene;
  const SceneMesh& plane = MeshNamed(s, "plane");
  EXPECT_FALSE(plane.smooth_shading);  // face_normals = true
  Vector3f centre = Vector3f::Zero();
  for (const Vector3f& v : plane.mesh.vertices) centre += v / 4.0f;
  EXPECT_LT((centre - Vector3f(0, 0, -1)).norm(), 1e-6f);
  EXPECT_TRUE(UnitFaceNormal(plane.mesh, 0).isApprox(Vector3f(0, -1, 1).normalized(), 1e-6f));
  EXPECT_NEAR(plane.mesh.FaceNormalScaled(0).norm() + plane.mesh.FaceNormalScaled(1).norm(),
              2 * 0.25f, 1e-6f);  // area
  // Non-uniform scale (2, 0.5, 1) then translate (0, 8, -4); the normal stays +z.
  const LoadedScene right_angle = LoadScene(ad / "translate_self_shadowing_right_angle.xml");
  const SceneMesh& tall = MeshNamed(right_angle.scene, "light");
  const Eigen::AlignedBox3f box = tall.mesh.Bounds();
  EXPECT_TRUE(box.min().isApprox(Vector3f(-2, 7.5, -4)));
  EXPECT_TRUE(box.max().isApprox(Vector3f(2, 8.5, -4)));
  EXPECT_TRUE(UnitFaceNormal(tall.mesh, 0).isApprox(Vector3f(0, 0, 1)));
  // Ignis: a binary PLY ceiling scaled by 0.5 about the origin, <spectrum value="1"> radiance.
  const LoadedScene ignis =
      LoadScene(data / "mitsuba/ignis-evaluation/evaluation/emissive-plane-scale.xml");
  const SceneMesh& top = ignis.scene.meshes[1];
  EXPECT_EQ(top.emission, Vector3f(1, 1, 1));
  EXPECT_TRUE(top.mesh.Bounds().max().isApprox(Vector3f(0.5f, 0.5f, 0.5f)));
  EXPECT_TRUE(UnitFaceNormal(top.mesh, 0).isApprox(Vector3f(0, -1, 0)));
}

TEST(MitsubaXmlData, PointLightsByPositionAndByTransform) {
  GS_REQUIRE_SHARED_DATA(data);
  const LoadedScene teapot = LoadScene(data / "mitsuba/simple-teapot/simple.xml");
  EXPECT_EQ(teapot.scene.point_lights[0].position, Vector3d(3, -10, 6));
  EXPECT_EQ(teapot.scene.point_lights[1].position, Vector3d(-3, -10, -2));
  EXPECT_EQ(teapot.scene.point_lights[1].intensity, Vector3f(100, 100, 100));
  EXPECT_EQ(teapot.scene.meshes[0].albedo.constant, Vector3f(0.9f, 0.9f, 0.0f));  // "0.9 0.9 0.0"
  EXPECT_TRUE(teapot.scene.meshes[0].smooth_shading);  // no normals in the PLY: computed
  EXPECT_EQ(teapot.scene.meshes[0].mesh.faces.size(), 2256u);
  // The up vector (0, 0, 1) appears upwards: a point above the target is above the centre.
  EXPECT_LT(Pixel(teapot.views[0], Vector3d(0, 0, 2.25)).y(), 127.5);
  const LoadedScene ignis = LoadScene(data / "mitsuba/ignis-evaluation/evaluation/point.xml");
  const PointLight& light = ignis.scene.point_lights[0];
  EXPECT_EQ(light.position, Vector3d(0, 1, 0));
  EXPECT_NEAR(ignis.views[0].intrinsics.fx, 128.0, 1e-9);  // fov 90 on 256 pixels
  // The whole chain against Mitsuba's reference (SOURCE.txt): the ray through pixel (128, 192)
  // meets the floor y = -1 where rho/pi * I * cos / d^2 = 0.070483; the reference reads 0.070496.
  const PosedView& view = ignis.views[0];
  const Vector3d dir = view.world_from_camera.linear() * view.intrinsics.RayDirection(128, 192);
  const Vector3d origin = view.world_from_camera.translation();
  const Vector3d hit = origin + dir * ((-1.0 - origin.y()) / dir.y());
  const Vector3d to_light = light.position - hit;
  const double radiance = ignis.scene.meshes[0].albedo.constant.x() / M_PI * light.intensity.x() *
                          (to_light.y() / to_light.norm()) / to_light.squaredNorm();
  EXPECT_NEAR(radiance, 0.070496, 3e-5);
}

// ------------------------------------------------------------------------------------------------
// The document features, on small files.

TEST(MitsubaXml, DefaultsSubstitutionAndParameters) {
  test::TempDir dir;
  const fs::path path = WriteScene(dir, R"(
    <default name="r" value="0.25"/>
    <default name="r" value="0.75"/>
    <default name="rr" value="0.5"/>
    <default name="kind" value="rect"/>
    <shape type="$kindangle" id="a"><bsdf type="diffuse"><rgb name="reflectance" value="$r, $rr, $r"/></bsdf></shape>
    <shape type="rectangle" id="b\$"/>)");
  const LoadedScene s = ImportMitsubaXml(path);
  EXPECT_EQ(s.scene.meshes[0].albedo.constant, Vector3f(0.25f, 0.5f, 0.25f));  // first default wins
  EXPECT_EQ(s.scene.meshes[1].name, "b$");
  MitsubaImportOptions options;
  options.parameters["r"] = "1";  // like -D r=1: wins over the file
  EXPECT_EQ(ImportMitsubaXml(path, options).scene.meshes[0].albedo.constant, Vector3f(1, 0.5f, 1));
}

TEST(MitsubaXml, UndefinedParameterIsAnError) {
  test::TempDir dir;
  const std::string message =
      ErrorOf([&] { ImportMitsubaXml(WriteScene(dir, "<shape type=\"$shape_kind\"/>")); });
  EXPECT_CONTAINS(message, "scene.xml:2:");
  EXPECT_CONTAINS(message, "undefined parameter: $shape_kind");
}

TEST(MitsubaXml, ForwardReferencesIncludesAndSearchPaths) {
  test::TempDir dir;
  WriteFile(
      dir / "parts/bsdfs.xml",
      R"(<scene version="3.0.0"><bsdf type="diffuse" id="grey"><float name="reflectance" value="0.3"/></bsdf></scene>)");
  WriteFile(dir / "geometry/quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  const fs::path path = WriteScene(dir, R"(
    <path value="geometry"/>
    <shape type="obj"><string name="filename" value="quad.obj"/><ref id="grey"/><ref id="lamp"/></shape>
    <include filename="parts/bsdfs.xml"/>
    <emitter type="area" id="lamp"><rgb name="radiance" value="2"/></emitter>)");
  const LoadedScene s = ImportMitsubaXml(path);
  ASSERT_EQ(s.scene.meshes.size(), 1u);
  EXPECT_EQ(s.scene.meshes[0].name, "quad");
  EXPECT_EQ(s.scene.meshes[0].albedo.constant, Vector3f::Constant(0.3f));
  EXPECT_EQ(s.scene.meshes[0].emission, Vector3f::Constant(2.0f));
  EXPECT_EQ(s.scene.meshes[0].mesh.faces.size(), 2u);  // quad fan-triangulated
  EXPECT_TRUE(s.warnings.empty());
  const std::string message = ErrorOf([&] {
    ImportMitsubaXml(WriteScene(dir, "<shape type=\"cube\"><ref id=\"nope\"/></shape>"));
  });
  EXPECT_CONTAINS(message, "unresolved reference to 'nope'");
}

TEST(MitsubaXml, TransformElements) {
  test::TempDir dir;
  const auto corner = [&](const std::string& transform) {
    const fs::path p = WriteScene(dir, "<shape type=\"cube\"><transform name=\"to_world\">" +
                                           transform + "</transform></shape>");
    return ImportMitsubaXml(p).scene.meshes[0].mesh.Bounds().max();
  };
  // matrix is row-major: translation in entries 3, 7, 11.
  EXPECT_TRUE(corner("<matrix value=\"2 0 0 10 0 2 0 20 0 0 2 30 0 0 0 1\"/>")
                  .isApprox(Vector3f(12, 22, 32)));
  EXPECT_TRUE(corner("<matrix value=\"1 0 0 0 1 0 0 0 3\"/>").isApprox(Vector3f(1, 1, 3)));
  EXPECT_TRUE(corner("<scale x=\"2\"/>").isApprox(Vector3f(2, 1, 1)));      // missing = 1
  EXPECT_TRUE(corner("<translate y=\"5\"/>").isApprox(Vector3f(1, 6, 1)));  // missing = 0
  EXPECT_TRUE(
      corner("<translate value=\"1\"/><scale value=\"2\"/>").isApprox(Vector3f(4, 4, 4)));  // then
  EXPECT_TRUE(corner("<scale value=\"2\"/><translate value=\"1\"/>").isApprox(Vector3f(3, 3, 3)));
  // rotate: degrees, right-handed; x by 90 maps +z to -y.
  const fs::path p = WriteScene(dir, R"(<shape type="rectangle"><transform name="to_world">
      <rotate x="1" angle="90"/></transform></shape>)");
  EXPECT_TRUE(
      UnitFaceNormal(ImportMitsubaXml(p).scene.meshes[0].mesh, 0).isApprox(Vector3f(0, -1, 0)));
  // lookat without up: any orthonormal frame with +z along the view direction.
  const fs::path q = WriteScene(dir, R"(<shape type="rectangle"><transform name="to_world">
      <lookat origin="1, 2, 3" target="1, 2, 4"/></transform></shape>)");
  EXPECT_TRUE(
      UnitFaceNormal(ImportMitsubaXml(q).scene.meshes[0].mesh, 0).isApprox(Vector3f(0, 0, 1)));
}

TEST(MitsubaXml, CubeAndSphereAreClosedAndFaceOutwards) {
  test::TempDir dir;
  const Scene s = ImportMitsubaXml(WriteScene(dir, R"(<shape type="cube"/>
      <shape type="sphere"><point name="center" x="1" y="2" z="3"/><float name="radius" value="2"/></shape>)"))
                      .scene;
  for (const SceneMesh& m : s.meshes) {
    SCOPED_TRACE(m.name);
    const Vector3f centre = m.name == "cube" ? Vector3f::Zero() : Vector3f(1, 2, 3);
    double volume = 0.0, area = 0.0;  // signed volume by the divergence theorem
    std::map<std::pair<int, int>, int> edges;
    for (size_t f = 0; f < m.mesh.faces.size(); ++f) {
      const auto& t = m.mesh.faces[f];
      const Vector3d a = (m.mesh.vertices[t[0]] - centre).cast<double>(),
                     b = (m.mesh.vertices[t[1]] - centre).cast<double>(),
                     c = (m.mesh.vertices[t[2]] - centre).cast<double>();
      volume += a.dot(b.cross(c)) / 6.0;
      area += (b - a).cross(c - a).norm() / 2.0;
      for (int k = 0; k < 3; ++k) ++edges[std::minmax(t[k], t[(k + 1) % 3])];
    }
    if (m.name == "cube") {
      EXPECT_EQ(m.mesh.faces.size(), 12u);
      EXPECT_NEAR(volume, 8.0, 1e-9);
      EXPECT_NEAR(area, 24.0, 1e-9);
    } else {
      EXPECT_EQ(m.mesh.faces.size(), 20480u);  // level 5
      for (const auto& [edge, count] : edges) EXPECT_EQ(count, 2);
      EXPECT_NEAR(volume / (4.0 / 3.0 * M_PI * 8.0), 1.0, 1e-3);
      EXPECT_NEAR(area / (4.0 * M_PI * 4.0), 1.0, 1e-3);
    }
  }
}

// The tessellation error that matters for radiance: how far inside the sphere the faces lie.
TEST(MitsubaXml, SphereTessellationStaysWithinTheDocumentedTolerance) {
  const TriangleMesh m = SphereMesh(Eigen::Matrix4d::Identity(), 5);
  double min_plane_distance = 1.0;
  for (size_t f = 0; f < m.faces.size(); ++f) {
    const Vector3d n = m.FaceNormalScaled(f).cast<double>().normalized();
    min_plane_distance =
        std::min(min_plane_distance, n.dot(m.vertices[m.faces[f][0]].cast<double>()));
  }
  EXPECT_GT(min_plane_distance, 1.0 - 3e-4);  // documented in mitsuba_xml.h
  const TriangleMesh coarse = SphereMesh(Eigen::Matrix4d::Identity(), 4);
  double coarse_min = 1.0;
  for (size_t f = 0; f < coarse.faces.size(); ++f) {
    const Vector3d n = coarse.FaceNormalScaled(f).cast<double>().normalized();
    coarse_min = std::min(coarse_min, n.dot(coarse.vertices[coarse.faces[f][0]].cast<double>()));
  }
  EXPECT_LT(coarse_min, 1.0 - 1e-3);  // level 4: 0.2 % of the projected area on its own
  Eigen::Matrix4d skew = Eigen::Matrix4d::Identity();
  skew(0, 0) = 2.0;
  EXPECT_CONTAINS(ErrorOf([&] { SphereMesh(skew, 1); }), "uniformly");
}

// Sensors: fov axes, principal point offsets and the OpenCV conversion.
TEST(MitsubaXml, SensorFovAxesAndPrincipalPoint) {
  test::TempDir dir;
  const auto view = [&](const std::string& props, int w, int h) {
    return ImportMitsubaXml(
               WriteScene(dir, "<sensor type=\"perspective\">" + props +
                                   "<film type=\"hdrfilm\"><integer name=\"width\" value=\"" +
                                   std::to_string(w) + "\"/><integer name=\"height\" value=\"" +
                                   std::to_string(h) + "\"/></film></sensor>"))
        .views[0];
  };
  const double t = std::tan(30.0 * M_PI / 180);  // half of 60 degrees
  EXPECT_NEAR(view("<float name=\"fov\" value=\"60\"/>", 200, 100).intrinsics.fx, 100 / t, 1e-9);
  // fov on y: tan(x/2) = tan(y/2) * aspect, so fx = W / (2 tan(x/2)) = H / (2 tan(y/2)).
  EXPECT_NEAR(
      view("<float name=\"fov\" value=\"60\"/><string name=\"fov_axis\" value=\"y\"/>", 200, 100)
          .intrinsics.fx,
      50 / t, 1e-9);
  EXPECT_NEAR(
      view("<float name=\"fov\" value=\"60\"/><string name=\"fov_axis\" value=\"smaller\"/>", 200,
           100)
          .intrinsics.fx,
      50 / t, 1e-9);
  EXPECT_NEAR(view("<float name=\"fov\" value=\"60\"/><string name=\"fov_axis\" value=\"larger\"/>",
                   100, 200)
                  .intrinsics.fx,
              100 / t, 1e-9);
  const double diagonal = std::hypot(300.0, 400.0);  // 3:4 film: fx = diagonal / (2 tan(d/2))
  EXPECT_NEAR(
      view("<float name=\"fov\" value=\"60\"/><string name=\"fov_axis\" value=\"diagonal\"/>", 300,
           400)
          .intrinsics.fx,
      diagonal / 2 / t, 1e-9);
  EXPECT_NEAR(view("<string name=\"focal_length\" value=\"36mm\"/>", 360, 240).intrinsics.fx, 360.0,
              1e-9);
  // A principal point offset moves the image content by -ppo * size (§5).
  const PosedView shifted = view(
      "<float name=\"fov\" value=\"90\"/><float name=\"principal_point_offset_x\" value=\"0.1\"/>"
      "<float name=\"principal_point_offset_y\" value=\"-0.05\"/>",
      100, 80);
  EXPECT_NEAR(shifted.intrinsics.cx, 49.5 - 10, 1e-12);
  EXPECT_NEAR(shifted.intrinsics.cy, 39.5 + 4, 1e-12);
  // Default film and filter when the sensor has none: 768 x 576, Gaussian 0.5, 4 spp.
  const LoadedScene bare = ImportMitsubaXml(WriteScene(dir, "<sensor type=\"perspective\"/>"));
  EXPECT_EQ(bare.views[0].intrinsics.width, 768);
  EXPECT_EQ(bare.settings.pixel_filter->kind, PixelFilter::Kind::kGaussian);
  EXPECT_EQ(bare.settings.pixel_filter->stddev, 0.5);
  EXPECT_EQ(bare.settings.samples_per_pixel, 4);
  EXPECT_EQ(bare.settings.max_depth, -1);  // default path integrator
}

// ------------------------------------------------------------------------------------------------
// Bad inputs: one clear line naming the file, the line and the element.

TEST(MitsubaXmlErrors, EachBadInputIsAClearError) {
  test::TempDir dir;
  WriteFile(dir / "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
  WriteFile(dir / "nan.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty "
            "float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\nnan 0 0\n0 "
            "1 0\n3 0 1 2\n");
  struct Case {
    std::string body, expected;
  };
  const Case cases[] = {
      {"<shape type=\"disk\"/>", "<shape type=\"disk\">: shape type 'disk' is not in the subset"},
      {"<shape type=\"sphere\"><float name=\"raduis\" value=\"1\"/></shape>",
       "property 'raduis' is not supported"},
      {"<shape type=\"ply\"><string name=\"filename\" value=\"missing.ply\"/></shape>",
       "missing.ply: file not found"},
      {"<shape type=\"obj\"><string name=\"filename\" value=\"nan.obj\"/></shape>",
       "nan.obj:2: 'v nan 0 0' is not finite"},
      {"<shape type=\"ply\"><string name=\"filename\" value=\"nan.ply\"/></shape>", "nan.ply"},
      {"<shape type=\"cube\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"1, -1, "
       "1\"/></emitter></shape>",
       "is negative"},
      {"<shape type=\"cube\"><transform name=\"to_world\"><rotate "
       "angle=\"30\"/></transform></shape>",
       "rotation axis cannot be zero"},
      {"<shape type=\"cube\"><transform name=\"to_world\"><rotate x=\"1\" y=\"1\" "
       "angle=\"30\"/></transform></shape>",
       "give a unit axis"},
      {"<shape type=\"cube\"><boolean name=\"flip_normals\" value=\"true\"/></shape>",
       "'flip_normals' is not supported"},
      {"<shape type=\"cube\"><bsdf type=\"twosided\"><bsdf type=\"diffuse\"/></bsdf></shape>",
       "bsdf type 'twosided' is not in the subset"},
      {"<shape type=\"cube\"><bsdf type=\"diffuse\"><rgb name=\"reflectance\" "
       "value=\"1.5\"/></bsdf></shape>",
       "not in [0, 1]"},
      {"<shape type=\"cube\"><bsdf type=\"diffuse\"><spectrum name=\"reflectance\" "
       "value=\"400:0.1, 700:0.5\"/></bsdf></shape>",
       "wavelength:value"},
      {"<shape type=\"cube\"><bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"1, "
       "2\"/></bsdf></shape>",
       "needs 1 or 3 values"},
      {"<emitter type=\"point\"><point name=\"position\" value=\"1, 2, 3\"/><transform "
       "name=\"to_world\"/></emitter>",
       "only one of 'position' and 'to_world'"},
      {"<emitter type=\"constant\"/>", "emitter type 'constant' is not in the subset"},
      {"<sensor type=\"perspective\"><transform name=\"to_world\"><scale "
       "value=\"2\"/></transform></sensor>",
       "no scale"},
      {"<sensor type=\"perspective\"><transform name=\"to_world\"><lookat origin=\"0,0,0\" "
       "target=\"0,1,0\" up=\"0,1,0\"/></transform></sensor>",
       "invalid lookat"},
      {"<sensor type=\"thinlens\"/>", "sensor type 'thinlens' is not in the subset"},
      {"<integrator type=\"volpath\"/>", "integrator type 'volpath' is not in the subset"},
      {"<texture type=\"bitmap\"/>", "not in the subset"},
      {"<shape type=\"cube\"><float name=\"x\" value=\"1\"/><float name=\"x\" "
       "value=\"2\"/></shape>",
       "duplicate property"},
      {"<shape type=\"sphere\"><float name=\"radius\" value=\"1O\"/></shape>",
       "'1O' is not a number"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.body);
    const std::string message = ErrorOf([&] { ImportMitsubaXml(WriteScene(dir, c.body)); });
    EXPECT_CONTAINS(message, c.expected);
    EXPECT_CONTAINS(message, (dir / "scene.xml:2:").string());
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  }
}

TEST(MitsubaXmlErrors, MalformedDocuments) {
  test::TempDir dir;
  WriteFile(dir / "broken.xml", "<scene version=\"3.0.0\">\n  <shape type=\"cube\">\n</scene>\n");
  std::string message = ErrorOf([&] { ImportMitsubaXml(dir / "broken.xml"); });
  EXPECT_CONTAINS(message, "broken.xml:");
  EXPECT_CONTAINS(message, "malformed XML");
  WriteFile(dir / "old.xml", "<scene>\n</scene>\n");
  EXPECT_CONTAINS(ErrorOf([&] { ImportMitsubaXml(dir / "old.xml"); }),
                  "missing attribute 'version'");
  EXPECT_CONTAINS(ErrorOf([&] { ImportMitsubaXml(dir / "absent.xml"); }),
                  "absent.xml: file not found");
}

TEST(MitsubaXml, DegenerateTrianglesAreKeptWithAWarningAndNonManifoldMeshesLoadAsTheyAre) {
  test::TempDir dir;
  // A "fin": three triangles on the edge (0, 1), plus a triangle with a repeated vertex.
  TriangleMesh fin;
  fin.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  fin.faces = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}, {2, 2, 4}};
  WritePly(dir / "fin.ply", fin);
  const LoadedScene s = ImportMitsubaXml(
      WriteScene(dir, R"(<shape type="ply"><string name="filename" value="fin.ply"/>
      <boolean name="face_normals" value="true"/></shape>)"));
  EXPECT_EQ(s.scene.meshes[0].mesh.vertices, fin.vertices);
  EXPECT_EQ(s.scene.meshes[0].mesh.faces, fin.faces);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_CONTAINS(s.warnings[0], "1 of 4 triangles have zero area");
}

}  // namespace
}  // namespace genscene::render
