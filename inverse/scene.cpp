#include "inverse/scene.h"

#include <cmath>

#include "core/check.h"
#include "core/color.h"

namespace genscene::inverse {

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
      const Eigen::Vector3i& f = mesh.faces[face];
      return (1.0f - b1 - b2) * values[f[0]] + b1 * values[f[1]] + b2 * values[f[2]];
    }
    case Kind::kField:
      return field->Eval(face, b1, b2);
  }
  return constant;
}

const std::array<Eigen::Vector3d, 6>& VoxelLightGrid::Directions() {
  static const std::array<Eigen::Vector3d, 6> d = {
      Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(-1, 0, 0), Eigen::Vector3d(0, 1, 0),
      Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, -1)};
  return d;
}

Eigen::Vector3d VoxelLightGrid::VoxelCenter(int voxel) const {
  const int x = voxel % dims.x();
  const int y = (voxel / dims.x()) % dims.y();
  const int z = voxel / (dims.x() * dims.y());
  const Eigen::Vector3d size = bounds.sizes().cwiseQuotient(dims.cast<double>());
  return bounds.min() + Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5).cwiseProduct(size);
}

Eigen::Vector3f VoxelLightGrid::Intensity(int voxel, const Eigen::Vector3d& w) const {
  const auto& lambda = weights[voxel];
  // Faces facing w: +x when w.x > 0, -x when w.x < 0, and so on.
  const double sum = lambda[0] * std::max(0.0, w.x()) + lambda[1] * std::max(0.0, -w.x()) +
                     lambda[2] * std::max(0.0, w.y()) + lambda[3] * std::max(0.0, -w.y()) +
                     lambda[4] * std::max(0.0, w.z()) + lambda[5] * std::max(0.0, -w.z());
  return intensity[voxel] * static_cast<float>(sum);
}

float VoxelLightGrid::MaxIntensityLuminance(int voxel) const {
  const auto& l = weights[voxel];
  // max over unit w of sum_k lambda_k max(0, w.d_k) = norm of the per-axis larger weights.
  const double mx = std::max(l[0], l[1]), my = std::max(l[2], l[3]), mz = std::max(l[4], l[5]);
  return Luminance(intensity[voxel]) * static_cast<float>(std::sqrt(mx * mx + my * my + mz * mz));
}

std::vector<SceneMesh> VoxelLightGrid::ExportCubeFaces() const {
  std::vector<SceneMesh> out;
  const double h = 0.5 * cube_size;
  const auto& dirs = Directions();
  for (int v = 0; v < VoxelCount(); ++v) {
    if (intensity[v].maxCoeff() <= 0.0f) continue;
    const Eigen::Vector3d c = VoxelCenter(v);
    for (int k = 0; k < 6; ++k) {
      if (weights[v][k] <= 0.0f) continue;
      const Eigen::Vector3d n = dirs[k];
      // Two tangent axes with t1 x t2 = n, so (c + h(+-t1 +-t2)) is counter-clockwise seen from n.
      const Eigen::Vector3d t1 = dirs[(k / 2 * 2 + 2) % 6];
      const Eigen::Vector3d t2 = n.cross(t1);
      SceneMesh m;
      m.name = Format("voxel", v, "_face", k);
      const Eigen::Vector3d center = c + h * n;
      for (const auto& [a, b] : {std::pair{-1, -1}, std::pair{1, -1}, std::pair{1, 1}, std::pair{-1, 1}}) {
        m.mesh.vertices.push_back((center + h * (a * t1 + b * t2)).cast<float>());
      }
      m.mesh.faces = {Eigen::Vector3i(0, 1, 2), Eigen::Vector3i(0, 2, 3)};
      m.albedo = SurfaceAlbedo::Constant(Eigen::Vector3f::Zero());
      // Intensity along n of a Lambertian quad of area A and radiance R is R A: R = L lambda / A.
      m.emission = intensity[v] * static_cast<float>(weights[v][k] / (cube_size * cube_size));
      out.push_back(std::move(m));
    }
  }
  return out;
}

void VoxelLightGrid::Validate() const {
  if (dims.minCoeff() < 1 || dims.maxCoeff() > 256) {
    throw Error(Format("voxel lights: grid ", dims.transpose(), " is not in [1, 256] per axis"));
  }
  if (bounds.isEmpty() || !bounds.min().allFinite() || !bounds.max().allFinite()) {
    throw Error("voxel lights: bounds are empty or not finite");
  }
  const size_t n = static_cast<size_t>(VoxelCount());
  if (intensity.size() != n || weights.size() != n) {
    throw Error(Format("voxel lights: ", intensity.size(), " intensities and ", weights.size(),
                       " weight sets for ", n, " voxels"));
  }
  for (size_t v = 0; v < n; ++v) {
    if (!intensity[v].allFinite() || intensity[v].minCoeff() < 0.0f) {
      throw Error(Format("voxel lights: voxel ", v, " has intensity (", intensity[v].transpose(),
                         "), must be finite and >= 0"));
    }
    for (float w : weights[v]) {
      if (!std::isfinite(w) || w < 0.0f) {
        throw Error(Format("voxel lights: voxel ", v, " has a directional weight ", w, ", must be >= 0"));
      }
    }
  }
  if (!(cube_size > 0.0)) throw Error(Format("voxel lights: cube_size ", cube_size, " must be > 0"));
}

void Scene::Validate() const {
  for (const SceneMesh& m : meshes) {
    const std::string name = "mesh '" + m.name + "'";
    m.mesh.Validate(name);
    if (!m.emission.allFinite() || m.emission.minCoeff() < 0.0f) {
      throw Error(Format(name, ": emitted radiance (", m.emission.transpose(), ") must be finite and >= 0"));
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
        const size_t expected = m.albedo.kind == SurfaceAlbedo::Kind::kPerFace ? m.mesh.faces.size()
                                                                               : m.mesh.vertices.size();
        if (m.albedo.values.size() != expected) {
          throw Error(Format(name, ": ", m.albedo.values.size(), " albedo values for ", expected, " elements"));
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
      throw Error(Format("point light ", i, ": position (", p.position.transpose(), ") and intensity (",
                         p.intensity.transpose(), ") must be finite, intensity >= 0"));
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

}  // namespace genscene::inverse
