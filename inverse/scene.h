// The scene a path tracer renders and the inverse stages estimate: triangle meshes with a
// Lambertian albedo, one-sided emissive meshes (area lights), point lights and voxel lights.
// Plain data; the ray tracer (embree_scene.h) and the path tracer (path_tracer.h) read it.
//
// Radiometric units: everything linear RGB in the units of the images. Area lights emit radiance
// (W / (m^2 sr) in those units); point lights and voxel lights emit radiant intensity (W / sr).
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/mesh.h"
#include "core/view_set.h"

namespace genscene::inverse {

// A custom albedo field over a mesh (issue "Texturing" plugs Mesh Colors in here): albedo at
// barycentric point (b1, b2) of `face` (b0 = 1 - b1 - b2 belongs to the face's first vertex).
class AlbedoField {
 public:
  virtual ~AlbedoField() = default;
  virtual Eigen::Vector3f Eval(int face, float b1, float b2) const = 0;
};

// Where a mesh's albedo comes from, in [0, 1] per channel.
struct SurfaceAlbedo {
  enum class Kind { kConstant, kPerFace, kPerVertex, kField };
  Kind kind = Kind::kConstant;
  Eigen::Vector3f constant{0.5f, 0.5f, 0.5f};  // kConstant (Mitsuba's default diffuse is 0.5)
  std::vector<Eigen::Vector3f> values;         // kPerFace: one per face; kPerVertex: one per vertex
  std::shared_ptr<const AlbedoField> field;    // kField

  static SurfaceAlbedo Constant(const Eigen::Vector3f& albedo);
  // The mesh's face colours, else its vertex colours, else `fallback`.
  static SurfaceAlbedo FromMesh(const TriangleMesh& mesh, const Eigen::Vector3f& fallback);

  Eigen::Vector3f Eval(const TriangleMesh& mesh, int face, float b1, float b2) const;
};

struct SceneMesh {
  std::string name;
  TriangleMesh mesh;  // world frame; faces counter-clockwise seen from the front
  SurfaceAlbedo albedo;
  // Emitted radiance of an area light; zero = not an emitter. One-sided: only the front (the side
  // the counter-clockwise normal points to) emits.
  Eigen::Vector3f emission = Eigen::Vector3f::Zero();
  // Shade with interpolated vertex normals (mesh.normals) instead of the face normal.
  bool smooth_shading = false;

  bool IsEmitter() const { return emission.maxCoeff() > 0.0f; }
};

struct PointLight {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3f intensity = Eigen::Vector3f::Zero();  // radiant intensity, W/sr per channel
};

// Voxel lights (the paper's Fig. 1): a regular grid of dims.x * dims.y * dims.z voxels over
// `bounds`, each with an RGB intensity L >= 0 and six directional weights lambda_k >= 0 for the
// directions d_k = +x, -x, +y, -y, +z, -z (in that order).
//
// Emission model: a voxel is a tiny cube at the voxel centre whose face k is a one-sided
// Lambertian emitter facing d_k. Seen from direction w (unit, from the voxel towards the
// receiver), face k shows its projected area A * max(0, w . d_k), so the voxel's radiant
// intensity is
//     I(w) = L * sum_k lambda_k * max(0, w . d_k)        [W/sr]
// i.e. L * lambda_k is the intensity along d_k. The cube is treated as a point for shading (it
// is tiny next to the distances to the surfaces it lights), which makes the predicted pixel a
// linear function of the products L * lambda_k (what light estimation caches). The model is
// physically exact and exports to any renderer as six emissive quads of side `cube_size` with
// radiance L * lambda_k / cube_size^2 (ExportCubeFaces).
struct VoxelLightGrid {
  Eigen::AlignedBox3d bounds;
  Eigen::Vector3i dims = Eigen::Vector3i::Constant(7);
  std::vector<Eigen::Vector3f> intensity;        // L per voxel, x fastest, then y, then z
  std::vector<std::array<float, 6>> weights;     // lambda per voxel
  double cube_size = 0.01;                       // side of the exported emitting cube, meters

  static const std::array<Eigen::Vector3d, 6>& Directions();
  int VoxelCount() const { return dims.x() * dims.y() * dims.z(); }
  Eigen::Vector3d VoxelCenter(int voxel) const;
  // Radiant intensity of `voxel` towards unit direction w (from the voxel to the receiver).
  Eigen::Vector3f Intensity(int voxel, const Eigen::Vector3d& w) const;
  // Upper bound of the intensity over directions (for light selection): L * max over the
  // combinations of at most three faces facing one direction.
  float MaxIntensityLuminance(int voxel) const;
  // The six emitting quads of every active voxel, as emissive scene meshes.
  std::vector<SceneMesh> ExportCubeFaces() const;
  void Validate() const;
};

struct Scene {
  std::vector<SceneMesh> meshes;
  std::vector<PointLight> point_lights;
  std::optional<VoxelLightGrid> voxel_lights;

  // Throws Error naming the mesh when a vertex is not finite, an index is out of range, an
  // albedo is outside [0, 1], an emission or intensity is negative or not finite.
  void Validate() const;
  Eigen::AlignedBox3d Bounds() const;
};

// A pinhole view: OpenCV intrinsics and world_from_camera pose (DESIGN.md §1).
using View = PosedView;

}  // namespace genscene::inverse
