#include "viewer/view_data.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/light_set.h"
#include "core/ply_io.h"
#include "core/workspace.h"

namespace genscene::viewer {

namespace fs = std::filesystem;

namespace {

// Runs `load`; a missing file or an Error becomes one line in `missing`.
template <typename F>
void LoadPiece(const fs::path& path, const std::string& how_to_make,
               std::vector<std::string>* missing, F&& load) {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    missing->push_back(Format(path.filename().string(), ": missing (", how_to_make, ")"));
    return;
  }
  try {
    load();
  } catch (const Error& e) {
    missing->push_back(Format(path.filename().string(), ": not shown: ", e.what()));
  }
}

void PushVertex(std::vector<float>* out, const Eigen::Vector3d& p, const Eigen::Vector3f& rgb) {
  out->insert(out->end(), {static_cast<float>(p.x()), static_cast<float>(p.y()),
                           static_cast<float>(p.z()), rgb.x(), rgb.y(), rgb.z()});
}

void PushSegment(Overlay* overlay, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                 const Eigen::Vector3f& rgb) {
  PushVertex(&overlay->lines, a, rgb);
  PushVertex(&overlay->lines, b, rgb);
}

}  // namespace

ViewData LoadWorkspace(const fs::path& root) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw Error(Format(root.string(), ": no such workspace folder"));
  const Workspace ws(root);
  ViewData data;
  auto* missing = &data.missing;
  LoadPiece(ws.Mesh(), "run genscene-mesh", missing, [&] { data.mesh = ReadPly(ws.Mesh()); });
  if (data.mesh) {
    LoadPiece(ws.Texture(), "run genscene-texture", missing,
              [&] { data.observed = ReadMeshColors(ws.Texture(), *data.mesh); });
    LoadPiece(ws.ModelAlbedo(), "run genscene-albedo", missing,
              [&] { data.albedo = ReadMeshColors(ws.ModelAlbedo(), *data.mesh); });
  } else {
    for (const fs::path& p : {ws.Texture(), ws.Albedo()}) {
      if (fs::exists(p, ec))
        missing->push_back(Format(p.filename().string(), ": not shown without mesh.ply"));
    }
  }
  LoadPiece(ws.RefinedMesh(), "vertex refinement has not run", missing, [&] {
    TriangleMesh refined = ReadPly(ws.RefinedMesh());
    // Refinement moves vertices only; the Mesh Colors of mesh.ply then fit it face for face.
    if (!data.mesh || MeshFingerprint(refined) != MeshFingerprint(*data.mesh)) {
      throw Error("its vertex count or faces differ from mesh.ply's");
    }
    data.refined_mesh = std::move(refined);
  });
  LoadPiece(ws.Trajectory(), "run genscene-fuse", missing,
            [&] { data.trajectory = ReadTumTrajectory(ws.Trajectory()); });
  LoadPiece(ws.Keyframes(), "run genscene-fuse", missing,
            [&] { data.keyframes = ReadViewSet(ws.Keyframes()); });
  // Voxel lights: a glyph per active voxel (the estimate's threshold, kept in lights.json).
  LoadPiece(ws.Lights(), "light estimation has not run (genscene-lights)", missing, [&] {
    const VoxelLightGrid grid = ReadLightsJson(ws.Lights());
    for (int j : grid.ActiveVoxels()) {
      LightGlyph glyph;
      glyph.position = grid.VoxelCenter(j);
      glyph.power = grid.intensity[j];
      glyph.weights = grid.weights[j];
      data.lights.push_back(glyph);
    }
    if (grid.HasDistantLight()) {
      LightGlyph glyph;
      glyph.power = grid.distant_intensity;
      glyph.weights = grid.distant_weights;
      data.distant = glyph;
    }
  });
  return data;
}

Eigen::AlignedBox3d SceneBounds(const ViewData& data) {
  Eigen::AlignedBox3d box;
  for (const auto* mesh :
       {data.mesh ? &*data.mesh : nullptr, data.refined_mesh ? &*data.refined_mesh : nullptr}) {
    if (!mesh) continue;
    for (const Eigen::Vector3f& p : mesh->vertices) box.extend(p.cast<double>());
  }
  for (const StampedPose& p : data.trajectory.poses())
    box.extend(p.world_from_camera.translation());
  for (const PosedView& v : data.keyframes) box.extend(v.world_from_camera.translation());
  for (const LightGlyph& l : data.lights) box.extend(l.position);
  return box;
}

