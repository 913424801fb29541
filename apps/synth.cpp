#include "apps/synth.h"

#include <chrono>
#include <cmath>
#include <iostream>

#include "core/check.h"
#include "core/file_util.h"
#include "core/options.h"
#include "core/ply_io.h"
#include "core/sequence_writer.h"
#include "core/synthetic.h"
#include "render/formats/scene_io.h"
#include "render/path_tracer.h"
#include "render/procedural.h"

namespace genscene::apps {

namespace {

std::pair<long long, long long> ParseSize(const std::string& size) {
  const auto x = size.find('x');
  if (x == std::string::npos)
    throw Error(Format("option size = '", size, "' is not WxH (e.g. 160x120)"));
  return {ParseInteger(size.substr(0, x), "option size"),
          ParseInteger(size.substr(x + 1), "option size")};
}

bool IsSceneFile(const std::string& scene) {
  const std::string ext = std::filesystem::path(scene).extension().string();
  return ext == ".xml" || ext == ".json";
}

// All non-emitting meshes as one mesh with per-face albedo: the ground truth for fusion and
// meshing.
TriangleMesh GroundTruthMesh(const render::Scene& scene) {
  TriangleMesh out;
  for (const render::SceneMesh& m : scene.meshes) {
    if (m.IsEmitter()) continue;
    const int base = static_cast<int>(out.vertices.size());
    out.vertices.insert(out.vertices.end(), m.mesh.vertices.begin(), m.mesh.vertices.end());
    for (size_t f = 0; f < m.mesh.faces.size(); ++f) {
      out.faces.push_back(m.mesh.faces[f] + Eigen::Vector3i::Constant(base));
      out.face_colors.push_back(m.albedo.Eval(m.mesh, static_cast<int>(f), 1.0f / 3, 1.0f / 3));
    }
  }
  out.ComputeVertexNormals();
  return out;
}

// The scene and the trajectory through it: inside the built-in rooms, swaying around the scene
// file's first camera, or orbiting the scene's centre when the file has none.
struct Setup {
  render::Scene scene;
  Trajectory trajectory;
};

Setup MakeSetup(const SynthOptions& o, uint64_t seed) {
  Setup s;
  if (o.scene == "cornell") {
    s.scene = render::MakeCornellBoxScene();
    s.trajectory = MakeHandheldTrajectory({0.0, 0.0, 0.6}, 0.9, 1.0, o.arc, o.frames, seed);
  } else if (o.scene == "room") {
    s.scene = render::MakeRoomScene();
    s.trajectory = MakeHandheldTrajectory({0.0, 0.4, 0.7}, 1.6, 1.5, o.arc, o.frames, seed);
  } else {
    const render::LoadedScene loaded = render::LoadScene(o.scene);
    s.scene = loaded.scene;
    const Eigen::AlignedBox3d box = s.scene.Bounds();
    if (!loaded.views.empty()) {
      const Eigen::Isometry3d& first = loaded.views.front().world_from_camera;
      const Eigen::Vector3d eye = first.translation();
      const double distance = (box.center() - eye).norm();
      const Eigen::Vector3d target = eye + distance * first.linear().col(2);
      const Eigen::Vector3d offset = eye - target;
      const double radius = std::hypot(offset.x(), offset.y());
      s.trajectory = MakeHandheldTrajectory(target, radius, eye.z(), o.arc, o.frames, seed);
    } else {
      const double size = box.diagonal().norm();
      s.trajectory = MakeHandheldTrajectory(box.center(), 0.6 * size, box.center().z() + 0.2 * size,
                                            o.arc, o.frames, seed);
    }
  }
  return s;
}

}  // namespace

void SynthOptions::Validate() const {
  if (scene != "cornell" && scene != "room" && !IsSceneFile(scene)) {
    throw Error(
        Format("option scene = '", scene, "' is not cornell, room, or a .xml/.json scene file"));
  }
  RequireRange("frames", frames, 1, 100000);
  const auto [w, h] = ParseSize(size);
  if (w < 8 || h < 8 || w > 4096 || h > 4096) {
    throw Error(Format("option size = '", size, "': width and height must be in [8, 4096]"));
  }
  RequireOneOf("noise", noise, {"none", "kinect"});
  RequireRange("fov", fov, 10.0, 150.0);
  RequireRange("arc", arc, 0.0, 360.0);
  paths.Validate();
}

int SynthOptions::Width() const {
  return static_cast<int>(ParseSize(size).first);
}
int SynthOptions::Height() const {
  return static_cast<int>(ParseSize(size).second);
}

SynthSummary Synthesize(const SynthOptions& options, uint64_t seed,
                        const std::filesystem::path& out_dir) {
  options.Validate();
  const Setup setup = MakeSetup(options, seed);
  const CameraIntrinsics k =
      CameraIntrinsics::FromHorizontalFov(options.Width(), options.Height(), options.fov);

  const render::PathTracer tracer(setup.scene);
  const render::RenderOptions& render = options.paths;
  std::vector<RgbdFrame> frames;
  SynthSummary summary;
  summary.min_depth = INFINITY;
  const auto start = std::chrono::steady_clock::now();
  for (size_t i = 0; i < setup.trajectory.size(); ++i) {
    const StampedPose& p = setup.trajectory.poses()[i];
    const PosedView view{k, p.world_from_camera, p.timestamp};
    render::RenderOutput image = tracer.Render(view, render, seed * 1000003 + i);
    RgbdFrame frame;
    frame.timestamp = p.timestamp;
    frame.intrinsics = k;
    frame.world_from_camera = p.world_from_camera;
    frame.color = std::move(image.radiance);
    frame.depth = std::move(image.depth);
    if (options.noise == "kinect") AddKinectDepthNoise(frame.depth, seed, i);
    for (float z : frame.depth.pixels()) {
      if (z <= 0.0f) continue;
      summary.min_depth = std::min<double>(summary.min_depth, z);
      summary.max_depth = std::max<double>(summary.max_depth, z);
    }
    frames.push_back(std::move(frame));
    std::cerr << "\rsynth: rendered " << i + 1 << "/" << setup.trajectory.size() << " frames"
              << std::flush;
  }
  std::cerr << "\n";
  summary.render_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!std::isfinite(summary.min_depth)) summary.min_depth = 0.0;
  const TriangleMesh mesh = GroundTruthMesh(setup.scene);
  TumWriteOptions write;
  write.linear_exr = true;
  write.extra_files = [&](const std::filesystem::path& tmp) {
    WritePly(tmp / "mesh_gt.ply", mesh);
    render::SaveSceneJson(tmp / "scene.json", setup.scene);
  };
  WriteTumSequence(out_dir, frames, write);
  summary.frames = static_cast<int>(frames.size());
  summary.width = k.width;
  summary.height = k.height;
  summary.mesh_vertices = mesh.vertices.size();
  summary.mesh_faces = mesh.faces.size();
  return summary;
}

}  // namespace genscene::apps
