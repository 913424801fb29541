#include "render/formats/workspace_scene.h"

#include <memory>

#include "core/check.h"
#include "core/light_set.h"
#include "core/mesh_colors.h"
#include "core/ply_io.h"
#include "core/view_set.h"
#include "core/workspace.h"
#include "render/formats/scene_io.h"

namespace genscene::render {

namespace fs = std::filesystem;

bool IsWorkspaceFolder(const fs::path& folder) {
  std::error_code ec;
  return fs::is_directory(folder, ec) && fs::exists(Workspace(folder).Mesh(), ec);
}

LoadedScene LoadWorkspaceScene(const fs::path& folder) {
  const Workspace ws(folder);
  if (!fs::is_directory(folder)) throw Error(Format(folder.string(), ": no such workspace folder"));
  const fs::path mesh_path = ws.ModelMesh();
  if (!fs::exists(mesh_path)) {
    throw Error(Format(folder.string(),
                       ": not a workspace with a model (no mesh.ply; run genscene "
                       "run, or genscene-fuse and genscene-mesh)"));
  }
  LoadedScene out;
  SceneMesh m;
  m.name = "model";
  m.mesh = ReadPly(mesh_path);
  if (fs::exists(ws.ModelAlbedo())) {
    m.albedo = SurfaceAlbedo::FromMeshColors(ReadMeshColors(ws.ModelAlbedo(), m.mesh));
  } else {
    m.albedo = SurfaceAlbedo::FromMesh(m.mesh, Eigen::Vector3f::Constant(0.5f));
    out.warnings.push_back(Format(ws.Albedo().string(),
                                  ": no albedo (run genscene-albedo); using the mesh's colours"));
  }
  m.smooth_shading = m.mesh.normals.size() == m.mesh.vertices.size();  // as the PLY's normals say
  out.scene.meshes.push_back(std::move(m));
  if (fs::exists(ws.Lights())) {
    out.scene.voxel_lights = ReadLightsJson(ws.Lights());
  } else {
    out.warnings.push_back(
        Format(ws.Lights().string(), ": no lights (run genscene-lights); the render is black"));
  }
  if (fs::exists(ws.Keyframes() / "groundtruth.txt")) out.views = ReadViewSet(ws.Keyframes());
  out.scene.Validate();
  return out;
}

LoadedScene LoadSceneOrWorkspace(const fs::path& path) {
  return IsWorkspaceFolder(path) ? LoadWorkspaceScene(path) : LoadScene(path);
}

}  // namespace genscene::render
