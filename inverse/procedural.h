// Built-in scenes for genscene-synth and the demo: path-traceable versions of core's analytic
// scenes, with area lights.
#pragma once

#include "inverse/scene.h"

namespace genscene::inverse {

// The Cornell-box-like room of core/synthetic.h (2 m, z up, red -x wall, green +x wall, a white
// box and a yellow sphere) lit by a 0.5 x 0.5 m area light just under the ceiling, facing down.
Scene MakeCornellBoxScene();

// A 5 x 4 x 2.6 m living room (z up): grey floor, off-white walls, a table, a sofa, a cabinet and
// a ball, lit by a ceiling panel and a warm lamp on the cabinet.
Scene MakeRoomScene();

// The light-estimation replica of the paper's Fig. 3 (issue 7): five views inside the Cornell box
// of MakeCornellBoxScene, `width` x `height`, 60 degrees horizontal field of view; the first three
// are the training views, the last two the novel views.
std::vector<View> CornellLightViews(int width, int height);

}  // namespace genscene::inverse
