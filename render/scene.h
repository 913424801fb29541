// The scene a path tracer renders and the inverse stages estimate: triangle meshes with a
// Lambertian albedo, one-sided emissive meshes (area lights), point lights and voxel lights.
// Plain data; the ray tracer (embree_scene.h) and the path tracer (path_tracer.h) read it.
//
// Radiometric units: everything linear RGB in the units of the images. Area lights emit radiance
// (W / (m^2 sr) in those units); point lights and voxel lights emit radiant intensity (W / sr).
#pragma once

#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/image.h"
#include "core/light_set.h"
#include "core/mesh.h"
#include "core/mesh_colors.h"
#include "core/view_set.h"

namespace genscene::render {

// A custom albedo field over a mesh (texturing plugs Mesh Colors in here): albedo at
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
  // A field looked up linearly in Mesh Colors (texturing's albedo.mcol), clamped to [0, 1].
  static SurfaceAlbedo FromMeshColors(MeshColors colors);

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
  // The shading normal at barycentric (b1, b2) of `face`, on the side of the unit geometric normal
  // `ng`: with smooth_shading the interpolated vertex normal (ng where it vanishes), else ng.
  Eigen::Vector3f ShadingNormal(size_t face, float b1, float b2, const Eigen::Vector3f& ng) const {
    const auto& vn = mesh.normals;
    if (!smooth_shading || vn.size() != mesh.vertices.size()) return ng;
    const Eigen::Vector3i& f = mesh.faces[face];
    const Eigen::Vector3f n = (1.0f - b1 - b2) * vn[f[0]] + b1 * vn[f[1]] + b2 * vn[f[2]];
    Eigen::Vector3f ns = n.squaredNorm() > 0.0f ? Eigen::Vector3f(n.normalized()) : ng;
    if (ns.dot(ng) < 0.0f) ns = -ns;
    return ns;
  }
};

struct PointLight {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3f intensity = Eigen::Vector3f::Zero();  // radiant intensity, W/sr per channel
};

// Voxel lights: core/light_set.h (the light set is shared with the viewer). The six emitting
// quads of every active voxel as emissive scene meshes, for renderers that have no voxel lights:
// side `grid.cube_size`, radiance L * lambda_k / cube_size^2.
std::vector<SceneMesh> VoxelCubeFaces(const VoxelLightGrid& grid);

struct Scene;
// The scene with every non-emitting mesh's albedo grey 0.8: renders of the shading alone.
Scene ShadingOnly(Scene scene);

struct Scene {
  std::vector<SceneMesh> meshes;
  std::vector<PointLight> point_lights;
  std::optional<VoxelLightGrid> voxel_lights;

  // Throws Error naming the mesh when a vertex is not finite, an index is out of range, an
  // albedo is outside [0, 1], an emission or intensity is negative or not finite.
  void Validate() const;
  Eigen::AlignedBox3d Bounds() const;
};

}  // namespace genscene::render
