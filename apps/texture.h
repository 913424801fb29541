// genscene-texture and genscene-albedo as functions, shared with `genscene run`:
//   TextureWorkspace: mesh.ply + keyframes/ -> texture.mcol (observed colour as Mesh Colors,
//                     labels = keyframe samples per texel) + texture.ply (the same as vertex
//                     colours of the subdivided mesh, for MeshLab / Open3D / Blender);
//   AlbedoWorkspace:  mesh.ply + texture.mcol -> albedo.mcol (labels = cluster ids), albedo.ply,
//                     albedo.json (the clusters and the stage's figures).
#pragma once

#include <filesystem>
#include <string>

#include "core/frame_source.h"
#include "core/workspace.h"
#include "texturing/albedo.h"
#include "texturing/backproject.h"

namespace genscene::apps {

struct TextureInputs {
  std::filesystem::path mesh;   // empty = the workspace's mesh.ply
  std::filesystem::path views;  // keyframes folder or view set; empty = the workspace's keyframes/
};

struct TextureSummary {
  texturing::TexturingStats stats;
  size_t faces = 0;
  int max_resolution_used = 0;
  double mean_views_per_texel = 0.0;  // over observed texels
};

TextureSummary TextureWorkspace(const TextureInputs& inputs, const SourceOptions& source,
                                const texturing::TexturingOptions& options, const Workspace& ws);
std::string ToString(const TextureSummary& summary);

struct AlbedoSummary {
  texturing::AlbedoStats stats;
  std::vector<texturing::AlbedoCluster> clusters;
};

AlbedoSummary AlbedoWorkspace(const std::filesystem::path& mesh_path,
                              const texturing::AlbedoOptions& options, const Workspace& ws);
std::string ToString(const AlbedoSummary& summary);

}  // namespace genscene::apps
