// A genscene workspace as a scene: the model the chain estimated, rendered as any scene file is.
#pragma once

#include <filesystem>

#include "render/formats/loaded_scene.h"

namespace genscene::render {

// The workspace's model: mesh_refined.ply when present, else mesh.ply, named "model"; its albedo
// from albedo.mcol (else the PLY's colours, else grey 0.5, with a warning); the voxel lights of
// lights.json when present (else a warning: the render sees no light); the keyframe cameras of
// keyframes/ as the scene's views. Throws Error naming the file when the folder holds no mesh or a
// file is bad.
LoadedScene LoadWorkspaceScene(const std::filesystem::path& folder);

// True when `folder` is a directory holding a genscene workspace's mesh.ply.
bool IsWorkspaceFolder(const std::filesystem::path& folder);

// A workspace folder's model (LoadWorkspaceScene), else the scene file (LoadScene).
LoadedScene LoadSceneOrWorkspace(const std::filesystem::path& path);

}  // namespace genscene::render
