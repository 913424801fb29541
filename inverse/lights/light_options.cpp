#include "inverse/lights/light_options.h"

#include "core/check.h"
#include "core/options.h"

namespace genscene::inverse {

void LightEstimationOptions::Validate() const {
  RequireRange("grid", grid, 1, 64);
  RequireRange("pixels_per_view", pixels_per_view, 1, 1 << 24);
  paths.Validate();
  if (paths.spp < 2 || paths.spp % 2)
    throw Error(Format("option spp = ", paths.spp, " must be even (two independent halves)"));
  RequireRange("direct_paths", direct_paths, 1, 1 << 16);  // at most all of a half's paths
  RequireRange("split_depth", split_depth, 1, 1 << 20);
  RequireRange("refine_coarse_pixels", refine_coarse_pixels, 0, 1 << 24);
  RequireRange("boundary_inset", boundary_inset, 0.0, 0.5);
  RequireRange("softening", softening, 0.0, 2.0);
  RequireRange("grid_margin", grid_margin, 0.0, 10.0);
  RequireRange("penalty_weight", penalty_weight, 0.0, 1e6);
  RequireRange("penalty_epsilon", penalty_epsilon, 1e-9, 1e6);
  RequireRange("chroma_weight", chroma_weight, 0.0, 1e6);
  RequireRange("rounds", rounds, 1, 100);
  RequireRange("round_tolerance", round_tolerance, 0.0, 10.0);
  RequireRange("resample_voxels", resample_voxels, 1, 1 << 16);
  RequireRange("resample_uniform", resample_uniform, 0.0, 1.0);
  RequireRange("max_iterations", max_iterations, 1, 1 << 20);
  RequireRange("move_passes", move_passes, 0, 100);
  RequireRange("move_voxels", move_voxels, 1, 1 << 20);
  RequireRange("move_iterations", move_iterations, 1, 1 << 20);
  RequireRange("tolerance", tolerance, 0.0, 1.0);
  RequireRange("saturation", saturation, 0.0, 1e30);
  RequireRange("emitter_factor", emitter_factor, 1.0, 1e30);
  RequireRange("noise_correction", noise_correction, 0.0, 1.0);
  RequireRange("refine_levels", refine_levels, 0, 4);
  RequireRange("refine_fraction", refine_fraction, 0.0, 1.0);
  RequireRange("refine_reach", refine_reach, 0.0, 10.0);
  RequireRange("refine_penalty_scale", refine_penalty_scale, 0.0, 1e6);
  RequireRange("refine_max_voxels", refine_max_voxels, 1, 1 << 20);
  RequireRange("refine_spp", refine_spp, 0, 1 << 16);
  RequireRange("refine_grow", refine_grow, 0, 100);
  RequireOneOf("exposure", exposure, {"none", "gain", "white-balance"});
  if (refine_spp % 2)
    throw Error(
        Format("option refine_spp = ", refine_spp, " must be even (two independent halves)"));
  if (grid << refine_levels > 256) {
    throw Error(Format("option refine_levels = ", refine_levels, " with grid = ", grid, " gives a ",
                       grid << refine_levels, "^3 grid; at most 256 per axis"));
  }
  RequireRange("albedo_iterations", albedo_iterations, 0, 100);
  RequireRange("albedo_prior", albedo_prior, 0.0, 1e6);
  RequireRange("albedo_radius", albedo_radius, 1e-6, 1.0);
  RequireRange("albedo_min_pixels", albedo_min_pixels, 1, 1 << 20);
  RequireRange("albedo_probe_spp", albedo_probe_spp, 0, 1 << 16);
  RequireRange("albedo_guide", albedo_guide, 0.0, 1e6);
  RequireRange("albedo_ceiling", albedo_ceiling, 1e-3, 1.0);
  RequireRange("albedo_tolerance", albedo_tolerance, 0.0, 1.0);
  RequireRange("active_fraction", active_fraction, 0.0, 1.0);
  RequireRange("memory_cap", memory_cap, 1.0, 1e7);
}

}  // namespace genscene::inverse
