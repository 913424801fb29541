// Scene files (render/formats/scene_io.h): our JSON format, LoadScene, the cbox-cycles loader and
// the mesh sources (OBJ, normals).
#include "render/formats/scene_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "core/check.h"
#include "core/ply_io.h"
#include "render/formats/mesh_sources.h"
#include "render/formats/workspace_scene.h"
#include "tests/test_util.h"

namespace genscene::render {
namespace {

using test::ErrorOf;
using test::WriteFile;

namespace fs = std::filesystem;
using Eigen::Vector3d;
using Eigen::Vector3f;

TriangleMesh Quad(float z) {
  TriangleMesh m;
  m.vertices = {{0, 0, z}, {1, 0, z}, {1, 1, z}, {0, 1, z}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

// A scene with every kind of content our JSON format stores.
Scene FullScene() {
  Scene scene;
  SceneMesh constant;
  constant.name = "floor / white";  // a name that is not a file name
  constant.mesh = Quad(0.0f);
  constant.albedo = SurfaceAlbedo::Constant(Vector3f(0.725f, 0.71f, 0.68f));
  scene.meshes.push_back(constant);
  SceneMesh per_face;
  per_face.name = "wall";
  per_face.mesh = Quad(1.0f);
  per_face.mesh.ComputeVertexNormals();
  per_face.smooth_shading = true;
  per_face.albedo.kind = SurfaceAlbedo::Kind::kPerFace;
  per_face.albedo.values = {{0.1f, 0.2f, 0.3f}, {0.4f, 0.5f, 0.6f}};
  scene.meshes.push_back(per_face);
  SceneMesh per_vertex;
  per_vertex.name = "lamp";
  per_vertex.mesh = Quad(2.0f);
  per_vertex.albedo.kind = SurfaceAlbedo::Kind::kPerVertex;
  per_vertex.albedo.values = {
      {0.1f, 0.1f, 0.1f}, {0.2f, 0.2f, 0.2f}, {0.3f, 0.3f, 0.3f}, {0.123456789f, 0, 1}};
  per_vertex.emission = Vector3f(30, 24, 18);
  scene.meshes.push_back(per_vertex);
  scene.point_lights.push_back({Vector3d(0.1, 0.2, 1.0 / 3.0), Vector3f(1.5f, 2, 2.5f)});
  VoxelLightGrid grid;
  grid.bounds = Eigen::AlignedBox3d(Vector3d(-0.5, -0.5, 0), Vector3d(0.5, 0.5, 1.0 / 3.0));
  grid.dims = Eigen::Vector3i(2, 1, 2);
  grid.cube_size = 0.02;
  for (int v = 0; v < 4; ++v) {
    grid.intensity.push_back(Vector3f(v, 0.5f * v, 1.0f / 3.0f));
    grid.weights.push_back({0.1f * v, 1, 0, 2, 1.0f / 7.0f, 0});
  }
  scene.voxel_lights = grid;
  return scene;
}

TEST(SceneJson, RoundTripKeepsEverything) {
  test::TempDir dir;
  const Scene scene = FullScene();
  std::vector<PosedView> views(2);
  views[0].intrinsics = {190, 190, 79.5, 59.5, 160, 120, {}};
  views[0].world_from_camera = Eigen::Translation3d(0.1, -1.9, 0.5) *
                               Eigen::AngleAxisd(1.2, Vector3d(1, 0.2, 0.1).normalized());
  views[0].timestamp = 0.125;
  views[1].intrinsics = {
      517.3, 516.5, 318.6, 255.3, 640, 480, {0.2624, -0.9531, -0.0054, 0.0026, 1.1633}};
  views[1].timestamp = 1305031102.175304;
  RenderSettings settings;
  settings.integrator = "direct";
  settings.max_depth = 2;
  settings.pixel_filter = PixelFilter{PixelFilter::Kind::kGaussian, 0.3};
  settings.near_clip = 0.01;

  SaveSceneJson(dir / "scene.json", scene, views, settings);
  EXPECT_TRUE(fs::exists(dir / "scene_meshes/000_floor___white.ply"));
  const LoadedScene back = LoadScene(dir / "scene.json");
  ASSERT_EQ(back.scene.meshes.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const SceneMesh &a = scene.meshes[i], &b = back.scene.meshes[i];
    SCOPED_TRACE(a.name);
    EXPECT_EQ(b.name, a.name);
    EXPECT_EQ(b.mesh.vertices, a.mesh.vertices);
    EXPECT_EQ(b.mesh.faces, a.mesh.faces);
    EXPECT_EQ(b.mesh.normals, a.mesh.normals);
    EXPECT_EQ(b.smooth_shading, a.smooth_shading);
    EXPECT_EQ(b.emission, a.emission);
    EXPECT_EQ(b.albedo.kind, a.albedo.kind);
    ASSERT_EQ(b.albedo.values.size(), a.albedo.values.size());
    // Per-face albedo is stored as float; per-vertex albedo goes through WritePly's 8-bit sRGB
    // vertex colours (half a step of 1/255 in sRGB is at most 0.0021 in linear, near 1).
    const float tolerance = a.albedo.kind == SurfaceAlbedo::Kind::kPerVertex ? 0.0021f : 0.0f;
    for (size_t k = 0; k < a.albedo.values.size(); ++k) {
      EXPECT_LE((b.albedo.values[k] - a.albedo.values[k]).cwiseAbs().maxCoeff(), tolerance) << k;
    }
    if (a.albedo.kind == SurfaceAlbedo::Kind::kConstant) {
      EXPECT_EQ(b.albedo.constant, a.albedo.constant);
    }
  }
  ASSERT_EQ(back.scene.point_lights.size(), 1u);
  EXPECT_EQ(back.scene.point_lights[0].position, scene.point_lights[0].position);
  EXPECT_EQ(back.scene.point_lights[0].intensity, scene.point_lights[0].intensity);
  ASSERT_TRUE(back.scene.voxel_lights.has_value());
  const VoxelLightGrid &g = *scene.voxel_lights, &h = *back.scene.voxel_lights;
  EXPECT_EQ(h.bounds.min(), g.bounds.min());
  EXPECT_EQ(h.bounds.max(), g.bounds.max());
  EXPECT_EQ(h.dims, g.dims);
  EXPECT_EQ(h.cube_size, g.cube_size);
  EXPECT_EQ(h.intensity, g.intensity);
  EXPECT_EQ(h.weights, g.weights);
  ASSERT_EQ(back.views.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    const CameraIntrinsics &a = views[i].intrinsics, &b = back.views[i].intrinsics;
    EXPECT_EQ(b.ToString(), a.ToString());
    EXPECT_EQ(b.distortion, a.distortion);
    EXPECT_NEAR(back.views[i].timestamp, views[i].timestamp, 1e-9 * std::abs(views[i].timestamp));
    EXPECT_LT(
        (back.views[i].world_from_camera.matrix() - views[i].world_from_camera.matrix()).norm(),
        1e-12);
  }
  EXPECT_EQ(back.settings.integrator, settings.integrator);
  EXPECT_EQ(back.settings.max_depth, settings.max_depth);
  EXPECT_FALSE(back.settings.samples_per_pixel.has_value());
  EXPECT_EQ(back.settings.pixel_filter->kind, PixelFilter::Kind::kGaussian);
  EXPECT_EQ(back.settings.pixel_filter->stddev, 0.3);
  EXPECT_EQ(back.settings.near_clip, settings.near_clip);
  EXPECT_FALSE(back.settings.far_clip.has_value());
}

TEST(SceneJson, HandWrittenFileWithDefaults) {
  test::TempDir dir;
  WritePly(dir / "meshes/quad.ply", Quad(0.0f));
  WriteFile(dir / "room.json", R"({"genscene_scene": 1,
    "meshes": [{"ply": "meshes/quad.ply"}, {"ply": "meshes/quad.ply", "albedo": [0, 0, 0], "emission": [2, 2, 2]}],
    "point_lights": [{"position": [0, 0, 1], "intensity": [3, 3, 3]}]})");
  const LoadedScene s = LoadScene(dir / "room.json");
  ASSERT_EQ(s.scene.meshes.size(), 2u);
  EXPECT_EQ(s.scene.meshes[0].name, "mesh0");
  EXPECT_EQ(s.scene.meshes[0].albedo.constant, Vector3f::Constant(0.5f));
  EXPECT_FALSE(s.scene.meshes[0].IsEmitter());
  EXPECT_TRUE(s.scene.meshes[1].IsEmitter());
  EXPECT_TRUE(s.views.empty());
  EXPECT_FALSE(s.settings.integrator.has_value());
}

TEST(SceneJson, BadFilesAreErrorsNamingTheKey) {
  test::TempDir dir;
  WritePly(dir / "quad.ply", Quad(0.0f));
  struct Case {
    std::string json, expected;
  };
  const Case cases[] = {
      {R"({"genscene_scene": 1, "lights": []})", "unknown key 'lights'"},
      {R"({"genscene_scene": 1, "meshes": [{"ply": "quad.ply", "albedoo": [1, 1, 1]}]})",
       "meshes[0]: unknown key 'albedoo'"},
      {R"({"genscene_scene": 1, "render": {"spp": 4}})", "render: unknown key 'spp'"},
      {R"({"genscene_scene": 2})", "genscene_scene"},
      {R"({"meshes": []})", "genscene_scene"},
      {R"({"genscene_scene": 1, "meshes": [{"ply": "quad.ply", "albedo": "from_ply"}]})",
       "has no colours"},
      {R"({"genscene_scene": 1, "meshes": [{"ply": "quad.ply", "smooth": true}]})",
       "no vertex normals"},
      {R"({"genscene_scene": 1, "meshes": [{"ply": "quad.ply", "emission": [1, -1, 1]}]})",
       "must be finite and >= 0"},
      {R"({"genscene_scene": 1, "meshes": [{"ply": "quad.ply", "emission": "bright"}]})",
       "meshes[0].emission: expected 3 numbers"},
      {R"({"genscene_scene": 1, "meshes": [{"ply": "quad.ply", "name": 7}]})", "scene.json"},
      {R"({"genscene_scene": 1, "meshes": [{"ply": "absent.ply"}]})", "absent.ply: file not found"},
      {R"({"genscene_scene": 1, "cameras": [{"intrinsics": "1 2 3", "pose": "0 0 0 0 0 0 0 1"}]})",
       "expected 6 or 11 values"},
      {R"({"genscene_scene": 1, "voxel_lights": {"bounds_min": [0,0,0], "bounds_max": [1,1,1], "dims": [1,1,1],
           "intensity": [[1,1,1]], "weights": [[1,1,1,1,1]]}})",
       "voxel_lights.weights: expected 6 numbers"},
      {R"({"genscene_scene": 1, )", "malformed JSON"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.json);
    WriteFile(dir / "scene.json", c.json);
    const std::string message = ErrorOf([&] { LoadScene(dir / "scene.json"); });
    EXPECT_CONTAINS(message, c.expected);
  }
  EXPECT_CONTAINS(ErrorOf([&] { LoadScene(dir / "scene.obj"); }), "unknown scene format '.obj'");
}

