// Scene files through render/formats/scene_io (LoadScene): our JSON format (GENSCENE_FUZZ_SCENE_XML
// undefined) or Mitsuba 3 XML (defined). The meshes a seed scene refers to are written once next
// to the scratch file, so that fuzzed variants of the seed reach past the mesh references.
#include "fuzz/fuzz_util.h"
#include "render/formats/mitsuba_xml.h"
#include "render/formats/scene_io.h"
#include "render/procedural.h"

using namespace genscene;
using namespace genscene::render;

namespace {

#ifdef GENSCENE_FUZZ_SCENE_XML
constexpr const char* kName = "scene.xml";
#else
constexpr const char* kName = "scene.json";
#endif

// A floor, an emitting quad above it, a point light and one view: every kind of element, and
// small meshes (each execution reads them).
void WriteScene(const std::filesystem::path& path) {
  Scene scene;
  SceneMesh floor;
  floor.name = "floor";
  floor.mesh.vertices = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  floor.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  floor.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f(0.7f, 0.6f, 0.5f));
  SceneMesh lamp;
  lamp.name = "lamp";
  lamp.mesh.vertices = {
      {-0.2f, -0.2f, 1.5f}, {-0.2f, 0.2f, 1.5f}, {0.2f, 0.2f, 1.5f}, {0.2f, -0.2f, 1.5f}};
  lamp.mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  lamp.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Zero());
  lamp.emission = Eigen::Vector3f(4.0f, 4.0f, 3.0f);
  scene.meshes = {floor, lamp};
  scene.point_lights.push_back({Eigen::Vector3d(0.5, 0.5, 1.0), Eigen::Vector3f(1.0f, 1.0f, 1.0f)});
  std::vector<PosedView> views = CornellLightViews(8, 6);
  views.resize(1);
#ifdef GENSCENE_FUZZ_SCENE_XML
  ExportMitsubaXml(path, scene, views);
#else
  SaveSceneJson(path, scene, views);
#endif
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::MaybeWriteSeeds([](const std::filesystem::path& dir) { WriteScene(dir / kName); });
  WriteScene(fuzz::ScratchDir() / kName);  // the meshes next to the scratch file
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = fuzz::Scratch(kName, data, size);
#ifdef GENSCENE_FUZZ_SCENE_XML
  // An analytic sphere becomes an icosphere: at the default level 5 (20480 triangles) its
  // tessellation took most of the time on the seeds that have one (80 executions/s); level 1
  // runs the same parser code.
  MitsubaImportOptions options;
  options.sphere_subdivision_level = 1;
  GENSCENE_FUZZ_EXPECT_ERROR_OK(ImportMitsubaXml(path, options));
#else
  GENSCENE_FUZZ_EXPECT_ERROR_OK(LoadScene(path));
#endif
  return 0;
}
