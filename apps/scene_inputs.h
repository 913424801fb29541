// Inputs the inverse apps (genscene-lights, genscene-refine) share: the scene geometry with its
// albedo, from a scene file or a mesh PLY (+ Mesh Colors albedo), and posed images.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/workspace.h"
#include "inverse/lights/light_estimation.h"
#include "render/scene.h"

namespace genscene::apps {

struct GeometryInputs {
  std::filesystem::path scene;   // scene file (.xml Mitsuba 3 subset or .json); or, when empty,
  std::filesystem::path mesh;    // a mesh PLY (empty = the workspace's mesh.ply)
  std::filesystem::path albedo;  // with `mesh`: a .mcol (empty = the workspace's albedo.mcol if
                                 // present, else the PLY's face / vertex colours, else grey 0.5)
};

// The scene file's scene (lights included), or one mesh with its albedo. Throws Error naming the
// file that is missing or bad; adds notes (e.g. "assuming grey") to `warnings`.
render::Scene LoadGeometry(const GeometryInputs& inputs, const Workspace& ws,
                           std::vector<std::string>* warnings);

}  // namespace genscene::apps