TEST(SceneJson, AlbedoFieldsCannotBeSaved) {
  struct Grey : AlbedoField {
    Vector3f Eval(int, float, float) const override { return Vector3f::Constant(0.5f); }
  };
  test::TempDir dir;
  Scene scene;
  SceneMesh m;
  m.name = "textured";
  m.mesh = Quad(0.0f);
  m.albedo.kind = SurfaceAlbedo::Kind::kField;
  m.albedo.field = std::make_shared<Grey>();
  scene.meshes.push_back(m);
  EXPECT_CONTAINS(ErrorOf([&] { SaveSceneJson(dir / "s.json", scene); }), "albedo field");
  EXPECT_FALSE(fs::exists(dir / "s.json"));
}

// ------------------------------------------------------------------------------------------------
// cbox-cycles (Blender Cycles reference scenes).

TEST(CyclesScene, CornellBoxObjectsFacesAndLight) {
  GS_REQUIRE_SHARED_DATA(data);
  const Scene scene = LoadCyclesScene(data / "cbox-cycles");
  const std::vector<std::pair<std::string, size_t>> expected = {
      {"floor", 2},         {"ceiling", 2},          {"back_wall", 2},
      {"left_wall_red", 2}, {"right_wall_green", 2}, {"short_block", 10},
      {"tall_block", 10},   {"ceiling_light", 2}};
  ASSERT_EQ(scene.meshes.size(), expected.size());
  size_t faces = 0;
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(scene.meshes[i].name, expected[i].first);
    EXPECT_EQ(scene.meshes[i].mesh.faces.size(), expected[i].second);
    EXPECT_FALSE(scene.meshes[i].smooth_shading);
    faces += scene.meshes[i].mesh.faces.size();
  }
  EXPECT_EQ(faces, 30u + 2u);  // scene.ply + the light's quad
  EXPECT_EQ(scene.meshes[3].albedo.constant, Vector3f(0.63f, 0.065f, 0.05f));
  EXPECT_EQ(scene.meshes[4].albedo.constant, Vector3f(0.14f, 0.45f, 0.091f));
  const SceneMesh& light = scene.meshes.back();
  EXPECT_EQ(light.emission, Vector3f(30, 24, 18));
  EXPECT_EQ(light.albedo.constant, Vector3f::Zero());
  for (size_t f = 0; f < 2; ++f)
    EXPECT_TRUE(light.mesh.FaceNormalScaled(f).normalized().isApprox(Vector3f(0, 0, -1)));
  EXPECT_NEAR(light.mesh.FaceNormalScaled(0).norm() / 2 + light.mesh.FaceNormalScaled(1).norm() / 2,
              0.0625, 1e-7);
  EXPECT_TRUE(scene.point_lights.empty());
}