namespace {

std::vector<Eigen::Isometry3d> RecordingCameras(const ViewData& data) {
  std::vector<Eigen::Isometry3d> poses;
  for (const PosedView& v : data.keyframes) poses.push_back(v.world_from_camera);
  if (poses.empty()) {
    for (const StampedPose& p : data.trajectory.poses()) poses.push_back(p.world_from_camera);
  }
  return poses;
}

}  // namespace

Eigen::Vector3d WorkspaceUp(const ViewData& data) {
  return CamerasUp(RecordingCameras(data));
}

OrbitController Overview(const ViewData& data, const CameraIntrinsics& intrinsics) {
  Eigen::AlignedBox3d model;
  for (const auto* mesh :
       {data.mesh ? &*data.mesh : nullptr, data.refined_mesh ? &*data.refined_mesh : nullptr}) {
    if (!mesh) continue;
    for (const Eigen::Vector3f& p : mesh->vertices) model.extend(p.cast<double>());
  }
  return OverviewOrbit(model.isEmpty() ? SceneBounds(data) : model, intrinsics,
                       RecordingCameras(data));
}

PosedView ResolveCamera(const CameraSpec& spec, const ViewData& data, const Eigen::Vector2i& size) {
  PosedView view;
  view.intrinsics = DefaultIntrinsics(size.x(), size.y());
  switch (spec.kind) {
    case CameraSpec::Kind::kOverview:
      view.world_from_camera = Overview(data, view.intrinsics).WorldFromCamera();
      break;
    case CameraSpec::Kind::kPose:
      view.world_from_camera = spec.world_from_camera;
      break;
    case CameraSpec::Kind::kKeyframe: {
      if (spec.keyframe >= static_cast<int>(data.keyframes.size())) {
        throw Error(Format("--camera keyframe:", spec.keyframe, ": the workspace has ",
                           data.keyframes.size(), " keyframes (keyframe:0 to keyframe:",
                           static_cast<int>(data.keyframes.size()) - 1, ")"));
      }
      const PosedView& key = data.keyframes[spec.keyframe];
      view = key;
      const double sx = static_cast<double>(size.x()) / key.intrinsics.width;
      const double sy = static_cast<double>(size.y()) / key.intrinsics.height;
      view.intrinsics.width = size.x();
      view.intrinsics.height = size.y();
      view.intrinsics.fx *= sx;
      view.intrinsics.fy *= sy;
      view.intrinsics.cx = (key.intrinsics.cx + 0.5) * sx - 0.5;
      view.intrinsics.cy = (key.intrinsics.cy + 0.5) * sy - 0.5;
      break;
    }
  }
  return view;
}

MeshColorsTables BuildMeshColorsTables(const MeshColors& colors) {
  MeshColorsTables t;
  const int nf = colors.num_faces();
  t.face_table.resize(2 * static_cast<size_t>(nf));
  size_t total = 0;
  for (int f = 0; f < nf; ++f) {
    const size_t r = static_cast<size_t>(colors.FaceResolution(f));
    total += (r + 1) * (r + 2) / 2;
  }
  if (total > 0x7fffffffull) {
    throw Error(Format("viewer: Mesh Colors lattice of ", total,
                       " entries exceeds a 32-bit buffer texture index"));
  }
  t.lattice_index.reserve(total);
  for (int f = 0; f < nf; ++f) {
    const int r = colors.FaceResolution(f);
    t.face_table[2 * f] = static_cast<int32_t>(t.lattice_index.size());
    t.face_table[2 * f + 1] = r;
    for (int j = 0; j <= r; ++j) {
      for (int i = 0; i + j <= r; ++i) {
        t.lattice_index.push_back(static_cast<int32_t>(colors.SampleIndex(f, i, j)));
      }
    }
  }
  t.rgba.reserve(4 * colors.SampleCount());
  for (const Eigen::Vector3f& c : colors.colors())
    t.rgba.insert(t.rgba.end(), {c.x(), c.y(), c.z(), 1.0f});
  if (colors.labels().empty()) {
    t.labels.assign(colors.SampleCount(), -1);
  } else {
    t.labels.assign(colors.labels().begin(), colors.labels().end());
  }
  return t;
}

std::vector<float> UnindexedPositions(const TriangleMesh& mesh) {
  std::vector<float> out;
  out.reserve(9 * mesh.faces.size());
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3f& p = mesh.vertices[f[k]];
      out.insert(out.end(), {p.x(), p.y(), p.z()});
    }
  }
  return out;
}

