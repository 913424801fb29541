#include "render/scene.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/color.h"
#include "core/mesh_colors.h"

namespace genscene::render {

SurfaceAlbedo SurfaceAlbedo::Constant(const Eigen::Vector3f& albedo) {
  SurfaceAlbedo a;
  a.kind = Kind::kConstant;
  a.constant = albedo;
  return a;
}

SurfaceAlbedo SurfaceAlbedo::FromMesh(const TriangleMesh& mesh, const Eigen::Vector3f& fallback) {
  SurfaceAlbedo a = Constant(fallback);
  if (!mesh.face_colors.empty()) {
    a.kind = Kind::kPerFace;
    a.values = mesh.face_colors;
  } else if (!mesh.vertex_colors.empty()) {
    a.kind = Kind::kPerVertex;
    a.values = mesh.vertex_colors;
  }
  return a;
}

Eigen::Vector3f SurfaceAlbedo::Eval(const TriangleMesh& mesh, int face, float b1, float b2) const {
  switch (kind) {
    case Kind::kConstant:
      return constant;
    case Kind::kPerFace:
      return values[face];
    case Kind::kPerVertex: {
      // A hit a few ulps outside the face would extrapolate (and leave [0, 1]).
      ClampToFace(&b1, &b2);
      const Eigen::Vector3i& f = mesh.faces[face];
      return std::max(0.0f, 1.0f - b1 - b2) * values[f[0]] + b1 * values[f[1]] + b2 * values[f[2]];
    }
    case Kind::kField:
      return field->Eval(face, b1, b2);
  }
  return constant;
}

std::vector<SceneMesh> VoxelCubeFaces(const VoxelLightGrid& grid) {
  std::vector<SceneMesh> out;
  const double h = 0.5 * grid.cube_size;
  const auto& dirs = VoxelLightGrid::Directions();
  for (int v = 0; v < grid.VoxelCount(); ++v) {
    if (grid.intensity[v].maxCoeff() <= 0.0f) continue;
    const Eigen::Vector3d c = grid.VoxelCenter(v);
    for (int k = 0; k < 6; ++k) {
      if (grid.weights[v][k] <= 0.0f) continue;
      const Eigen::Vector3d n = dirs[k];
      // Two tangent axes with t1 x t2 = n, so (c + h(+-t1 +-t2)) is counter-clockwise seen from n.
      const Eigen::Vector3d t1 = dirs[(k / 2 * 2 + 2) % 6];
      const Eigen::Vector3d t2 = n.cross(t1);
      SceneMesh m;
      m.name = Format("voxel", v, "_face", k);
      const Eigen::Vector3d center = c + h * n;
      for (const auto& [a, b] :
           {std::pair{-1, -1}, std::pair{1, -1}, std::pair{1, 1}, std::pair{-1, 1}}) {
        m.mesh.vertices.push_back((center + h * (a * t1 + b * t2)).cast<float>());
      }
      m.mesh.faces = {Eigen::Vector3i(0, 1, 2), Eigen::Vector3i(0, 2, 3)};
      m.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Zero());
      // Intensity along n of a Lambertian quad of area A and radiance R is R A: R = L lambda / A.
      m.emission = grid.intensity[v] *
                   static_cast<float>(grid.weights[v][k] / (grid.cube_size * grid.cube_size));
      out.push_back(std::move(m));
    }
  }
  return out;
}

void Scene::Validate() const {
  for (const SceneMesh& m : meshes) {
    const std::string name = "mesh '" + m.name + "'";
    m.mesh.Validate(name);
    if (!m.emission.allFinite() || m.emission.minCoeff() < 0.0f) {
      throw Error(Format(name, ": emitted radiance (", m.emission.transpose(),
                         ") must be finite and >= 0"));
    }
    if (m.smooth_shading && m.mesh.normals.size() != m.mesh.vertices.size()) {
      throw Error(Format(name, ": smooth shading needs one normal per vertex"));
    }
    const auto check_albedo = [&](const Eigen::Vector3f& a) {
      if (!a.allFinite() || a.minCoeff() < 0.0f || a.maxCoeff() > 1.0f) {
        throw Error(Format(name, ": albedo (", a.transpose(), ") is not in [0, 1]"));
      }
    };
    switch (m.albedo.kind) {
      case SurfaceAlbedo::Kind::kConstant:
        check_albedo(m.albedo.constant);
        break;
      case SurfaceAlbedo::Kind::kPerFace:
      case SurfaceAlbedo::Kind::kPerVertex: {
        const size_t expected = m.albedo.kind == SurfaceAlbedo::Kind::kPerFace
                                    ? m.mesh.faces.size()
                                    : m.mesh.vertices.size();
        if (m.albedo.values.size() != expected) {
          throw Error(Format(name, ": ", m.albedo.values.size(), " albedo values for ", expected,
                             " elements"));
        }
        for (const auto& a : m.albedo.values) check_albedo(a);
        break;
      }
      case SurfaceAlbedo::Kind::kField:
        if (!m.albedo.field) throw Error(Format(name, ": albedo field is missing"));
        break;
    }
  }
  for (size_t i = 0; i < point_lights.size(); ++i) {
    const PointLight& p = point_lights[i];
    if (!p.position.allFinite() || !p.intensity.allFinite() || p.intensity.minCoeff() < 0.0f) {
      throw Error(Format("point light ", i, ": position (", p.position.transpose(),
                         ") and intensity (", p.intensity.transpose(),
                         ") must be finite, intensity >= 0"));
    }
  }
  if (voxel_lights) voxel_lights->Validate();
}

Eigen::AlignedBox3d Scene::Bounds() const {
  Eigen::AlignedBox3d box;
  for (const SceneMesh& m : meshes) {
    for (const auto& v : m.mesh.vertices) box.extend(v.cast<double>());
  }
  for (const PointLight& p : point_lights) box.extend(p.position);
  if (voxel_lights) box.extend(voxel_lights->bounds);
  return box;
}

namespace {

class MeshColorsAlbedo : public AlbedoField {
 public:
  explicit MeshColorsAlbedo(MeshColors colors) : colors_(std::move(colors)) {}
  Eigen::Vector3f Eval(int face, float b1, float b2) const override {
    return colors_.Linear(face, b1, b2).cwiseMax(0.0f).cwiseMin(1.0f);
  }

 private:
  MeshColors colors_;
};

}  // namespace

SurfaceAlbedo SurfaceAlbedo::FromMeshColors(MeshColors colors) {
  SurfaceAlbedo a;
  a.kind = Kind::kField;
  a.field = std::make_shared<MeshColorsAlbedo>(std::move(colors));
  return a;
}

Scene ShadingOnly(Scene scene) {
  for (SceneMesh& m : scene.meshes) {
    if (!m.IsEmitter()) m.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Constant(0.8f));
  }
  return scene;
}

}  // namespace genscene::render