TEST(CyclesScene, IcosphereSmoothFlagComesFromObjectsJson) {
  GS_REQUIRE_SHARED_DATA(data);
  for (const char* variant : {"icosphere_flat", "icosphere_smooth"}) {
    SCOPED_TRACE(variant);
    const Scene scene = LoadCyclesScene(data / "cbox-cycles" / variant);
    ASSERT_EQ(scene.meshes.size(), 7u);
    const SceneMesh& sphere = scene.meshes[5];
    EXPECT_EQ(sphere.name, "icosphere");
    EXPECT_EQ(sphere.mesh.vertices.size(), 42u);
    EXPECT_EQ(sphere.mesh.faces.size(), 80u);
    EXPECT_EQ(sphere.albedo.constant, Vector3f::Constant(0.8f));
    const bool smooth = std::string(variant) == "icosphere_smooth";
    EXPECT_EQ(sphere.smooth_shading, smooth);
    EXPECT_EQ(sphere.mesh.normals.size(), smooth ? 42u : 0u);
    // Fronts outward: every face normal points away from the centre (0, 0, 0.201).
    for (size_t f = 0; f < sphere.mesh.faces.size(); ++f) {
      EXPECT_GT(sphere.mesh.FaceNormalScaled(f).dot(sphere.mesh.vertices[sphere.mesh.faces[f][0]] -
                                                    Vector3f(0, 0, 0.201f)),
                0.0f);
    }
    EXPECT_EQ(scene.meshes[6].emission, Vector3f(30, 24, 18));
  }
}

