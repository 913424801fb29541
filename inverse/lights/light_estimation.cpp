#include "inverse/lights/light_estimation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <tuple>
#include <utility>

#include "core/check.h"
#include "core/color.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "inverse/lights/lights_internal.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on

namespace {

using lights_internal::EquationBytes;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// With refinement the coarse rounds only find where the lights are: an even spread of each
// view's sampled pixels (in raster order) is enough there; the finer levels use all of them.
std::vector<SampledPixel> CoarsePixels(const std::vector<SampledPixel>& pixels,
                                       const LightEstimationOptions& options) {
  if (options.refine_levels <= 0 || options.refine_coarse_pixels <= 0) return pixels;
  std::vector<SampledPixel> coarse_pixels;
  for (size_t begin = 0; begin < pixels.size();) {
    size_t end = begin;
    while (end < pixels.size() && pixels[end].view == pixels[begin].view) ++end;
    const size_t m = end - begin,
                 keep = std::min<size_t>(m, static_cast<size_t>(options.refine_coarse_pixels));
    for (size_t t = 0; t < keep; ++t) coarse_pixels.push_back(pixels[begin + t * m / keep]);
    begin = end;
  }
  return coarse_pixels;
}

// The relative change sqrt(sum (p_j - q_j)^2 / sum p_j^2) of the voxel powers p from q.
double PowerChange(const std::vector<double>& power, const std::vector<double>& previous) {
  double diff = 0.0, norm = 0.0;
  for (size_t j = 0; j < power.size(); ++j) {
    diff += (power[j] - previous[j]) * (power[j] - previous[j]);
    norm += power[j] * power[j];
  }
  return norm > 0.0 ? std::sqrt(diff / norm) : 0.0;
}

// The state of one adaptive refinement level: the finer grid, its candidate voxels (`enabled`)
// and those traced so far, and the second cache of its paths (the first is the estimator's
// `last`).
struct RefinementLevel {
  int level = 0;
  VoxelLightGrid fine;
  std::vector<bool> enabled, traced;
  int candidates = 0;
  LightCache second;
  double coarser_bytes = 0.0;  // the coarser result's cache, held beside this level's
};

// EstimateLights (steps 1-6 of light_estimation.h). `last_` and `total_` are the first cache and
// the normal equations of the latest round, out_.lights the current result.
class LightEstimator {
 public:
  LightEstimator(const Scene& scene, const std::vector<PosedImage>& views,
                 const LightEstimationOptions& options, uint64_t seed)
      : views_(views),
        options_(options),
        seed_(seed),
        tracer_(WithoutLights(scene)),
        pixels_(SamplePixels(tracer_, views, options, seed, &out_.masks)),
        coarse_pixels_(CoarsePixels(pixels_, options)),
        cap_bytes_(options.memory_cap * 1e6),
        equation_bytes_(NormalEquationsBoundBytes(options.grid)),
        scale_(views.size(), Eigen::Vector3d::Ones()) {
    out_.pixels = pixels_.size();
    out_.lights = MakeVoxelGrid(tracer_.scene(), options.grid, options.boundary_inset,
                                options.grid_margin, options.softening, options.distant);
    out_.lights.active_fraction = options.active_fraction;
    CheckEquationBytes();
  }

  LightEstimate Run(std::chrono::steady_clock::time_point start, const JointAlbedoInputs* joint) {
    // 1. The coarse rounds.
    CoarseRounds(coarse_pixels_);
    // 2. Adaptive refinement: a grid twice as fine, traced and solved over the voxels near the
    // lights only, level by level while the finer grid fits the pixels better.
    for (int level = 1; level <= options_.refine_levels; ++level) {
      if (!Refine(level)) break;
    }
    // 2b. Joint albedo.
    if (joint && options_.albedo_iterations > 0) JointAlbedo(*joint);
    // 3. The training error of the result's cache (the prediction times the view's gain).
    const std::vector<Eigen::Vector3f> predicted = last_.Predict(out_.lights);
    double err = 0.0, ref = 0.0;
    for (size_t i = 0; i < last_.pixels.size(); ++i) {
      const Eigen::Vector3d observed = last_.pixels[i].observed.cast<double>();
      const Eigen::Vector3d gain = scale_[static_cast<size_t>(last_.pixels[i].view)].cwiseInverse();
      err += (predicted[i].cast<double>().cwiseProduct(gain) - observed).squaredNorm();
      ref += observed.squaredNorm();
    }
    if (Exposure()) {
      for (const Eigen::Vector3d& h : scale_) out_.exposure_gains.push_back(h.cwiseInverse());
    }
    out_.train_rmse = ref > 0.0 ? std::sqrt(err / ref) : 0.0;
    if (out_.lights.distant) {
      VoxelLightGrid distant_only = out_.lights;
      for (Eigen::Vector3f& l : distant_only.intensity) l.setZero();
      const std::vector<Eigen::Vector3f> from_distant = last_.Predict(distant_only);
      double all = 0.0, part = 0.0;
      for (size_t i = 0; i < predicted.size(); ++i) {
        all += Luminance(predicted[i]);
        part += Luminance(from_distant[i]);
      }
      out_.distant_share = all > 0.0 ? std::clamp(part / all, 0.0, 1.0) : 0.0;
    }
    out_.active_voxels = static_cast<int>(
        out_.lights.ActiveVoxels(options_.active_fraction).size());  // of the result's grid
    out_.seconds = SecondsSince(start);
    return std::move(out_);
  }

