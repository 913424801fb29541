// glTF 2.0 binary export: the .glb read back here (container, JSON, accessors against the mesh,
// cameras and lights) and by an independent reader, `assimp info` (Debian's assimp-utils).
#include "render/formats/gltf_export.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <regex>

#include "tests/test_util.h"

namespace genscene::render {
namespace {

using test::ErrorOf;
using Json = nlohmann::json;

// A 2 x 2 grid of quads (8 triangles) on z = 0 with vertex normals, and Mesh Colors of varied
// resolutions.
struct Model {
  TriangleMesh mesh;
  MeshColors albedo, observed;
  VoxelLightGrid lights;
  std::vector<PosedView> views;
};

Model MakeModel() {
  Model m;
  for (int y = 0; y <= 2; ++y) {
    for (int x = 0; x <= 2; ++x) m.mesh.vertices.emplace_back(0.5f * x, 0.5f * y, 0.0f);
  }
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 2; ++x) {
      const int a = 3 * y + x, b = a + 1, c = a + 3, d = c + 1;
      m.mesh.faces.emplace_back(a, b, d);
      m.mesh.faces.emplace_back(a, d, c);
    }
  }
  m.mesh.ComputeVertexNormals();
  m.albedo = MeshColors(m.mesh, {1, 2, 4, 8, 4, 2, 1, 8});
  for (size_t s = 0; s < m.albedo.SampleCount(); ++s) {
    m.albedo.colors()[s] = Eigen::Vector3f(0.2f + 0.6f * (s % 2), 0.5f, 0.1f * (s % 7));
  }
  m.observed = MeshColors(m.mesh, std::vector<int>(8, 4));
  for (Eigen::Vector3f& c : m.observed.colors()) c = Eigen::Vector3f(0.3f, 0.6f, 0.9f);
  m.lights.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 1, 2));
  m.lights.dims = Eigen::Vector3i(2, 1, 1);
  m.lights.intensity = {Eigen::Vector3f(2.0f, 1.0f, 0.5f), Eigen::Vector3f(0.0f, 4.0f, 4.0f)};
  m.lights.weights = {{1, 1, 1, 1, 1, 1}, {0, 0, 0, 0, 0, 1}};
  for (int v = 0; v < 2; ++v) {
    PosedView view;
    view.intrinsics = CameraIntrinsics::Centered(64, 48, 50.0);
    view.world_from_camera.translation() = Eigen::Vector3d(0.5 * v, 0.5, -1.5);
    view.world_from_camera.linear() =
        Eigen::AngleAxisd(0.2 * v, Eigen::Vector3d::UnitY()).toRotationMatrix();
    view.timestamp = 0.5 * v;
    m.views.push_back(view);
  }
  return m;
}

uint32_t U32(const std::string& data, size_t offset) {
  uint32_t v;
  std::memcpy(&v, data.data() + offset, 4);
  return v;
}

struct Glb {
  Json json;
  std::string bin;
};

