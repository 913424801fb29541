#include "viewer/viewer_options.h"

#include "viewer/renderer.h"
#include "viewer/view_camera.h"

namespace genscene::viewer {

void ViewerOptions::Validate() const {
  ParseCameraSpec(camera);
  ParseSize(size);
  if (!mode.empty()) ParseColorMode(mode);
  RequireOneOf("lookup", lookup, {"nearest", "linear"});
}

}  // namespace genscene::viewer