void AddTrajectory(const Trajectory& trajectory, Overlay* overlay) {
  const Eigen::Vector3f orange(1.0f, 0.55f, 0.1f);
  const auto& poses = trajectory.poses();
  for (size_t i = 1; i < poses.size(); ++i) {
    PushSegment(overlay, poses[i - 1].world_from_camera.translation(),
                poses[i].world_from_camera.translation(), orange);
  }
}

void AddFrusta(const std::vector<PosedView>& keyframes, double depth, Overlay* overlay) {
  const Eigen::Vector3f cyan(0.1f, 0.85f, 0.9f);
  for (const PosedView& view : keyframes) {
    const CameraIntrinsics& k = view.intrinsics;
    const Eigen::Vector3d eye = view.world_from_camera.translation();
    // The image corners' pixel footprints at planar depth `depth`.
    const double us[4] = {-0.5, k.width - 0.5, k.width - 0.5, -0.5};
    const double vs[4] = {-0.5, -0.5, k.height - 0.5, k.height - 0.5};
    Eigen::Vector3d corner[4];
    for (int c = 0; c < 4; ++c)
      corner[c] = view.world_from_camera * k.Unproject(us[c], vs[c], depth);
    for (int c = 0; c < 4; ++c) {
      PushSegment(overlay, eye, corner[c], cyan);
      PushSegment(overlay, corner[c], corner[(c + 1) % 4], cyan);
    }
  }
}

void AddLightGlyphs(const std::vector<LightGlyph>& lights, double scale, Overlay* overlay) {
  static const Eigen::Vector3d kAxes[6] = {Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitX(),
                                           Eigen::Vector3d::UnitY(), -Eigen::Vector3d::UnitY(),
                                           Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitZ()};
  // Octahedron faces as triples of axis indices (+x -x +y -y +z -z), counter-clockwise outside.
  static const int kFaces[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                   {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  float strongest = 0.0f;
  for (const LightGlyph& light : lights) {
    const float mean = light.power.mean();
    if (std::isfinite(mean)) strongest = std::max(strongest, mean);
  }
  for (const LightGlyph& light : lights) {
    const float mean = std::max(0.0f, light.power.mean());
    if (!(mean > 0.0f) || !std::isfinite(mean)) continue;  // a dark light has no glyph
    const Eigen::Vector3f color = (light.power / light.power.maxCoeff()).cwiseMax(0.0f);
    const double radius = scale * std::cbrt(static_cast<double>(mean / strongest));
    for (const auto& face : kFaces) {
      for (int k : face) PushVertex(&overlay->triangles, light.position + radius * kAxes[k], color);
    }
    const float max_weight = *std::max_element(light.weights.begin(), light.weights.end());
    if (!(max_weight > 0.0f)) continue;
    for (int k = 0; k < 6; ++k) {
      const double length = 3.0 * radius * light.weights[k] / max_weight;
      if (length > 0.0)
        PushSegment(overlay, light.position, light.position + length * kAxes[k], color);
    }
  }
}

void AddDistantGlyph(const LightGlyph& distant, const Eigen::AlignedBox3d& box, Overlay* overlay) {
  if (box.isEmpty() || !(distant.power.maxCoeff() > 0.0f) || !distant.power.allFinite()) return;
  const float max_weight = *std::max_element(distant.weights.begin(), distant.weights.end());
  if (!(max_weight > 0.0f)) return;
  const Eigen::Vector3f color = (distant.power / distant.power.maxCoeff()).cwiseMax(0.0f);
  const Eigen::Vector3d centre = box.center(), half = 0.5 * box.sizes();
  const double size = box.diagonal().norm();
  for (int k = 0; k < 6; ++k) {
    if (!(distant.weights[k] > 0.0f)) continue;
    const int axis = k / 2;
    const double sign = k % 2 == 0 ? 1.0 : -1.0;
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[axis] = sign;
    const Eigen::Vector3d inner = centre + half[axis] * d;
    const double length = 0.5 * size * distant.weights[k] / max_weight;
    PushSegment(overlay, inner + length * d, inner, color);
    // The barb: two short segments back from the inner end, in the plane of the next axis.
    Eigen::Vector3d across = Eigen::Vector3d::Zero();
    across[(axis + 1) % 3] = 1.0;
    const double barb = 0.03 * size;
    PushSegment(overlay, inner, inner + barb * (d + across), color);
    PushSegment(overlay, inner, inner + barb * (d - across), color);
  }
}

}  // namespace genscene::viewer