// Reads the container, checking header and chunks as the glTF 2.0 specification has them.
Glb ReadGlb(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  const std::string data((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  Glb glb;
  EXPECT_GE(data.size(), 28u);
  if (data.size() < 28) return glb;
  EXPECT_EQ(data.substr(0, 4), "glTF");
  EXPECT_EQ(U32(data, 4), 2u);
  EXPECT_EQ(U32(data, 8), data.size());
  const uint32_t json_length = U32(data, 12);
  EXPECT_EQ(data.substr(16, 4), "JSON");
  EXPECT_EQ(json_length % 4, 0u);
  const std::string json = data.substr(20, json_length);
  EXPECT_EQ(json.find_last_not_of(' '), json.find_last_of('}'));  // padded with spaces
  glb.json = Json::parse(json);
  const size_t bin_at = 20 + json_length;
  EXPECT_EQ(data.substr(bin_at + 4, 4), std::string("BIN\0", 4));
  const uint32_t bin_length = U32(data, bin_at);
  EXPECT_EQ(bin_length % 4, 0u);
  EXPECT_EQ(bin_at + 8 + bin_length, data.size());
  glb.bin = data.substr(bin_at + 8, bin_length);
  return glb;
}

// The bytes of accessor `a` (tightly packed floats or uints).
template <typename T>
std::vector<T> AccessorData(const Glb& glb, int a, int components) {
  const Json& accessor = glb.json["accessors"][a];
  const Json& view = glb.json["bufferViews"][accessor["bufferView"].get<int>()];
  const size_t count = accessor["count"].get<size_t>() * components;
  EXPECT_EQ(view["byteLength"].get<size_t>(), count * sizeof(T));
  std::vector<T> out(count);
  std::memcpy(out.data(), glb.bin.data() + view["byteOffset"].get<size_t>(), count * sizeof(T));
  return out;
}

TEST(GltfExportTest, GlbHoldsTheMeshTexturesCamerasAndLights) {
  const Model m = MakeModel();
  test::TempDir dir;
  const auto path = dir / "model.glb";
  const GltfExportSummary s = ExportGltf(path, m.mesh, m.albedo, &m.observed, &m.lights, m.views);
  EXPECT_EQ(s.cameras, 2);
  EXPECT_EQ(s.lights, 2);
  EXPECT_TRUE(s.observed);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  EXPECT_EQ(s.bytes, std::filesystem::file_size(path));
  const Glb glb = ReadGlb(path);
  const Json& j = glb.json;
  EXPECT_EQ(j["asset"]["version"], "2.0");
  EXPECT_LE(j["buffers"][0]["byteLength"].get<size_t>(), glb.bin.size());
  ASSERT_EQ(j["meshes"].size(), 1u);
  const Json& primitive = j["meshes"][0]["primitives"][0];
  const size_t corners = 3 * m.mesh.faces.size();
  for (const char* a : {"POSITION", "NORMAL", "TEXCOORD_0"}) {
    EXPECT_EQ(j["accessors"][primitive["attributes"][a].get<int>()]["count"], corners) << a;
  }
  EXPECT_EQ(j["accessors"][primitive["indices"].get<int>()]["count"], corners);
  const auto positions = AccessorData<float>(glb, primitive["attributes"]["POSITION"], 3);
  const auto uvs = AccessorData<float>(glb, primitive["attributes"]["TEXCOORD_0"], 2);
  const auto indices = AccessorData<uint32_t>(glb, primitive["indices"], 1);
  for (size_t c = 0; c < corners; ++c) {
    const Eigen::Vector3f& p = m.mesh.vertices[m.mesh.faces[c / 3][c % 3]];
    EXPECT_EQ(Eigen::Vector3f(positions[3 * c], positions[3 * c + 1], positions[3 * c + 2]), p);
    EXPECT_TRUE(uvs[2 * c] > 0 && uvs[2 * c] < 1 && uvs[2 * c + 1] > 0 && uvs[2 * c + 1] < 1);
    EXPECT_EQ(indices[c], c);
  }
  // Materials: albedo (metallic 0, roughness 1) and the unlit observed variant, PNG textures.
  ASSERT_EQ(j["materials"].size(), 2u);
  EXPECT_EQ(j["materials"][0]["pbrMetallicRoughness"]["metallicFactor"], 0.0);
  EXPECT_EQ(j["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"], 1.0);
  EXPECT_TRUE(j["materials"][1]["extensions"].contains("KHR_materials_unlit"));
  EXPECT_EQ(primitive["extensions"]["KHR_materials_variants"]["mappings"].size(), 2u);
  ASSERT_EQ(j["images"].size(), 2u);
  for (const Json& image : j["images"]) {
    const Json& view = j["bufferViews"][image["bufferView"].get<int>()];
    EXPECT_EQ(glb.bin.substr(view["byteOffset"].get<size_t>(), 8), "\x89PNG\r\n\x1a\n");
  }
  // Cameras: yfov from fy and the height; the glTF camera's -z is the OpenCV camera's +z.
  ASSERT_EQ(j["cameras"].size(), 2u);
  EXPECT_NEAR(j["cameras"][0]["perspective"]["yfov"].get<double>(), 2 * std::atan(24.0 / 50.0),
              1e-12);
  EXPECT_NEAR(j["cameras"][0]["perspective"]["aspectRatio"].get<double>(), 64.0 / 48.0, 1e-12);
  int camera_nodes = 0, light_nodes = 0;
  for (const Json& node : j["nodes"]) {
    if (node.contains("camera")) {
      const int v = camera_nodes++;
      const auto& r = node["rotation"];
      const Eigen::Quaterniond q(r[3].get<double>(), r[0].get<double>(), r[1].get<double>(),
                                 r[2].get<double>());
      const Eigen::Matrix3d& truth = m.views[v].world_from_camera.linear();
      EXPECT_LT((q * Eigen::Vector3d(0, 0, -1) - truth.col(2)).norm(), 1e-9);
      EXPECT_LT((q * Eigen::Vector3d(0, 1, 0) + truth.col(1)).norm(), 1e-9);
      EXPECT_NEAR(node["translation"][0].get<double>(), 0.5 * v, 1e-12);
    }
    if (node.contains("extensions")) ++light_nodes;
  }
  EXPECT_EQ(camera_nodes, 2);
  EXPECT_EQ(light_nodes, 2);
  // Lights: the voxel's power over 4 pi sr, I = L sum(lambda) / 4.
  const Json& lights = j["extensions"]["KHR_lights_punctual"]["lights"];
  ASSERT_EQ(lights.size(), 2u);
  EXPECT_EQ(lights[0]["type"], "point");
  EXPECT_NEAR(lights[0]["intensity"].get<double>(), 2.0 * 6 / 4, 1e-6);
  EXPECT_NEAR(lights[0]["color"][2].get<double>(), 0.25, 1e-6);
  EXPECT_NEAR(lights[1]["intensity"].get<double>(), 4.0 / 4, 1e-6);
  EXPECT_EQ(lights[1]["extras"]["weights"][5], 1.0);
}

// The integer after `label` in assimp's output, or -1.
int AssimpCount(const std::string& output, const std::string& label) {
  std::smatch match;
  if (!std::regex_search(output, match, std::regex(label + R"(:\s*(\d+))"))) return -1;
  return std::stoi(match[1]);
}

TEST(GltfExportTest, AssimpReadsTheGlb) {
  if (test::RunCommand("command -v assimp").exit_code != 0) {
    if (test::InCi()) FAIL() << "assimp not found: CI=true needs assimp-utils (install_deps.sh)";
    GTEST_SKIP() << "assimp not found (Debian package assimp-utils); skipping the outside reader";
  }
  const Model m = MakeModel();
  test::TempDir dir;
  const auto path = dir / "model.glb";
  ExportGltf(path, m.mesh, m.albedo, &m.observed, &m.lights, m.views);
  const test::CommandResult r = test::RunCommand("assimp info '" + path.string() + "' 2>&1", 60);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(AssimpCount(r.output, "Meshes"), 1) << r.output;
  EXPECT_GE(AssimpCount(r.output, "Materials"), 1) << r.output;
  EXPECT_GE(AssimpCount(r.output, R"(Textures \(embed\.\))"), 1) << r.output;
  EXPECT_EQ(AssimpCount(r.output, "Cameras"), 2) << r.output;
  EXPECT_EQ(AssimpCount(r.output, "Lights"), 2) << r.output;
  EXPECT_EQ(AssimpCount(r.output, "Faces"), 8) << r.output;
}

TEST(GltfExportTest, ErrorsNameTheFile) {
  const Model m = MakeModel();
  test::TempDir dir;
  const auto path = dir / "model.glb";
  TriangleMesh other = m.mesh;
  std::swap(other.faces[0][0], other.faces[0][1]);
  EXPECT_CONTAINS(ErrorOf([&] { ExportGltf(path, other, m.albedo, nullptr, nullptr, {}); }),
                  path.string() + ": the albedo Mesh Colors were made for another mesh");
  std::vector<PosedView> bad = m.views;
  bad[1].intrinsics.fy = -1.0;
  EXPECT_CONTAINS(ErrorOf([&] { ExportGltf(path, m.mesh, m.albedo, nullptr, nullptr, bad); }),
                  path.string() + ": camera 1");
  test::WriteFile(dir / "file", "x");
  const auto blocked = dir / "file" / "model.glb";
  EXPECT_CONTAINS(ErrorOf([&] { ExportGltf(blocked, m.mesh, m.albedo, nullptr, nullptr, {}); }),
                  "model.glb");
  EXPECT_FALSE(std::filesystem::exists(path));
}

// Without observed colours, lights or cameras: one material, no extensions; fx != fy warns.
TEST(GltfExportTest, MinimalModelAndWarnings) {
  const Model m = MakeModel();
  test::TempDir dir;
  std::vector<PosedView> views = {m.views[0]};
  views[0].intrinsics.fx = 60.0;
  const GltfExportSummary s =
      ExportGltf(dir / "model.glb", m.mesh, m.albedo, nullptr, nullptr, views);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_CONTAINS(s.warnings[0], "fx != fy");
  const Glb glb = ReadGlb(dir / "model.glb");
  EXPECT_EQ(glb.json["materials"].size(), 1u);
  EXPECT_FALSE(glb.json.contains("extensionsUsed"));
  EXPECT_EQ(glb.json["cameras"].size(), 1u);
  EXPECT_EQ(glb.json["cameras"][0]["extras"]["fx"], 60.0);
}

}  // namespace
}  // namespace genscene::render
