// Line plots as PNG for `genscene report`, drawn with OpenCV (no Python needed): axes with ticks,
// a grid, one coloured polyline with markers per series and a legend.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace genscene::apps {

struct PlotSeries {
  std::string name;
  std::vector<double> x, y;  // same length; non-finite points are left out
};

struct PlotSpec {
  std::string title, x_label, y_label;
  bool log_x = false, log_y = false;  // log axes drop points <= 0
  int width = 640, height = 400;
};

// Writes the plot atomically. Throws Error when no series has a finite point.
void WritePlot(const std::filesystem::path& png, const PlotSpec& spec,
               const std::vector<PlotSeries>& series);

}  // namespace genscene::apps
