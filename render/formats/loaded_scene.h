// What a scene file holds besides the scene: its cameras and render settings. Shared by the
// loaders of render/formats (scene_io.h, mitsuba_xml.h).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "render/scene.h"

namespace genscene::render {

// The pixel reconstruction filter of a render (Mitsuba's rfilter).
struct PixelFilter {
  enum class Kind { kBox, kGaussian };
  Kind kind = Kind::kBox;  // box: each pixel is the plain mean of its own samples
  double stddev = 0.5;     // gaussian: standard deviation in pixels, truncated at 4 stddev
};

// Render settings a scene file may carry; unset = not given.
struct RenderSettings {
  std::optional<std::string> integrator;  // "path" or "direct"
  // Longest path in vertices after the camera, as Mitsuba counts: 1 = emitters seen directly,
  // 2 = direct lighting, -1 = unbounded. "direct" is recorded as 2.
  std::optional<int> max_depth;
  std::optional<int> samples_per_pixel;
  std::optional<PixelFilter> pixel_filter;
  std::optional<double> near_clip;  // metres (scene units) along the camera axis
  std::optional<double> far_clip;
  std::optional<bool> hide_emitters;  // camera rays that hit an emitter see black (Mitsuba's)
};

struct LoadedScene {
  Scene scene;
  std::vector<PosedView> views;  // in file order; timestamps 0, 1, 2... unless the file gives them
  RenderSettings settings;
  std::vector<std::string> warnings;  // one line each, for the app to print (never fatal)
};

}  // namespace genscene::render
