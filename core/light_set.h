// The light set of a scene model (DESIGN.md §3): voxel lights, the paper's Fig. 1, as light
// estimation writes them to `lights.json` and the renderer, the viewer and the exporters read them.
//
// lights.json (written by genscene-lights, version 1):
//   {
//     "genscene_lights": 1,
//     "voxel_lights": {
//       "bounds_min": [x, y, z], "bounds_max": [x, y, z],   meters, world frame
//       "dims": [nx, ny, nz],                              voxels per axis
//       "cube_size": s,                                     side of the exported emitting cube, m
//       "softening": e,                                     optional, m (default 0): see below
//       "intensity": [[r, g, b], ...],                      L per voxel (W/sr), x fastest,
//                                                           then y, then z
//       "weights": [[l+x, l-x, l+y, l-y, l+z, l-z], ...]    six lambdas per voxel, in [0, 1]
//       "distant": {"intensity": [r, g, b],                 optional: the distant light (below)
//                   "weights": [l+x, l-x, l+y, l-y, l+z, l-z]}
//     },
//     "estimate": { ... }                                   free-form: how the estimate was made
//   }
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <filesystem>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace genscene {

// Voxel lights (the paper's Fig. 1): a regular grid of dims.x * dims.y * dims.z voxels over
// `bounds`, each with an RGB intensity L >= 0 and six directional weights lambda_k >= 0 for the
// directions d_k = +x, -x, +y, -y, +z, -z (in that order).
//
// Emission model: a voxel is a tiny cube at the voxel centre whose face k is a one-sided
// Lambertian emitter facing d_k. Seen from direction w (unit, from the voxel towards the
// receiver), face k shows its projected area A * max(0, w . d_k), so the voxel's radiant
// intensity is
//     I(w) = L * sum_k lambda_k * max(0, w . d_k)        [W/sr]
// i.e. L * lambda_k is the intensity along d_k. The cube is treated as a point for shading,
// which makes the predicted pixel a linear function of the products L * lambda_k (what light
// estimation caches). A receiver at distance d gets I(w) cos / (d^2 + e^2), e = `softening`:
// the light is spread over about a ball of radius e (a Plummer-softened point), so that a wall a
// few centimetres from a voxel centre is not lit without bound (e = 0: an exact point). Every
// tracer (estimate, renders, refinement) uses this falloff. The model exports to any renderer
// as six emissive quads of side `cube_size` with radiance L * lambda_k / cube_size^2
// (render::VoxelCubeFaces), which matches it beyond a few e.
//
// The distant light (optional, `distant`): light from beyond the scan (a window, a ceiling lamp
// never scanned), an environment at infinity in the form of a voxel's emission, six lobes: a ray
// that leaves the scene along the unit direction w receives the radiance
//     E(w) = L_d * sum_k lambda_dk * max(0, w . d_k)        [W / (m^2 sr)]
// (L_d = `distant_intensity`, lambda_d = `distant_weights`, d_k the voxels' six directions, so
// lambda_d,+y is the light from above when +y points up). It is linear in the products
// L_d lambda_dk as a voxel is in its own, so light estimation takes it as one more light, index
// VoxelCount() (LightCount, IntensityOf, WeightsOf). Camera rays that miss the scene do not see it
// (as hidden emitters); every path that leaves the scene after a bounce does.
// sum_k lambda_k max(0, w . d_k) (d_k = +x, -x, +y, -y, +z, -z): the share of a six-lobe
// emitter's intensity along the unit direction w, in w's precision.
template <typename Vec3>
typename Vec3::Scalar LobeSum(const std::array<float, 6>& lambda, const Vec3& w) {
  using S = typename Vec3::Scalar;
  const S zero(0);
  return S(lambda[0]) * std::max(zero, w.x()) + S(lambda[1]) * std::max(zero, -w.x()) +
         S(lambda[2]) * std::max(zero, w.y()) + S(lambda[3]) * std::max(zero, -w.y()) +
         S(lambda[4]) * std::max(zero, w.z()) + S(lambda[5]) * std::max(zero, -w.z());
}

struct VoxelLightGrid {
  Eigen::AlignedBox3d bounds;
  Eigen::Vector3i dims = Eigen::Vector3i::Constant(7);
  std::vector<Eigen::Vector3f> intensity;     // L per voxel, x fastest, then y, then z
  std::vector<std::array<float, 6>> weights;  // lambda per voxel
  double cube_size = 0.01;                    // side of the exported emitting cube, meters
  double softening = 0.0;                     // e of the falloff 1 / (d^2 + e^2), meters
  // Share of the largest voxel power from which a voxel counts as an active light (the estimate's
  // own threshold, kept with the lights so that every stage and the viewer count alike).
  double active_fraction = 1e-3;
  bool distant = false;  // the distant light is part of the model
  Eigen::Vector3f distant_intensity = Eigen::Vector3f::Zero();  // L_d
  std::array<float, 6> distant_weights = {1, 1, 1, 1, 1, 1};    // lambda_d

  static const std::array<Eigen::Vector3d, 6>& Directions();
  int VoxelCount() const { return dims.x() * dims.y() * dims.z(); }
  // The voxels and, when `distant`, the distant light as light VoxelCount().
  int LightCount() const { return VoxelCount() + (distant ? 1 : 0); }
  Eigen::Vector3f& IntensityOf(int light) {
    return light < VoxelCount() ? intensity[static_cast<size_t>(light)] : distant_intensity;
  }
  const Eigen::Vector3f& IntensityOf(int light) const {
    return light < VoxelCount() ? intensity[static_cast<size_t>(light)] : distant_intensity;
  }
  std::array<float, 6>& WeightsOf(int light) {
    return light < VoxelCount() ? weights[static_cast<size_t>(light)] : distant_weights;
  }
  const std::array<float, 6>& WeightsOf(int light) const {
    return light < VoxelCount() ? weights[static_cast<size_t>(light)] : distant_weights;
  }
  // E(w) of the distant light for unit w (zero without one).
  Eigen::Vector3f DistantRadiance(const Eigen::Vector3f& w) const;
  bool HasDistantLight() const { return distant && distant_intensity.maxCoeff() > 0.0f; }
  Eigen::Vector3d VoxelCenter(int voxel) const;
  // 1 / (d2 + e^2): the falloff with the squared distance d2 from a voxel centre.
  float Falloff(float d2) const { return 1.0f / (d2 + static_cast<float>(softening * softening)); }
  // Radiant intensity of `voxel` towards unit direction w (from the voxel to the receiver).
  Eigen::Vector3f Intensity(int voxel, const Eigen::Vector3d& w) const;
  // Upper bound of the intensity over directions (for light selection): L * max over the
  // combinations of at most three faces facing one direction.
  float MaxIntensityLuminance(int voxel) const;
  // Radiant power (W) of `voxel`, per channel: the integral of I(w) over the sphere,
  // pi * L * sum_k lambda_k.
  Eigen::Vector3f Power(int voxel) const;
  // Sum over the voxels of Luminance(Power(j)), and the voxel centres' mean weighted by it (NaN
  // when no voxel has power): where the light is, as the light-estimation tests and bench judge it.
  double TotalPowerLuminance() const;
  Eigen::Vector3d PowerCentroid() const;
  // Voxels whose power luminance is at least `fraction` of the largest one (0: any power > 0);
  // without an argument, at least active_fraction of it.
  std::vector<int> ActiveVoxels(double fraction) const;
  std::vector<int> ActiveVoxels() const { return ActiveVoxels(active_fraction); }
  void Validate() const;
};

// The "voxel_lights" object above, read (every key checked, Errors name `where`) and written.
VoxelLightGrid VoxelLightGridFromJson(const nlohmann::ordered_json& j, const std::string& where);
nlohmann::ordered_json VoxelLightGridToJson(const VoxelLightGrid& grid);

// lights.json: the grid plus a free-form "estimate" object (a JSON text, may be empty "{}").
// Write is atomic (temporary name, then rename); Read throws Error naming the file.
void WriteLightsJson(const std::filesystem::path& path, const VoxelLightGrid& grid,
                     const std::string& estimate_json = "{}");
VoxelLightGrid ReadLightsJson(const std::filesystem::path& path);

}  // namespace genscene
