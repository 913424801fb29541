#include "apps/synth.h"

#include <cmath>
#include <spdlog/spdlog.h>

#include "core/check.h"
#include "core/file_util.h"
#include "core/options.h"
#include "core/ply_io.h"
#include "core/sequence_writer.h"
#include "core/synthetic.h"

namespace genscene::apps {

namespace {

std::pair<long long, long long> ParseSize(const std::string& size) {
  const auto x = size.find('x');
  if (x == std::string::npos) throw Error(Format("option size = '", size, "' is not WxH (e.g. 160x120)"));
  return {ParseInteger(size.substr(0, x), "option size"), ParseInteger(size.substr(x + 1), "option size")};
}

}  // namespace

void SynthOptions::Validate() const {
  if (scene != "cornell") {
    throw Error(Format("option scene = '", scene, "': only the built-in 'cornell' scene is available "
                       "(room and Mitsuba XML scenes come with the path tracer)"));
  }
  RequireRange("frames", frames, 1, 100000);
  const auto [w, h] = ParseSize(size);
  if (w < 8 || h < 8 || w > 4096 || h > 4096) {
    throw Error(Format("option size = '", size, "': width and height must be in [8, 4096]"));
  }
  RequireOneOf("noise", noise, {"none", "kinect"});
  RequireRange("fov", fov, 10.0, 150.0);
  RequireRange("arc", arc, 0.0, 360.0);
}

int SynthOptions::Width() const { return static_cast<int>(ParseSize(size).first); }
int SynthOptions::Height() const { return static_cast<int>(ParseSize(size).second); }

SynthSummary Synthesize(const SynthOptions& options, uint64_t seed, const std::filesystem::path& out_dir) {
  options.Validate();
  const SyntheticScene scene = MakeCornellScene();
  CameraIntrinsics k;
  k.width = options.Width();
  k.height = options.Height();
  k.fx = k.fy = 0.5 * k.width / std::tan(0.5 * options.fov * M_PI / 180.0);
  k.cx = 0.5 * (k.width - 1);
  k.cy = 0.5 * (k.height - 1);

  // Inside the closed room, orbiting its centre so that every pixel sees a surface.
  const Trajectory orbit = MakeOrbitTrajectory({0.0, 0.0, 0.6}, 0.9, 1.0, options.arc, options.frames);
  std::vector<RgbdFrame> frames;
  SynthSummary summary;
  summary.min_depth = INFINITY;
  for (size_t i = 0; i < orbit.size(); ++i) {
    const StampedPose& p = orbit.poses()[i];
    RgbdFrame frame = RenderSyntheticFrame(scene, k, p.world_from_camera, p.timestamp);
    if (options.noise == "kinect") AddKinectDepthNoise(frame.depth, seed, i);
    for (float z : frame.depth.pixels()) {
      if (z <= 0.0f) continue;
      summary.min_depth = std::min<double>(summary.min_depth, z);
      summary.max_depth = std::max<double>(summary.max_depth, z);
    }
    frames.push_back(std::move(frame));
    spdlog::debug("synth: frame {}/{}", i + 1, orbit.size());
  }
  const TriangleMesh mesh = scene.ToMesh();
  TumWriteOptions write;
  write.linear_exr = true;
  write.extra_files = [&](const std::filesystem::path& tmp) { WritePly(tmp / "mesh_gt.ply", mesh); };
  WriteTumSequence(out_dir, frames, write);
  summary.frames = static_cast<int>(frames.size());
  summary.width = k.width;
  summary.height = k.height;
  summary.mesh_vertices = mesh.vertices.size();
  summary.mesh_faces = mesh.faces.size();
  return summary;
}

}  // namespace genscene::apps
