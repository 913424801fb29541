#include "core/rgbd_frame.h"

#include "core/check.h"
#include "core/image_io.h"

namespace genscene {

void RgbdFrame::Validate() const {
  const std::string name = !depth_path.empty()   ? depth_path
                           : !color_path.empty() ? color_path
                                                 : Format("frame at t=", timestamp);
  if (color.empty() && depth.empty())
    throw Error(Format(name, ": frame has neither colour nor depth"));
  intrinsics.Validate(name);
  if (!depth.empty() && !depth.SameSize(intrinsics.width, intrinsics.height)) {
    throw Error(Format(depth_path, ": depth ", depth.width(), "x", depth.height(),
                       " but intrinsics say ", intrinsics.width, "x", intrinsics.height));
  }
  if (!color.empty() && !color.SameSize(intrinsics.width, intrinsics.height)) {
    throw Error(Format(color_path, ": colour ", color.width(), "x", color.height(),
                       " but intrinsics say ", intrinsics.width, "x", intrinsics.height));
  }
  if (!depth.empty()) CheckDepthValues(depth, depth_path);
  if (world_from_camera && !world_from_camera->matrix().allFinite()) {
    throw Error(Format(name, ": pose is not finite"));
  }
}

}  // namespace genscene
