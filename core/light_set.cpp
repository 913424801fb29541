#include "core/light_set.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"
#include "core/json_util.h"

namespace genscene {

using namespace json_util;  // NOLINT: CheckKeys, JsonNumber, JsonVector, ... (core/json_util.h)

const std::array<Eigen::Vector3d, 6>& VoxelLightGrid::Directions() {
  static const std::array<Eigen::Vector3d, 6> d = {
      Eigen::Vector3d(1, 0, 0),  Eigen::Vector3d(-1, 0, 0), Eigen::Vector3d(0, 1, 0),
      Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(0, 0, 1),  Eigen::Vector3d(0, 0, -1)};
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
  // Faces facing w: +x when w.x > 0, -x when w.x < 0, and so on.
  return intensity[voxel] * static_cast<float>(LobeSum(weights[voxel], w));
}

Eigen::Vector3f VoxelLightGrid::DistantRadiance(const Eigen::Vector3f& w) const {
  if (!distant) return Eigen::Vector3f::Zero();
  return distant_intensity * LobeSum(distant_weights, w);
}

float VoxelLightGrid::MaxIntensityLuminance(int voxel) const {
  const auto& l = weights[voxel];
  // max over unit w of sum_k lambda_k max(0, w.d_k) = norm of the per-axis larger weights.
  const double mx = std::max(l[0], l[1]), my = std::max(l[2], l[3]), mz = std::max(l[4], l[5]);
  return Luminance(intensity[voxel]) * static_cast<float>(std::sqrt(mx * mx + my * my + mz * mz));
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
        throw Error(
            Format("voxel lights: voxel ", v, " has a directional weight ", w, ", must be >= 0"));
      }
    }
  }
  if (!distant_intensity.allFinite() || distant_intensity.minCoeff() < 0.0f) {
    throw Error(Format("voxel lights: the distant light has intensity (",
                       distant_intensity.transpose(), "), must be finite and >= 0"));
  }
  for (float w : distant_weights) {
    if (!std::isfinite(w) || w < 0.0f) {
      throw Error(
          Format("voxel lights: the distant light has a directional weight ", w, ", must be >= 0"));
    }
  }
  if (!(cube_size > 0.0))
    throw Error(Format("voxel lights: cube_size ", cube_size, " must be > 0"));
  if (!(softening >= 0.0 && std::isfinite(softening)))
    throw Error(Format("voxel lights: softening ", softening, " must be finite and >= 0"));
  if (!(active_fraction >= 0.0 && active_fraction <= 1.0)) {
    throw Error(Format("voxel lights: active_fraction ", active_fraction, " is not in [0, 1]"));
  }
}

Eigen::Vector3f VoxelLightGrid::Power(int voxel) const {
  double sum = 0.0;
  for (float w : weights[voxel]) sum += w;
  return intensity[voxel] * static_cast<float>(M_PI * sum);
}

double VoxelLightGrid::TotalPowerLuminance() const {
  double total = 0.0;
  for (int j = 0; j < VoxelCount(); ++j) total += Luminance(Power(j));
  return total;
}

Eigen::Vector3d VoxelLightGrid::PowerCentroid() const {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  double total = 0.0;
  for (int j = 0; j < VoxelCount(); ++j) {
    const double p = Luminance(Power(j));
    centroid += p * VoxelCenter(j);
    total += p;
  }
  if (!(total > 0.0)) return Eigen::Vector3d::Constant(std::nan(""));
  return centroid / total;
}

std::vector<int> VoxelLightGrid::ActiveVoxels(double fraction) const {
  std::vector<double> power(static_cast<size_t>(VoxelCount()));
  double largest = 0.0;
  for (int v = 0; v < VoxelCount(); ++v) {
    power[v] = Luminance(Power(v));
    largest = std::max(largest, power[v]);
  }
  std::vector<int> active;
  for (int v = 0; v < VoxelCount(); ++v) {
    if (power[v] > 0.0 && power[v] >= fraction * largest) active.push_back(v);
  }
  return active;
}

