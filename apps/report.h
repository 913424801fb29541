// `genscene report WORKSPACE`: a self-contained Markdown report of speed against error for every
// stage the workspace holds, with PNG figures (apps/plot.h) and the images it refers to copied
// next to it, in WS/report/:
//   - the run's summary table (WS/summary.json, written by `genscene run` / `demo`);
//   - tracking: per-frame time and, with a ground truth, per-frame position error and the ATE;
//   - meshing, texturing, albedo: their figures;
//   - lights: per-round cost, active voxels and time; training renders next to the keyframes;
//     with `sweep`, light error, active voxels and time against the penalty weight (Fig. 3);
//   - refinement: cost and image error per iteration, the renders after each iteration (Fig. 4);
//   - evaluation: novel views of the ground truth next to the model's, and their error.
// Beside it, report.html: the same report as a page, with the model in 3D (apps/report_html.h).
#pragma once

#include <filesystem>
#include <string>

#include "apps/report_html.h"
#include "core/workspace.h"

namespace genscene::apps {

struct ReportOptions {
  bool sweep = false;  // re-estimate the lights over penalty weights (Fig. 3)
  int sweep_spp = 32;  // samples per pixel of the sweep's renders
  std::filesystem::path three_dir = kDebianThreeDir;  // three.js for report.html's 3D view
};

// Writes WS/report/report.md, then report.html, and their figures; returns report.md's path. Throws
// Error when the workspace holds none of the stages' outputs.
std::filesystem::path WriteReport(const Workspace& ws, const ReportOptions& options, uint64_t seed);

}  // namespace genscene::apps