TEST(CyclesScene, MissingFolderIsAnError) {
  test::TempDir dir;
  EXPECT_CONTAINS(ErrorOf([&] { LoadCyclesScene(dir / "nothing"); }), "scene.ply: file not found");
}

// ------------------------------------------------------------------------------------------------
// Mesh sources.

TEST(MeshSources, ObjCornersTriangulationAndNormals) {
  test::TempDir dir;
  WriteFile(dir / "a.obj",
            "# comment\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 9 9 9\nvt 0 0\nvt 1 0\n"
            "vn 0 0 2\ns off\nusemtl x\nf 1/1/1 2/2/1 3//1 4//1\n");
  const TriangleMesh m = ReadObj(dir / "a.obj");
  EXPECT_EQ(m.vertices.size(), 4u);  // the unused "v 9 9 9" is not part of the mesh
  ASSERT_EQ(m.faces.size(), 2u);     // fan about the first corner: (1,2,3), (1,3,4)
  EXPECT_EQ(m.faces[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(m.faces[1], Eigen::Vector3i(0, 2, 3));
  ASSERT_EQ(m.normals.size(), 4u);
  EXPECT_EQ(m.normals[0], Vector3f(0, 0, 1));
  // The same position with two texture coordinates becomes two vertices (as in Mitsuba).
  WriteFile(dir / "b.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 1\nf 1/1 2/1 3/1\nf 1/2 3/1 2/1\n");
  EXPECT_EQ(ReadObj(dir / "b.obj").vertices.size(), 4u);
  WriteFile(dir / "c.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n");
  EXPECT_CONTAINS(ErrorOf([&] { ReadObj(dir / "c.obj"); }), "c.obj:3: index out of range");
  WriteFile(dir / "d.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n");
  EXPECT_CONTAINS(ErrorOf([&] { ReadObj(dir / "d.obj"); }), "d.obj:4");
  WriteFile(dir / "e.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2 3\n");
  EXPECT_CONTAINS(ErrorOf([&] { ReadObj(dir / "e.obj"); }), "some corners have normals");
}

// A cube corner whose three faces are triangulated differently: the corner touches triangles of
// area 2 + 2 on the +x face but 1 + 1 on the +y and +z faces, while each face contributes 90
// degrees of corner angle. Angle weighting (Mitsuba's) gives the symmetric (1, 1, 1) / sqrt(3);
// area weighting would lean towards +x.
TEST(MeshSources, AngleWeightedNormalsAtACubeCorner) {
  TriangleMesh m;
  m.vertices = {{1, 1, 1},   {1, -1, 1},  {1, -1, -1}, {1, 1, -1}, {-1, 1, 1},
                {-1, 1, -1}, {-1, -1, 1}, {0, 1, 0},   {0, 0, 1}};
  m.faces = {{0, 1, 2}, {0, 2, 3},               // +x
             {0, 3, 7}, {0, 7, 4},               // +y
             {0, 4, 8}, {0, 8, 1}};              // +z
  for (size_t f = 0; f < m.faces.size(); ++f) {  // wind every face outward
    const Vector3f c =
        (m.vertices[m.faces[f][0]] + m.vertices[m.faces[f][1]] + m.vertices[m.faces[f][2]]) / 3.0f;
    if (m.FaceNormalScaled(f).dot(c) < 0.0f) std::swap(m.faces[f][1], m.faces[f][2]);
  }
  const std::vector<Vector3f> n = AngleWeightedNormals(m);
  EXPECT_TRUE(n[0].isApprox(Vector3f(1, 1, 1).normalized(), 1e-6f)) << n[0].transpose();
}

// A workspace's mesh is shaded by the vertex normals its PLY carries (meshing writes the TSDF's
// gradients), and flat without them.
TEST(WorkspaceScene, APlyWithVertexNormalsIsShadedSmoothly) {
  for (const bool with_normals : {true, false}) {
    test::TempDir dir;
    TriangleMesh mesh;
    mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    mesh.faces = {{0, 1, 2}};
    if (with_normals) mesh.normals = {{0, 0, 1}, {0, 0.6f, 0.8f}, {0.6f, 0, 0.8f}};
    WritePly(dir / "mesh.ply", mesh);
    const LoadedScene loaded = LoadSceneOrWorkspace(dir.path());
    ASSERT_EQ(loaded.scene.meshes.size(), 1u);
    EXPECT_EQ(loaded.scene.meshes[0].smooth_shading, with_normals);
    if (with_normals) {
      ASSERT_EQ(loaded.scene.meshes[0].mesh.normals.size(), 3u);
      EXPECT_TRUE(loaded.scene.meshes[0].mesh.normals[1].isApprox(Vector3f(0, 0.6f, 0.8f), 1e-6f));
    }
  }
}

}  // namespace
}  // namespace genscene::render