 private:
  // The dense normal equations are known before any path is traced: refuse them up front.
  void CheckEquationBytes() const {
    if (equation_bytes_ >= cap_bytes_) {
      throw Error(Format("light estimation: the normal equations of a ", options_.grid,
                         "^3 voxel grid (", 6 * out_.lights.VoxelCount(),
                         " parameters, dense) may take ", std::ceil(equation_bytes_ / 1e6),
                         " MB, over the memory cap of ", options_.memory_cap,
                         " MB; lower lights grid or raise the", " lights memory_cap"));
    }
  }

  // Two independent halves of the paths (the second keyed by ~key), kept in `last_` and
  // `second`, within what the cap leaves beside `equation_bytes` of normal equations.
  void TraceHalves(const std::vector<SampledPixel>& traced_pixels, const VoxelLightGrid& lights,
                   const VoxelSplitting& splitting, int spp, uint64_t key, double equation_bytes,
                   LightCache* second, LightRound* r) {
    const auto t = std::chrono::steady_clock::now();
    LightEstimationOptions traced = options_;
    traced.paths.spp = spp;
    last_ = LightCache();  // the previous caches are not needed while tracing
    *second = LightCache();
    std::tie(last_, *second) =
        TraceLightCacheHalves(tracer_, lights, splitting, views_, traced_pixels, traced, key, ~key,
                              std::max(1.0, cap_bytes_ - equation_bytes));
    r->trace_seconds = SecondsSince(t);
    r->nonzeros = last_.NonZeros() + second->NonZeros();
    r->rays = last_.rays.total() + second->rays.total();
  }

  // The first vertex connects to every voxel; deeper ones draw voxels, uniformly in round 0,
  // then in proportion to the estimated powers mixed with the uniform distribution:
  //     pmf_j = (1 - u) P_j / sum P + u / voxels   (u: resample_uniform).
  VoxelSplitting RoundSplitting(int round) const {
    const VoxelLightGrid& grid = out_.lights;
    VoxelSplitting splitting;
    splitting.all_until_depth = options_.split_depth;
    std::vector<double> pmf(static_cast<size_t>(grid.VoxelCount()), 1.0);
    if (round > 0) {
      double total_power = 0.0;
      for (int j = 0; j < grid.VoxelCount(); ++j) total_power += pmf[j] = Luminance(grid.Power(j));
      for (double& p : pmf) {
        p = (1.0 - options_.resample_uniform) * (total_power > 0.0 ? p / total_power : 0.0) +
            options_.resample_uniform / grid.VoxelCount();
      }
    }
    splitting.SetPmf(std::move(pmf), options_.resample_voxels);
    return splitting;
  }

  // The coarse rounds over `round_pixels`, from the dark grid, then the moves in a final solve.
  void CoarseRounds(const std::vector<SampledPixel>& round_pixels) {
    out_.lights = MakeVoxelGrid(tracer_.scene(), options_.grid, options_.boundary_inset,
                                options_.grid_margin, options_.softening, options_.distant);
    out_.lights.active_fraction = options_.active_fraction;
    std::vector<double> previous_power;
    for (int round = 0; round < options_.rounds; ++round) {
      if (!CoarseRound(round, round_pixels, &previous_power)) break;
    }
    if (options_.move_passes > 0 && options_.penalty_weight > 0.0) {
      const auto t = std::chrono::steady_clock::now();
      LightRound& r = out_.rounds.back();
      const SolveReport polish = Solve(options_, &out_.lights);
      r.solve.iterations += polish.iterations;
      r.solve.moves = polish.moves;
      r.solve.cost = polish.cost;
      r.solve.data = polish.data;
      r.solve_seconds += SecondsSince(t);
      r.active_voxels = static_cast<int>(out_.lights.ActiveVoxels(options_.active_fraction).size());
    }
  }

