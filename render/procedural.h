// Built-in scenes for genscene-synth and the demo: path-traceable versions of core's analytic
// scenes, with area lights.
#pragma once

#include "render/scene.h"

namespace genscene::render {

// The Cornell-box-like room of core/synthetic.h (2 m, z up, red -x wall, green +x wall, a white
// box and a yellow sphere) lit by a 0.5 x 0.5 m area light just under the ceiling, facing down.
Scene MakeCornellBoxScene();

// A 5 x 4 x 2.6 m living room (z up): grey floor, off-white walls, a table, a sofa, a cabinet and
// a ball, lit by a ceiling panel and a warm lamp on the cabinet.
Scene MakeRoomScene();

// A flat quad of constant albedo, corners a, b, c, d counter-clockwise seen from its front (two
// triangles a b c, a c d).
SceneMesh MakeQuad(const std::string& name, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                   const Eigen::Vector3f& c, const Eigen::Vector3f& d,
                   const Eigen::Vector3f& albedo);

// The light-estimation replica of the paper's Fig. 3: five views inside the Cornell box
// of MakeCornellBoxScene, `width` x `height`, 60 degrees horizontal field of view; the first three
// are the training views, the last two the novel views.
std::vector<PosedView> CornellLightViews(int width, int height);

// The vertex-refinement replica of the paper's Fig. 4, the scene of
// ../shared/data/cbox-cycles/icosphere_flat (and _smooth) built in code: the 1 m Cornell box
// (interior x, y in [-0.5, 0.5], z in [0, 1], open towards -y; red wall at x = -0.5, green at
// x = +0.5) lit by a 0.25 m square light under the ceiling (radiance (30, 24, 18)), with an
// icosphere (42 vertices, 80 faces, radius 0.2 m, albedo 0.8) standing on the floor, seen by one
// 106 x 80 view. The sphere's vertices are MakeUnitIcosphere(1)'s, not Blender's.
struct IcosphereBox {
  Scene scene;
  PosedView view;
  int sphere = -1;  // index of the icosphere in scene.meshes
  double radius = 0.2;
  Eigen::Vector3d center{0.0, 0.0, 0.201};
};
IcosphereBox MakeIcosphereBox(bool smooth_shading = false);

// The replica's perturbation: the vertex of `mesh` that faces `eye` most squarely is pushed out
// by `size` along its direction from `center` (a spike), and the next most facing vertex beyond
// the first one's one-ring (more than 0.75 `radius` away; icosphere edges are ~0.55 r) is pushed
// in by `size` (a dent). `positions` holds every vertex, (x, y, z) each, the two moved.
struct SpikeAndDent {
  Eigen::VectorXd positions;
  int spike = -1, dent = -1;
};
SpikeAndDent PerturbFacingVertices(const TriangleMesh& mesh, const Eigen::Vector3d& center,
                                   double radius, const Eigen::Vector3d& eye, double size);

}  // namespace genscene::render