VoxelLightGrid VoxelLightGridFromJson(const json& j, const std::string& where) {
  CheckKeys(j,
            {"bounds_min", "bounds_max", "dims", "cube_size", "softening", "active_fraction",
             "intensity", "weights", "distant"},
            where);
  for (const char* key : {"bounds_min", "bounds_max", "dims", "intensity", "weights"}) {
    if (!j.contains(key)) throw Error(Format(where, ": missing \"", key, "\""));
  }
  VoxelLightGrid g;
  g.bounds = Eigen::AlignedBox3d(JsonVector<3>(j["bounds_min"], where + ".bounds_min"),
                                 JsonVector<3>(j["bounds_max"], where + ".bounds_max"));
  const Eigen::Vector3d dims = JsonVector<3>(j["dims"], where + ".dims");
  if (dims != dims.array().round().matrix()) throw Error(Format(where, ".dims: expected integers"));
  // Range-checked as doubles: casting a value beyond int's range is undefined behaviour.
  if (dims.minCoeff() < 1 || dims.maxCoeff() > 256) {
    throw Error(Format(where, ".dims: grid ", dims.transpose(), " is not in [1, 256] per axis"));
  }
  g.dims = dims.cast<int>();
  if (j.contains("cube_size")) g.cube_size = JsonNumber(j["cube_size"], where + ".cube_size");
  if (j.contains("softening")) g.softening = JsonNumber(j["softening"], where + ".softening");
  if (j.contains("active_fraction"))
    g.active_fraction = JsonNumber(j["active_fraction"], where + ".active_fraction");
  for (const json& v : JsonArray(j["intensity"], where + ".intensity")) {
    g.intensity.push_back(JsonVector<3>(v, where + ".intensity").cast<float>());
  }
  for (const json& v : JsonArray(j["weights"], where + ".weights")) {
    const Eigen::Matrix<double, 6, 1> w = JsonVector<6>(v, where + ".weights");
    g.weights.push_back({});
    for (int k = 0; k < 6; ++k) g.weights.back()[static_cast<size_t>(k)] = static_cast<float>(w[k]);
  }
  if (j.contains("distant")) {
    const std::string at = where + ".distant";
    const json& d = j["distant"];
    if (!d.is_object()) throw Error(Format(at, ": expected an object"));
    CheckKeys(d, {"intensity", "weights"}, at);
    for (const char* key : {"intensity", "weights"}) {
      if (!d.contains(key)) throw Error(Format(at, ": missing \"", key, "\""));
    }
    g.distant = true;
    g.distant_intensity = JsonVector<3>(d["intensity"], at + ".intensity").cast<float>();
    const Eigen::Matrix<double, 6, 1> w = JsonVector<6>(d["weights"], at + ".weights");
    for (int k = 0; k < 6; ++k)
      g.distant_weights[static_cast<size_t>(k)] = static_cast<float>(w[k]);
  }
  try {
    g.Validate();
  } catch (const Error& e) {
    throw Error(Format(where, ": ", e.what()));
  }
  return g;
}

json VoxelLightGridToJson(const VoxelLightGrid& g) {
  json intensity = json::array(), weights = json::array();
  for (const Eigen::Vector3f& l : g.intensity) intensity.push_back(FloatsToJson(l));
  for (const auto& w : g.weights) weights.push_back(std::vector<double>(w.begin(), w.end()));
  json out = {{"bounds_min", ToJson(g.bounds.min())},
              {"bounds_max", ToJson(g.bounds.max())},
              {"dims", {g.dims.x(), g.dims.y(), g.dims.z()}},
              {"cube_size", g.cube_size},
              {"softening", g.softening},
              {"active_fraction", g.active_fraction},
              {"intensity", intensity},
              {"weights", weights}};
  if (g.distant) {
    out["distant"] = {
        {"intensity", FloatsToJson(g.distant_intensity)},
        {"weights", std::vector<double>(g.distant_weights.begin(), g.distant_weights.end())}};
  }
  return out;
}

void WriteLightsJson(const std::filesystem::path& path, const VoxelLightGrid& grid,
                     const std::string& estimate_json) {
  grid.Validate();
  json j;
  j["genscene_lights"] = 1;
  j["voxel_lights"] = VoxelLightGridToJson(grid);
  j["estimate"] = json::parse(estimate_json);
  WriteTextFileAtomically(path, j.dump(1) + "\n");
}

VoxelLightGrid ReadLightsJson(const std::filesystem::path& path) {
  const json j = ParseJsonFile(path);
  const std::string where = path.string();
  CheckKeys(j, {"genscene_lights", "voxel_lights", "estimate"}, where);
  if (!j.contains("genscene_lights") || j["genscene_lights"] != 1) {
    throw Error(Format(where, ": not a genscene lights file (expected \"genscene_lights\": 1)"));
  }
  if (!j.contains("voxel_lights")) throw Error(Format(where, ": missing \"voxel_lights\""));
  return VoxelLightGridFromJson(j["voxel_lights"], where + ": voxel_lights");
}

}  // namespace genscene
