#include "inverse/refine/data_term.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "inverse/refine/robust_loss.h"

namespace genscene::inverse::refine_detail {
using namespace genscene::render;  // the renderer the inverse stages are built on

void CheckTargets(const std::vector<PosedImage>& targets) {
  if (targets.empty()) throw Error("vertex refinement: no reference images");
  for (size_t t = 0; t < targets.size(); ++t) {
    const auto& k = targets[t].view.intrinsics;
    const ImageRgb& image = targets[t].image;
    if (image.width() != k.width || image.height() != k.height) {
      throw Error(Format("vertex refinement: reference image ", t, " is ", image.width(), "x",
                         image.height(), " but its view is ", k.width, "x", k.height));
    }
    for (int v = 0; v < image.height(); ++v) {
      for (int u = 0; u < image.width(); ++u) {
        if (!image(u, v).allFinite()) {
          throw Error(Format("vertex refinement: reference image ", t, " pixel (", u, ", ", v,
                             ") is not finite"));
        }
      }
    }
  }
}

std::vector<PixelRef> SamplePixels(const DifferentiablePathTracer& tracer, const PathTracer& ids,
                                   const std::vector<PosedImage>& targets, int per_view, int margin,
                                   bool refined_only, uint64_t seed) {
  std::vector<PixelRef> pixels;
  RenderOptions one;
  one.spp = 1;
  for (size_t t = 0; t < targets.size(); ++t) {
    const int w = targets[t].image.width(), h = targets[t].image.height();
    const Image<int> object = ids.Render(targets[t].view, one, 1).object;
    const auto near_edge = [&](int u, int v) {
      for (int dv = -margin; dv <= margin; ++dv) {
        for (int du = -margin; du <= margin; ++du) {
          const int x = std::clamp(u + du, 0, w - 1), y = std::clamp(v + dv, 0, h - 1);
          if (object(x, y) != object(u, v)) return true;
        }
      }
      return false;
    };
    std::vector<int> order;
    for (int p = 0; p < w * h; ++p) {
      if (refined_only) {
        const int m = object(p % w, p / w);
        if (m < 0 || tracer.ParameterVertex(m, 0) < 0) continue;
      }
      if (margin <= 0 || !near_edge(p % w, p / w)) order.push_back(p);
    }
    if (per_view > 0 && per_view < static_cast<int>(order.size())) {
      CounterRng rng(seed, 0x5e1ec7, t);
      for (int i = 0; i < per_view; ++i) {  // partial Fisher-Yates
        std::swap(order[i], order[i + rng.UniformInt(static_cast<uint32_t>(order.size() - i))]);
      }
      order.resize(per_view);
      std::sort(order.begin(), order.end());
    }
    for (int p : order) pixels.push_back({static_cast<int>(t), p % w, p / w});
  }
  if (pixels.empty())
    throw Error(
        "vertex refinement: no pixels to fit (no pixel sees a refined mesh away from a "
        "silhouette)");
  return pixels;
}

// s = sqrt(sum_p |I*_p|^2 / (3 P)) over the P sampled pixels.
double ReferenceRms(const std::vector<PosedImage>& targets, const std::vector<PixelRef>& pixels) {
  double sum = 0.0;
  for (const PixelRef& p : pixels)
    sum += targets[p.target].image(p.u, p.v).cast<double>().squaredNorm();
  const double rms = std::sqrt(sum / (3.0 * pixels.size()));
  if (!(rms > 0.0)) throw Error("vertex refinement: the reference images are black where sampled");
  return rms;
}

Evaluation Evaluate(const DifferentiablePathTracer& tracer, const std::vector<PosedImage>& targets,
                    const std::vector<PixelRef>& pixels, const RefineOptions& options,
                    uint64_t seed, double scale, bool derivatives) {
  Evaluation e;
  e.rows.resize(pixels.size());
  std::vector<RayCounts> rays(pixels.size());
  const RenderOptions render = options.paths;
  RenderOptions jacobian = render;
  if (options.jacobian_max_depth > 0 &&
      (render.max_depth < 0 || options.jacobian_max_depth < render.max_depth)) {
    jacobian.max_depth = options.jacobian_max_depth;  // never deeper than the residuals' paths
  }
  // Deeper derivatives are mostly Monte Carlo noise, whose square inflates J^T J and shortens
  // every step, and their truncated bias walks vertices by the floor: the residuals come from the
  // full paths, the Jacobian from the short ones.
  const bool separate = derivatives && jacobian.max_depth != render.max_depth;
  ParallelFor(
      0, pixels.size(),
      [&](size_t i) {
        const PixelRef& p = pixels[i];
        const PosedImage& t = targets[p.target];
        DualRgb row =
            tracer.Pixel(t.view, p.u, p.v, render, seed, derivatives && !separate, &rays[i]);
        if (separate) {  // the values of the full paths, the derivatives of the short ones
          const DualRgb d = tracer.Pixel(t.view, p.u, p.v, jacobian, seed, true, &rays[i]);
          for (int c = 0; c < 3; ++c)
            row[c] = SparseDual::Linear(1.0, d[c], 0.0, SparseDual(), row[c].value());
        }
        // r_pc = (I_c(x) - I*_c) / (noise * s): the path-traced pixel (options.paths.spp samples
        // with the random numbers of `seed`) against the reference, in units of the noise.
        for (int c = 0; c < 3; ++c)
          row[c] = (std::move(row[c]) - t.image(p.u, p.v)[c]) * (1.0 / scale);
        e.rows[i] = std::move(row);
      },
      8);
  for (size_t i = 0; i < pixels.size(); ++i) {  // fixed order: the same sums with any thread count
    for (int c = 0; c < 3; ++c) {
      const double r = e.rows[i][c].value();
      e.sum_squared += r * r * scale * scale;
      // rho(r_pc) = HuberCost(r_pc, robust)
      e.data_cost += HuberCost(r, options.robust);
    }
    e.rays.intersect += rays[i].intersect;
    e.rays.occluded += rays[i].occluded;
  }
  return e;
}

std::vector<bool> SeenVertices(const DifferentiablePathTracer& tracer, const PathTracer& rays,
                               const std::vector<PosedImage>& targets,
                               const std::vector<PixelRef>& pixels) {
  const Scene& scene = tracer.scene();
  std::vector<std::vector<std::vector<int>>> incident(
      scene.meshes.size());  // mesh -> vertex -> faces
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    if (tracer.ParameterVertex(static_cast<int>(m), 0) < 0) continue;
    const TriangleMesh& mesh = scene.meshes[m].mesh;
    incident[m].resize(mesh.vertices.size());
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      for (int k = 0; k < 3; ++k) incident[m][mesh.faces[f][k]].push_back(static_cast<int>(f));
    }
  }
  std::vector<bool> seen(tracer.VertexCount(), false);
  for (const PixelRef& p : pixels) {  // one ray per pixel: cheap, serial
    const auto hit = rays.PixelCentreHit(targets[p.target].view, p.u, p.v);
    if (!hit || incident[hit->mesh].empty()) continue;
    const TriangleMesh& mesh = scene.meshes[hit->mesh].mesh;
    const auto mark = [&](int v) { seen[tracer.ParameterVertex(hit->mesh, v)] = true; };
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.faces[hit->face][k];
      mark(v);
      if (!scene.meshes[hit->mesh].smooth_shading) continue;
      for (int f : incident[hit->mesh][v]) {
        for (int j = 0; j < 3; ++j) mark(mesh.faces[f][j]);
      }
    }
  }
  return seen;
}

}  // namespace genscene::inverse::refine_detail
