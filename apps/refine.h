// genscene-refine as a function: vertex refinement of a workspace's mesh or of chosen
// meshes of a scene file, against posed images, with the scene's lights (a scene file's emitters
// and point lights, and/or the voxel lights of a lights.json).
//   outputs: WS/mesh_refined.ply (the refined meshes, area-weighted normals), WS/refine/:
//            iter_NN.png (the model rendered from the first view after each iteration) and
//            iter_NN_shading.png (the same with every albedo grey: shading only, as the paper's
//            Fig. 4), report.json (cost, image error, step, vertex errors per iteration).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "apps/scene_inputs.h"
#include "inverse/refine/vertex_refinement.h"

namespace genscene::apps {

struct RefineInputs {
  GeometryInputs geometry;
  std::filesystem::path lights;     // lights.json; empty = the workspace's when geometry is a mesh
  std::filesystem::path views;      // empty = the workspace's keyframes/
  std::vector<std::string> refine;  // names of the meshes to refine; empty = every non-emitter
  std::filesystem::path truth;      // optional PLY: true positions of the refined vertices
  int render_spp = 32;              // samples per pixel of the per-iteration renders (0 = none)
};

struct RefineSummary {
  inverse::RefineResult result;
  std::vector<std::string> refined;  // names of the refined meshes
  int vertices = 0;
  std::vector<double> vertex_rms, vertex_max;  // per iteration, when a truth is given (m)
  int flipped_faces = 0;                       // against the starting mesh
  // The baseline: the unrefined and the refined mesh on a fresh sample of pixels; when the refined
  // one fits them worse, the unrefined mesh is what the stage writes (kept_unrefined, a warning).
  inverse::HeldOutComparison held_out;
  bool kept_unrefined = false;
  // Why refinement did not run (the fit gate: the lights describe the keyframes worse than a
  // constant ambient light); empty when it ran.
  std::string skipped;
  std::vector<std::string> warnings;
};

RefineSummary RefineWorkspace(const RefineInputs& inputs, const inverse::RefineOptions& options,
                              uint64_t seed, const Workspace& ws);
std::string ToString(const RefineSummary& summary);

}  // namespace genscene::apps