  // One coarse round: trace, add its normal equations to the total, solve (without moves).
  // False when the voxel powers changed less than round_tolerance.
  bool CoarseRound(int round, const std::vector<SampledPixel>& round_pixels,
                   std::vector<double>* previous_power) {
    VoxelLightGrid& grid = out_.lights;
    LightRound r;
    r.round = static_cast<int>(out_.rounds.size());
    TraceHalves(round_pixels, grid, RoundSplitting(round), options_.paths.spp,
                Mix64(seed_ + 0x51ED * (round + 1)), equation_bytes_, &second_, &r);
    auto t = std::chrono::steady_clock::now();
    NormalEquations eq = NormalEquations::FromCaches(last_, second_, options_.noise_correction);
    if (round == 0) {
      total_ = std::move(eq);
    } else {
      total_.Add(eq);
    }
    r.gram_seconds = SecondsSince(t);
    t = std::chrono::steady_clock::now();
    LightEstimationOptions no_moves = options_;  // moves once, at the end
    no_moves.move_passes = 0;
    r.solve = Solve(no_moves, &grid);
    r.solve_seconds = SecondsSince(t);
    r.active_voxels = static_cast<int>(grid.ActiveVoxels(options_.active_fraction).size());
    std::vector<double> power(static_cast<size_t>(grid.VoxelCount()));
    for (int j = 0; j < grid.VoxelCount(); ++j) power[j] = Luminance(grid.Power(j));
    if (round > 0) r.power_change = PowerChange(power, *previous_power);
    *previous_power = power;
    out_.rounds.push_back(r);
    return !(round > 0 && r.power_change < options_.round_tolerance);
  }

