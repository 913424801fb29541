// Internal to vertex refinement (inverse/refine/*.cpp): the data term of E, the pixels it fits and
// the vertices those pixels see. The public API is in vertex_refinement.h.
#pragma once

#include <cstdint>
#include <vector>

#include "inverse/refine/vertex_refinement.h"

namespace genscene::inverse::refine_detail {

struct PixelRef {
  int target = 0, u = 0, v = 0;
};

// Throws Error when there are no targets, a target's size does not match its view, or one of its
// pixels is not finite.
void CheckTargets(const std::vector<PosedImage>& targets);

// The sampled pixels: every pixel, or `per_view` drawn without replacement per view, leaving out
// pixels within `margin` pixels of a silhouette (where the object seen through the pixel centre
// changes, in the starting geometry): their residuals come from visibility, which the derivatives
// do not see, and would pull the vertices the wrong way. With `refined_only`, only pixels whose
// camera ray first hits a refined mesh (elsewhere a vertex shows only through shadows and
// indirect light). Throws Error when no pixel is left.
// `ids` is a plain tracer of the tracer's scene (its object buffer gives what each pixel sees).
std::vector<PixelRef> SamplePixels(const render::DifferentiablePathTracer& tracer,
                                   const render::PathTracer& ids,
                                   const std::vector<PosedImage>& targets, int per_view, int margin,
                                   bool refined_only, uint64_t seed);

// s: the RMS of the reference over the sampled pixels and channels (> 0; throws Error otherwise).
double ReferenceRms(const std::vector<PosedImage>& targets, const std::vector<PixelRef>& pixels);

// One trace of every sampled pixel: the residual rows (with their derivatives when asked) and the
// data cost sum_p sum_c HuberCost(r_pc, robust).
struct Evaluation {
  std::vector<render::DualRgb> rows;  // per pixel: r_pc for c = R, G, B
  double data_cost = 0.0;
  double sum_squared = 0.0;  // of I - I*, for the RMSE
  render::RayCounts rays;
};

// Traces the pixels at the tracer's positions with the random numbers of `seed`; `scale` is
// noise * s. The values come from paths of options.paths.max_depth segments, the derivatives (with
// `derivatives`) from paths of at most options.jacobian_max_depth.
Evaluation Evaluate(const render::DifferentiablePathTracer& tracer,
                    const std::vector<PosedImage>& targets, const std::vector<PixelRef>& pixels,
                    const RefineOptions& options, uint64_t seed, double scale, bool derivatives);

// The vertices that a sampled pixel sees directly: those the shading of its pixel-centre ray's
// first hit depends on (the hit triangle's vertices and, with smooth normals, their one-rings,
// whose faces make the vertex normals). The others show only through indirect light, whose
// derivatives are mostly Monte Carlo noise. Found geometrically, not from a trace's derivatives:
// a vertex in shadow or lit only by a few light samples must not be held or freed by chance
// (a 1-sample trace leaves the Cycles dent held on some seeds).
// `rays` is a plain tracer of the tracer's scene.
std::vector<bool> SeenVertices(const render::DifferentiablePathTracer& tracer,
                               const render::PathTracer& rays,
                               const std::vector<PosedImage>& targets,
                               const std::vector<PixelRef>& pixels);

}  // namespace genscene::inverse::refine_detail
