// The viewer's window (GLFW, OpenGL 3.3 core): the interactive loop with orbit / pan / zoom and
// key bindings, and the one-frame screenshot. GLFW needs a display: under no display, an
// X server such as `xvfb-run -a` provides one (DESIGN.md §5).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>

#include "core/check.h"
#include "core/image.h"
#include "viewer/renderer.h"
#include "viewer/view_camera.h"
#include "viewer/view_data.h"

namespace genscene::viewer {

// No display could be reached (GLFW's message inside).
class NoDisplayError : public Error {
 public:
  using Error::Error;
};

// Renders one frame of `view` into an offscreen float framebuffer of a hidden window and returns
// it as a linear image (row 0 at the top). Throws NoDisplayError without a display.
ImageRgb RenderScreenshot(const ViewData& data, const PosedView& view, const DrawOptions& options);

// The key bindings, one per line, as printed on start and on H.
std::string KeyHelp();

// Opens a window of `view`'s image size on `data` and runs until it is closed (Esc or Q).
// Throws NoDisplayError without a display.
void RunInteractive(const ViewData& data, const PosedView& view, const DrawOptions& options);

}  // namespace genscene::viewer
