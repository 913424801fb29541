#include "apps/scene_inputs.h"

#include "core/check.h"
#include "core/frame_source.h"
#include "core/mesh_colors.h"
#include "core/ply_io.h"
#include "render/formats/scene_io.h"

namespace genscene::apps {

namespace fs = std::filesystem;
using namespace genscene::inverse;
using namespace genscene::render;

namespace {

// Albedo from Mesh Colors (linear lookup), clamped to [0, 1].
class MeshColorsAlbedo : public AlbedoField {
 public:
  explicit MeshColorsAlbedo(MeshColors colors) : colors_(std::move(colors)) {}
  Eigen::Vector3f Eval(int face, float b1, float b2) const override {
    return colors_.Linear(face, b1, b2).cwiseMax(0.0f).cwiseMin(1.0f);
  }

 private:
  MeshColors colors_;
};

}  // namespace

Scene LoadGeometry(const GeometryInputs& in, const Workspace& ws,
                   std::vector<std::string>* warnings) {
  if (!in.scene.empty()) {
    LoadedScene loaded = LoadScene(in.scene);
    for (std::string& w : loaded.warnings) warnings->push_back(std::move(w));
    return loaded.scene;
  }
  const fs::path mesh_path = in.mesh.empty() ? ws.Mesh() : in.mesh;
  if (!fs::exists(mesh_path))
    throw Error(Format(mesh_path.string(), ": no such mesh (run genscene-mesh, or give --mesh)"));
  SceneMesh m;
  m.name = mesh_path.stem().string();
  m.mesh = ReadPly(mesh_path);
  const fs::path albedo =
      !in.albedo.empty() ? in.albedo : (fs::exists(ws.Albedo()) ? ws.Albedo() : fs::path());
  if (!albedo.empty()) {
    m.albedo.kind = SurfaceAlbedo::Kind::kField;
    m.albedo.field = std::make_shared<MeshColorsAlbedo>(ReadMeshColors(albedo, m.mesh));
  } else {
    m.albedo = SurfaceAlbedo::FromMesh(m.mesh, Eigen::Vector3f::Constant(0.5f));
    if (m.mesh.face_colors.empty() && m.mesh.vertex_colors.empty()) {
      warnings->push_back(Format(mesh_path.string(),
                                 ": no albedo given and no colours in the PLY; assuming grey 0.5"));
    }
  }
  Scene scene;
  scene.meshes.push_back(std::move(m));
  return scene;
}

}  // namespace genscene::apps
