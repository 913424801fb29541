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
  const fs::path albedo = !in.albedo.empty()
                              ? in.albedo
                              : (fs::exists(ws.ModelAlbedo()) ? ws.ModelAlbedo() : fs::path());
  if (!albedo.empty()) {
    m.albedo = SurfaceAlbedo::FromMeshColors(ReadMeshColors(albedo, m.mesh));
  } else {
    m.albedo = SurfaceAlbedo::FromMesh(m.mesh, Eigen::Vector3f::Constant(0.5f));
    if (m.mesh.face_colors.empty() && m.mesh.vertex_colors.empty()) {
      warnings->push_back(Format(mesh_path.string(),
                                 ": no albedo given and no colours in the PLY; assuming grey 0.5"));
    }
  }
  // Per-vertex normals in the PLY (meshing's TSDF gradients, the refined mesh's) shade it smoothly,
  // as MeshLab and Blender show it.
  m.smooth_shading = m.mesh.normals.size() == m.mesh.vertices.size();
  Scene scene;
  scene.meshes.push_back(std::move(m));
  return scene;
}

}  // namespace genscene::apps