  // Adds the finer voxels near `lit`'s lights (strongest first) while refine_max_voxels allows:
  // those whose centre lies within refine_reach (lit's) voxel sizes of a split voxel's centre
  // per axis, a voxel being split when it holds at least refine_fraction of the largest power.
  // `left_out` tells whether some light's neighbourhood did not fit. Returns the voxels added.
  int AddCandidates(const VoxelLightGrid& lit, const VoxelLightGrid& fine,
                    std::vector<bool>* enabled, int* count, bool* left_out) const {
    std::vector<std::pair<double, int>> split;
    double top = 0.0;
    for (int j = 0; j < lit.VoxelCount(); ++j) top = std::max<double>(top, Luminance(lit.Power(j)));
    for (int j = 0; j < lit.VoxelCount(); ++j) {
      const double power = Luminance(lit.Power(j));
      if (power > 0.0 && power >= options_.refine_fraction * top) split.emplace_back(power, j);
    }
    std::sort(split.begin(), split.end(), [](const auto& a, const auto& b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    const Eigen::Vector3d reach = options_.refine_reach *
                                  lit.bounds.sizes().cwiseQuotient(lit.dims.cast<double>()) *
                                  (1.0 + 1e-9);
    int added = 0;
    for (const auto& [power, j] : split) {
      const Eigen::Vector3d centre = lit.VoxelCenter(j);
      std::vector<int> near;
      for (int f = 0; f < fine.VoxelCount(); ++f) {
        if (!(*enabled)[f] &&
            ((fine.VoxelCenter(f) - centre).cwiseAbs().array() <= reach.array()).all()) {
          near.push_back(f);
        }
      }
      if (*count + static_cast<int>(near.size()) > options_.refine_max_voxels) {
        *left_out = true;
        break;
      }
      for (int f : near) (*enabled)[f] = true;
      *count += static_cast<int>(near.size());
      added += static_cast<int>(near.size());
    }
    return added;
  }

  // One refinement level; false when refinement ends here (the result stands as it is then).
  bool Refine(int level) {
    RefinementLevel state;
    state.level = level;
    state.fine = MakeVoxelGrid(tracer_.scene(), 2 * out_.lights.dims.x(), options_.boundary_inset,
                               options_.grid_margin, options_.softening, options_.distant);
    state.fine.active_fraction = options_.active_fraction;
    state.enabled.assign(static_cast<size_t>(state.fine.VoxelCount()), false);
    bool left_out = false;
    if (AddCandidates(out_.lights, state.fine, &state.enabled, &state.candidates, &left_out) == 0 &&
        !left_out)
      return false;
    // Lights spread over more voxels than refine_max_voxels can refine: the finer grid would drop
    // the ones left out (it is dark outside its candidates), so the coarser result stands.
    // When the coarser result stands (here or below) and it is the coarse grid of a pixel subset,
    // the coarse grid is estimated again from every sampled pixel.
    const bool reestimate = level == 1 && coarse_pixels_.size() < pixels_.size();
    if (left_out) {
      out_.notes.push_back(Format(
          "adaptive refinement stopped before level ", level, ": the lights of the ",
          out_.lights.dims.x(), "^3 grid spread over more than lights refine_max_voxels = ",
          options_.refine_max_voxels, " finer voxels (a larger penalty_weight gives fewer)"));
      if (reestimate) CoarseRounds(pixels_);
      return false;
    }
    // The coarser result, kept in case this level fits worse (below); its cache only when it
    // would be the result's (not re-estimated).
    const double coarser_data = out_.rounds.back().solve.data;
    VoxelLightGrid coarser = out_.lights;
    LightCache coarser_cache, coarser_second;
    if (!reestimate) {
      coarser_cache = std::move(last_);
      coarser_second = std::move(second_);
    }
    second_ = LightCache();
    state.coarser_bytes = static_cast<double>(coarser_cache.Bytes() + coarser_second.Bytes());
    state.traced.assign(state.enabled.size(), false);
    // Growing passes add the neighbours of the finer solution's lights (a coarse voxel standing
    // in for an extended light can sit a layer off it) and solve again.
    for (int pass = 0; pass <= options_.refine_grow; ++pass) {
      bool grow_left_out = false;  // a growing pass adds what fits
      if (pass > 0 && AddCandidates(state.fine, state.fine, &state.enabled, &state.candidates,
                                    &grow_left_out) == 0)
        break;
      RefinementPass(&state, pass);
    }
    // The finer grid holds light only near the coarser lights (dark elsewhere) and a lighter
    // penalty: it should fit the pixels at least as well. When it does not (the coarser lights
    // stand in for light that no strong voxel holds, as with imperfect geometry and albedo: on
    // the demo chain at w 1e-4, data 0.020 coarse against 0.136 finer), the coarser result stands.
    // The coarser data term is the noisier (fewer paths per pixel), which favours the finer level.
    const double finer_data = out_.rounds.back().solve.data;
    if (finer_data > coarser_data) {
      out_.notes.push_back(Format("adaptive refinement level ", level,
                                  " fitted the pixels worse than the ", coarser.dims.x(),
                                  "^3 grid (data term ", finer_data, " against ", coarser_data,
                                  "): the coarser result stands"));
      state.second = LightCache();
      if (reestimate) {
        last_ = LightCache();
        CoarseRounds(pixels_);
      } else {
        out_.lights = std::move(coarser);
        last_ = std::move(coarser_cache);
        second_ = std::move(coarser_second);
      }
      return false;
    }
    coarser_cache = LightCache();
    coarser_second = LightCache();
    out_.lights = std::move(state.fine);
    second_ = std::move(state.second);
    return true;
  }

  // One pass of a refinement level: trace the candidates not traced yet, the normal equations
  // (keeping the previous pass's part), and a solve from the dark finer grid.
  void RefinementPass(RefinementLevel* state, int pass) {
    LightRound r;
    r.round = static_cast<int>(out_.rounds.size());
    r.level = state->level;
    r.candidates = state->candidates;
    const double level_equation_bytes = EquationBytes(state->candidates);
    if (level_equation_bytes >= cap_bytes_) {
      throw Error(Format("light estimation: the normal equations of refinement level ",
                         state->level, " (", state->candidates, " voxels) may take ",
                         std::ceil(level_equation_bytes / 1e6), " MB, over the memory cap of ",
                         options_.memory_cap,
                         " MB; lower lights refine_max_voxels or raise the lights memory_cap"));
    }
    TraceRefinementPass(state, pass, level_equation_bytes, &r);
    auto t = std::chrono::steady_clock::now();
    // A growing pass's caches hold the previous pass's entries: their part of G is kept.
    if (pass == 0) {
      total_ = NormalEquations::FromCaches(last_, state->second, options_.noise_correction);
    } else {
      const NormalEquations previous = std::move(total_);
      total_ =
          NormalEquations::FromCaches(last_, state->second, options_.noise_correction, &previous);
    }
    r.gram_seconds = SecondsSince(t);
    t = std::chrono::steady_clock::now();
    LightEstimationOptions level_options = options_;
    level_options.penalty_weight = options_.penalty_weight * options_.refine_penalty_scale;
    for (int j = 0; j < state->fine.LightCount(); ++j) {  // every pass starts dark (the relaxation)
      state->fine.IntensityOf(j).setZero();
      state->fine.WeightsOf(j) = {1, 1, 1, 1, 1, 1};
    }
    r.solve = Solve(level_options, &state->fine);
    r.solve_seconds = SecondsSince(t);
    r.active_voxels = static_cast<int>(state->fine.ActiveVoxels(options_.active_fraction).size());
    out_.rounds.push_back(r);
  }

  // Scales the rows of pixel i of both caches by ratio[i] (per channel).
  void ScaleRows(const std::vector<Eigen::Vector3f>& ratio) {
    for (LightCache* cache : {&last_, &second_}) {
      GS_CHECK_EQ(cache->pixels.size(), ratio.size());
      ParallelFor(0, ratio.size(), [&](size_t i) {
        for (size_t e = cache->row_begin[i]; e < cache->row_begin[i + 1]; ++e)
          cache->coefficient[e] = cache->coefficient[e].cwiseProduct(ratio[i]);
      });
    }
  }

  // The relative squared residual of the second half's prediction for the current lights,
  // sum |P_i - h_v I_i|^2 / sum |h_v I_i|^2 (h_v: the view's exposure scale).
  double CheckResidual() const {
    const std::vector<Eigen::Vector3f> predicted = second_.Predict(out_.lights);
    double err = 0.0, ref = 0.0;
    for (size_t i = 0; i < predicted.size(); ++i) {
      const Eigen::Vector3d observed = second_.pixels[i].observed.cast<double>().cwiseProduct(
          scale_[static_cast<size_t>(second_.pixels[i].view)]);
      err += (predicted[i].cast<double>() - observed).squaredNorm();
      ref += observed.squaredNorm();
    }
    return ref > 0.0 ? err / ref : 0.0;
  }

  // Step 7 (joint_albedo.h): per-texel albedo alternated with the lights.
  void JointAlbedo(const JointAlbedoInputs& in) {
    const auto start = std::chrono::steady_clock::now();
    const SceneMesh& traced = tracer_.scene().meshes[static_cast<size_t>(in.mesh)];
    const size_t n = last_.pixels.size();
    const std::vector<PixelSurface> surface = LocatePixels(tracer_, views_, last_.pixels);
    std::vector<Eigen::Vector3f> albedo(n, Eigen::Vector3f::Ones());  // at each first hit
    for (size_t i = 0; i < n; ++i) {
      const PixelSurface& p = surface[i];
      if (p.hit) {
        const SceneMesh& m = tracer_.scene().meshes[static_cast<size_t>(p.mesh)];
        albedo[i] = m.albedo.Eval(m.mesh, p.face, p.b1, p.b2);
      }
    }
    Eigen::AlignedBox3f box;
    for (const Eigen::Vector3f& v : traced.mesh.vertices) box.extend(v);
    const double radius = options_.albedo_radius * std::max(1e-6f, box.diagonal().norm());
    LightEstimationOptions solve = options_;  // the options of the result's last solve
    solve.move_passes = 0;
    if (out_.lights.dims.x() > options_.grid)
      solve.penalty_weight = options_.penalty_weight * options_.refine_penalty_scale;
    double cost = out_.rounds.back().solve.cost;
    MeshColors current = *in.clusters;
    GS_CHECK_EQ(second_.pixels.size(), n);  // the two halves of the same pixels' paths
    // The shading's samples: probes traced over the whole observed surface, or the sampled
    // pixels' first halves.
    const bool probing = options_.albedo_probe_spp > 0;
    const double probe_offset = 1e-3 * std::max(1e-6f, box.diagonal().norm());
    const std::vector<PixelSurface> probes =
        probing
            ? ShadingProbes(tracer_, current, in.mesh, in.view_counts, radius / 3.0, probe_offset)
            : std::vector<PixelSurface>();
    out_.albedo_probes = probes.size();
    const ShadingKernel kernel(traced.mesh, current, in.mesh, probing ? probes : surface, radius,
                               probing ? kProbeNormalCosine : kPixelNormalCosine);
    // The probes' shading under the current lights, with `albedo` on the mesh (the renders'
    // interreflections).
    const auto probe_shading = [&](const MeshColors& albedo, int step) {
      Scene lit_scene = tracer_.scene();
      lit_scene.meshes[static_cast<size_t>(in.mesh)].albedo = SurfaceAlbedo::FromMeshColors(albedo);
      lit_scene.voxel_lights = out_.lights;
      const PathTracer lit(lit_scene);
      return ProbeShading(lit, probes, probe_offset, options_.paths, options_.albedo_probe_spp,
                          Mix64(seed_ + 0xA1BE * static_cast<uint64_t>(step + 1)));
    };
    // With albedo_guide, the kernel's guide under the current lights (ShadingGuide): the
    // voxels' direct shading with its shadows at the probes and the texels, and the floor.
    const bool guided = probing && options_.albedo_guide > 0.0;
    const std::vector<PixelSurface> texel_points =
        guided ? TexelSurfaces(traced.mesh, current, in.mesh) : std::vector<PixelSurface>();
    const auto guide_for = [&](const std::vector<Eigen::Vector3f>& shading) {
      ShadingGuide guide;
      guide.samples = DirectShading(out_.lights, traced, probes, &tracer_.tracer());
      guide.texels = DirectShading(out_.lights, traced, texel_points, &tracer_.tracer());
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      size_t count = 0;
      for (const Eigen::Vector3f& s : shading) {
        if (!s.allFinite()) continue;
        sum += s.cast<double>();
        ++count;
      }
      const Eigen::Vector3d mean =
          count > 0 ? Eigen::Vector3d(sum / count) : Eigen::Vector3d::Ones();
      guide.floor = (options_.albedo_guide * mean).cwiseMax(1e-6).cast<float>();
      return guide;
    };
    // The albedo `colors` gives every pixel's first hit on the mesh (the others keep `albedo`),
    // and in `ratio` the factor of each against `albedo`: what the caches' rows take.
    const auto follow = [&](const MeshColors& colors, std::vector<Eigen::Vector3f>* ratio) {
      std::vector<Eigen::Vector3f> at = albedo;
      ratio->assign(n, Eigen::Vector3f::Ones());
      for (size_t i = 0; i < n; ++i) {
        if (!surface[i].hit || surface[i].mesh != in.mesh) continue;
        at[i] = colors.Linear(surface[i].face, surface[i].b1, surface[i].b2)
                    .cwiseMax(0.0f)
                    .cwiseMin(1.0f);
        (*ratio)[i] = at[i].cwiseQuotient(albedo[i].cwiseMax(1e-3f)).cwiseMin(1e3f);
      }
      return at;
    };
    double check = CheckResidual();
    for (int step = 0; step < options_.albedo_iterations; ++step) {
      // 1. The shading: at every probe under the current lights, or at every pixel on the mesh
      // from the first half of the paths (the second half judges the step); carried to the
      // texels.
      std::vector<Eigen::Vector3f> shading;
      if (probing) {
        shading = probe_shading(current, step);
      } else {
        const std::vector<Eigen::Vector3f> a = last_.Predict(out_.lights);
        shading.assign(n, Eigen::Vector3f::Zero());
        for (size_t i = 0; i < n; ++i) {
          if (!surface[i].hit || surface[i].mesh != in.mesh) continue;
          shading[i] = a[i].cwiseQuotient(albedo[i].cwiseMax(0.02f));
        }
      }
      std::vector<uint8_t> covered;
      const ShadingGuide guide = guided ? guide_for(shading) : ShadingGuide();
      const std::vector<Eigen::Vector3f> texel_shading =
          kernel.Shade(shading, options_.albedo_min_pixels, &covered, guided ? &guide : nullptr);
      // 2. The albedo.
      JointAlbedoStep record;
      MeshColors next =
          UpdateAlbedo(in, texel_shading, covered, options_.albedo_prior, options_.albedo_ceiling,
                       &record.texels_updated, &record.scale);
      if (record.texels_updated == 0) break;  // no texel has shading: the albedo stays
      // 4. The caches follow the albedo at the first hits; the lights are solved again.
      std::vector<Eigen::Vector3f> ratio;
      std::vector<Eigen::Vector3f> next_albedo = follow(next, &ratio);
      const VoxelLightGrid lights = out_.lights;
      const std::vector<Eigen::Vector3d> scale = scale_;
      ScaleRows(ratio);
      total_ = NormalEquations::FromCaches(last_, second_, options_.noise_correction);
      const SolveReport report = Solve(solve, &out_.lights);
      record.cost = report.cost;
      record.data = report.data;
      record.check_before = check;
      record.check = CheckResidual();
      // Kept when the cost falls and the second half's paths agree: albedo that took up the
      // first half's noise fits the second half worse.
      if (!(report.cost < cost) || !(record.check < check)) {  // undone
        record.kept = false;
        for (size_t i = 0; i < n; ++i) ratio[i] = ratio[i].cwiseInverse();
        ScaleRows(ratio);
        total_ = NormalEquations::FromCaches(last_, second_, options_.noise_correction);
        out_.lights = lights;
        scale_ = scale;
        out_.albedo_steps.push_back(record);
        break;
      }
      out_.albedo_steps.push_back(record);
      const double fall = (cost - report.cost) / std::max(cost, 1e-300);
      cost = report.cost;
      check = record.check;
      current = std::move(next);
      albedo = std::move(next_albedo);
      out_.albedo = current;
      if (fall < options_.albedo_tolerance) break;
    }
    // 5. With probes, the albedo of the last lights: each step's albedo was made for the lights
    // before that step's solve, and the renders show the lights after it. The texels take the
    // probes' shading under the final lights once more; a ceiling's scale goes to the lights.
    if (probing && out_.albedo) {
      std::vector<uint8_t> covered;
      const std::vector<Eigen::Vector3f> shading =
          probe_shading(current, options_.albedo_iterations);
      const ShadingGuide guide = guided ? guide_for(shading) : ShadingGuide();
      const std::vector<Eigen::Vector3f> texel_shading =
          kernel.Shade(shading, options_.albedo_min_pixels, &covered, guided ? &guide : nullptr);
      double scale = 1.0;
      size_t voted = 0;
      MeshColors final_albedo = UpdateAlbedo(in, texel_shading, covered, options_.albedo_prior,
                                             options_.albedo_ceiling, &voted, &scale);
      if (voted > 0) {  // else no texel has shading: the last step's albedo stays
        std::vector<Eigen::Vector3f> ratio;  // the caches follow
        follow(final_albedo, &ratio);
        ScaleRows(ratio);
        total_ = NormalEquations::FromCaches(last_, second_, options_.noise_correction);
        for (Eigen::Vector3f& l : out_.lights.intensity) l /= static_cast<float>(scale);
        out_.lights.distant_intensity /= static_cast<float>(scale);
        out_.albedo = std::move(final_albedo);
        out_.albedo_final_scale = scale;
      }
    }
    out_.albedo_seconds = SecondsSince(start);
  }

  bool Exposure() const { return options_.exposure != "none"; }

  // SolveLights on total_, alternating with the exposure step when options_.exposure asks
  // (light_estimation.h, step 4).
  SolveReport Solve(const LightEstimationOptions& options, VoxelLightGrid* grid) {
    if (!Exposure()) return SolveLights(total_, options, grid);
    constexpr int kSteps = 6;
    SolveReport report;
    bool settled = false;  // the last gain step moved the gains by less than 0.1 %
    for (int step = 0;; ++step) {
      total_.ScaleObserved(scale_);
      report = SolveLights(total_, options, grid);
      if (settled || step + 1 == kSteps) break;
      const std::vector<Eigen::Vector3d> next = ExposureStep(*grid);
      double change = 0.0;
      for (size_t v = 0; v < next.size(); ++v)
        change = std::max(change, (next[v].array() / scale_[v].array()).log().abs().maxCoeff());
      scale_ = next;
      settled = change < 1e-3;
    }
    return report;
  }

  // The scale of each view's observations that fits them best to the prediction of `grid`,
  // normalised to a geometric mean of 1 over the views with pixels (light_estimation.h, step 4).
  std::vector<Eigen::Vector3d> ExposureStep(const VoxelLightGrid& grid) const {
    const NormalEquations& eq = total_;
    const size_t views = std::min(eq.view_rhs.size(), scale_.size());
    std::array<Eigen::VectorXd, 3> x;  // the products L_jc lambda_jk of the used parameters
    for (int c = 0; c < 3; ++c) {
      x[c].resize(static_cast<Eigen::Index>(eq.used.size()));
      for (size_t i = 0; i < eq.used.size(); ++i) {
        const int j = eq.used[i] / 6, k = eq.used[i] % 6;
        x[c][static_cast<Eigen::Index>(i)] =
            static_cast<double>(grid.IntensityOf(j)[c]) * grid.WeightsOf(j)[static_cast<size_t>(k)];
      }
    }
    std::vector<Eigen::Vector3d> next(scale_.size(), Eigen::Vector3d::Ones());
    Eigen::Vector3d log_sum = Eigen::Vector3d::Zero();
    int counted = 0;
    for (size_t v = 0; v < views; ++v) {
      const Eigen::Vector3d s = eq.view_observed_sq[v];
      if (!(s.minCoeff() > 0.0)) continue;
      Eigen::Vector3d t;
      for (int c = 0; c < 3; ++c) t[c] = x[c].dot(eq.view_rhs[v][c]);
      Eigen::Vector3d h = t.cwiseQuotient(s);
      if (options_.exposure == "gain") h.setConstant(t.sum() / s.sum());
      for (int c = 0; c < 3; ++c) h[c] = std::clamp(h[c], 0.2, 5.0);
      next[v] = h;
      log_sum += h.array().log().matrix();
      ++counted;
    }
    if (counted == 0) return scale_;
    const Eigen::Vector3d mean = (log_sum / counted).array().exp().matrix();
    for (size_t v = 0; v < views; ++v) {
      if (eq.view_observed_sq[v].minCoeff() > 0.0) next[v] = next[v].cwiseQuotient(mean);
    }
    return next;
  }

  // A growing pass traces only the voxels it adds, with the same keys: the paths are the same
  // (a vertex that connects to every enabled voxel draws no random number for it), so their
  // entries merge into the caches as if every candidate had been traced again.
  void TraceRefinementPass(RefinementLevel* state, int pass, double level_equation_bytes,
                           LightRound* r) {
    VoxelSplitting splitting;
    splitting.distant = pass == 0;  // a growing pass's entries merge into the first pass's
    splitting.enabled = state->enabled;
    for (size_t f = 0; f < state->enabled.size(); ++f)
      splitting.enabled[f] = state->enabled[f] && !state->traced[f];
    state->traced = state->enabled;
    const int level_spp = options_.refine_spp > 0 ? options_.refine_spp : options_.paths.spp;
    const uint64_t key = Mix64(seed_ + 0x5EF1 * state->level);
    if (pass == 0) {
      TraceHalves(pixels_, state->fine, splitting, level_spp, key,
                  level_equation_bytes + state->coarser_bytes, &state->second, r);
      return;
    }
    LightCache held_first = std::move(last_), held_second = std::move(state->second);
    TraceHalves(pixels_, state->fine, splitting, level_spp, key,
                level_equation_bytes + state->coarser_bytes +
                    static_cast<double>(held_first.Bytes() + held_second.Bytes()),
                &state->second, r);
    held_first.Merge(last_);
    held_second.Merge(state->second);
    last_ = std::move(held_first);
    state->second = std::move(held_second);
  }

  const std::vector<PosedImage>& views_;
  const LightEstimationOptions& options_;
  const uint64_t seed_;
  const PathTracer tracer_;
  LightEstimate out_;
  const std::vector<SampledPixel> pixels_;
  const std::vector<SampledPixel> coarse_pixels_;
  const double cap_bytes_;
  const double equation_bytes_;
  NormalEquations total_;
  LightCache last_, second_;            // the two halves of the result's paths
  std::vector<Eigen::Vector3d> scale_;  // per view, the exposure step's h (1: no exposure)
};

}  // namespace

Scene WithoutLights(const Scene& scene) {
  Scene out;
  for (const SceneMesh& m : scene.meshes) {
    if (!m.IsEmitter()) out.meshes.push_back(m);
  }
  if (out.meshes.empty())
    throw Error("light estimation: the scene has no reflecting (non-emitting) mesh");
  return out;
}

VoxelLightGrid MakeVoxelGrid(const Scene& scene, int dims, double boundary_inset, double margin,
                             double softening, bool distant) {
  GS_CHECK(boundary_inset >= 0.0 && boundary_inset <= 0.5);
  GS_CHECK(margin >= 0.0);
  GS_CHECK(softening >= 0.0);
  VoxelLightGrid g;
  for (const SceneMesh& m : scene.meshes) {
    if (m.IsEmitter()) continue;
    for (const auto& v : m.mesh.vertices) g.bounds.extend(v.cast<double>());
  }
  if (g.bounds.isEmpty() || g.bounds.sizes().minCoeff() <= 0.0) {
    // A flat scene (one wall): give the grid some depth so it still has volume.
    const double size = std::max(1e-3, g.bounds.isEmpty() ? 1.0 : g.bounds.sizes().maxCoeff());
    g.bounds.extend(g.bounds.min() - Eigen::Vector3d::Constant(0.5 * size));
    g.bounds.extend(g.bounds.max() + Eigen::Vector3d::Constant(0.5 * size));
  }
  if (margin > 0.0) {  // beyond the scan: light from what was never scanned
    const Eigen::Vector3d grow = margin * g.bounds.sizes();
    g.bounds = Eigen::AlignedBox3d(g.bounds.min() - grow, g.bounds.max() + grow);
  }
  if (dims > 1) {
    // The outer layer of voxel centres lies `boundary_inset` voxels inside the bounding box
    // (a voxel centre grid would hold it half a voxel inside): lights sit on ceilings and walls.
    // The voxels are then (size / (dims - 1 + 2 inset)) wide and the box grows by
    // (1/2 - inset) of one on every side.
    const Eigen::Vector3d voxel = g.bounds.sizes() / (dims - 1 + 2.0 * boundary_inset);
    const Eigen::Vector3d grow = voxel * (0.5 - boundary_inset);
    g.bounds = Eigen::AlignedBox3d(g.bounds.min() - grow, g.bounds.max() + grow);
  }
  g.dims = Eigen::Vector3i::Constant(dims);
  g.intensity.assign(static_cast<size_t>(g.VoxelCount()), Eigen::Vector3f::Zero());
  g.weights.assign(static_cast<size_t>(g.VoxelCount()), {1, 1, 1, 1, 1, 1});
  g.cube_size = 0.01 * g.bounds.sizes().minCoeff() / dims;
  g.softening = softening * g.bounds.sizes().minCoeff() / dims;
  g.distant = distant;
  return g;
}

LightEstimate EstimateLights(const Scene& scene, const std::vector<PosedImage>& views,
                             const LightEstimationOptions& options, uint64_t seed,
                             const JointAlbedoInputs* joint) {
  options.Validate();
  const auto start = std::chrono::steady_clock::now();
  if (joint) {
    GS_CHECK(joint->observed && joint->clusters);
    if (joint->mesh < 0 || joint->mesh >= static_cast<int>(scene.meshes.size()) ||
        scene.meshes[static_cast<size_t>(joint->mesh)].IsEmitter())
      throw Error(Format("light estimation: joint albedo on mesh ", joint->mesh,
                         ", which is not a reflecting mesh of the scene"));
  }
  LightEstimator estimator(scene, views, options, seed);
  if (joint) {  // the mesh's index among the traced (non-emitting) meshes
    JointAlbedoInputs traced = *joint;
    traced.mesh = 0;
    for (int m = 0; m < joint->mesh; ++m) traced.mesh += scene.meshes[m].IsEmitter() ? 0 : 1;
    return estimator.Run(start, &traced);
  }
  return estimator.Run(start, nullptr);
}

}  // namespace genscene::inverse
