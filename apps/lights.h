// genscene-lights as a function, shared with `genscene run`: light estimation on a
// workspace or on given geometry, albedo and posed images.
//   inputs:  a scene file (Mitsuba XML or genscene JSON; its emitters and lights are ignored), or
//            a mesh PLY (albedo per face / vertex colour, or a Mesh Colors albedo .mcol), and a
//            view set or keyframes folder of posed images (EXR linear, PNG sRGB);
//   outputs: WS/lights.json (core/light_set.h), WS/lights/ (renders of the training and novel
//            views with the estimate: linear EXR + sRGB PNG), WS/lights/scene.xml (Mitsuba 3:
//            the geometry and the voxel lights as emissive cube faces).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/workspace.h"
#include "inverse/lights/light_estimation.h"

namespace genscene::apps {

struct LightsInputs {
  std::filesystem::path scene;  // scene file; or, when empty, `mesh` (+ `albedo`)
  std::filesystem::path mesh;   // empty = the workspace's mesh.ply
  std::filesystem::path
      albedo;  // .mcol; empty = the workspace's albedo.mcol if present, else the PLY's colours
  std::filesystem::path views;  // empty = the workspace's keyframes/
  std::filesystem::path novel;  // optional view set to judge the estimate on
  int render_spp = 64;          // samples per pixel of the output renders
};

struct LightsSummary {
  inverse::LightEstimate estimate;
  std::vector<inverse::ViewError> train, novel;  // renders against the images
  inverse::AmbientBaseline ambient;              // the baseline on the training views' pixels
  double train_rmse = 0.0;  // mean relative RMSE of the training renders, noise taken out
  std::vector<std::string> warnings;
};

LightsSummary LightsWorkspace(const LightsInputs& inputs,
                              const inverse::LightEstimationOptions& options, uint64_t seed,
                              const Workspace& ws);
std::string ToString(const LightsSummary& summary);

}  // namespace genscene::apps
