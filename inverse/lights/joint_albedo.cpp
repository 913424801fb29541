#include "inverse/lights/joint_albedo.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <utility>

#include "core/check.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "render/path_continuation.h"
#include "render/ray_tracer.h"

namespace genscene::inverse {

namespace {

// The hash key of a grid cell (21 bits per axis).
uint64_t CellKey(const Eigen::Vector3i& c) {
  return (static_cast<uint64_t>(static_cast<uint32_t>(c.x()) & 0x1FFFFF) << 42) |
         (static_cast<uint64_t>(static_cast<uint32_t>(c.y()) & 0x1FFFFF) << 21) |
         (static_cast<uint64_t>(static_cast<uint32_t>(c.z()) & 0x1FFFFF));
}

// A uniform hash grid of the pixels' first hits, cell size = the kernel radius.
class PointGrid {
 public:
  PointGrid(const std::vector<PixelSurface>& pixels, int mesh, double radius)
      : inverse_cell_(1.0 / radius) {
    for (size_t i = 0; i < pixels.size(); ++i) {
      if (pixels[i].hit && pixels[i].mesh == mesh)
        cells_[CellKey(Cell(pixels[i].position))].push_back(i);
    }
  }
  // Visits the pixels in p's cell and its 26 neighbours (all within the cell size of p).
  template <typename Visit>
  void ForNear(const Eigen::Vector3f& p, const Visit& visit) const {
    const Eigen::Vector3i c = Cell(p);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = cells_.find(CellKey(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (size_t i : it->second) visit(i);
        }
  }

 private:
  Eigen::Vector3i Cell(const Eigen::Vector3f& p) const {
    return (p.cast<double>() * inverse_cell_).array().floor().cast<int>();
  }
  double inverse_cell_;
  std::unordered_map<uint64_t, std::vector<size_t>> cells_;
};

// The unit normal of the face each texel belongs to (for an edge or vertex texel, the face
// MeshColors::SampleFacePoint names).
std::vector<Eigen::Vector3f> TexelFaceNormals(const TriangleMesh& mesh, const MeshColors& layout) {
  std::vector<Eigen::Vector3f> normal(layout.SampleCount(), Eigen::Vector3f::Zero());
  ParallelFor(0, normal.size(), [&](size_t t) {
    if (t < layout.VertexSampleCount() && layout.IsolatedVertex(static_cast<int>(t))) return;
    int face = -1;
    double b1 = 0.0, b2 = 0.0;
    layout.SampleFacePoint(t, &face, &b1, &b2);
    if (face >= 0) normal[t] = mesh.FaceNormalScaled(static_cast<size_t>(face)).normalized();
  });
  return normal;
}

bool Observed(const JointAlbedoInputs& in, size_t t) {
  return in.view_counts.empty() || in.view_counts[t] > 0;
}

}  // namespace

std::vector<PixelSurface> LocatePixels(const render::PathTracer& tracer,
                                       const std::vector<PosedImage>& views,
                                       const std::vector<SampledPixel>& pixels) {
  std::vector<PixelSurface> out(pixels.size());
  const render::Scene& scene = tracer.scene();
  ParallelFor(0, pixels.size(), [&](size_t i) {
    const SampledPixel& p = pixels[i];
    const auto hit = tracer.PixelCentreHit(views[static_cast<size_t>(p.view)].view, p.u, p.v);
    if (!hit) return;
    const TriangleMesh& mesh = scene.meshes[static_cast<size_t>(hit->mesh)].mesh;
    const Eigen::Vector3i& f = mesh.faces[static_cast<size_t>(hit->face)];
    PixelSurface& s = out[i];
    s.hit = true;
    s.mesh = hit->mesh;
    s.face = hit->face;
    s.b1 = hit->b1;
    s.b2 = hit->b2;
    s.position = (1.0f - hit->b1 - hit->b2) * mesh.vertices[f[0]] + hit->b1 * mesh.vertices[f[1]] +
                 hit->b2 * mesh.vertices[f[2]];
    s.normal = mesh.FaceNormalScaled(static_cast<size_t>(hit->face)).normalized();
  });
  return out;
}

std::vector<PixelSurface> ShadingProbes(const render::PathTracer& tracer, const MeshColors& layout,
                                        int mesh_index, const std::vector<int32_t>& view_counts,
                                        double spacing, double offset) {
  GS_CHECK(spacing > 0.0 && offset > 0.0);
  const render::Scene& scene = tracer.scene();
  GS_CHECK(mesh_index >= 0 && mesh_index < static_cast<int>(scene.meshes.size()));
  const TriangleMesh& mesh = scene.meshes[static_cast<size_t>(mesh_index)].mesh;
  const std::vector<Eigen::Vector3f> position = layout.InterpolateVertexAttribute(mesh.vertices);
  const std::vector<Eigen::Vector3f> normal = TexelFaceNormals(mesh, layout);
  // One texel per cell: the first face-interior texel in texel order, else the first edge
  // texel, else the first vertex texel (at a vertex or an edge the probe's ray meets several
  // faces at once). The same probes whatever the thread count.
  std::unordered_map<uint64_t, size_t> cells;
  std::vector<size_t> chosen;
  const double inverse = 1.0 / spacing;
  const size_t vertices = layout.VertexSampleCount();
  const size_t first_face = vertices + layout.EdgeSampleCount();
  const std::pair<size_t, size_t> ranges[] = {
      {first_face, position.size()}, {vertices, first_face}, {0, vertices}};
  for (const auto& [begin, end] : ranges) {
    for (size_t t = begin; t < end; ++t) {
      if (!view_counts.empty() && view_counts[t] <= 0) continue;
      if (!(normal[t].squaredNorm() > 0.0f) || !position[t].allFinite()) continue;
      const Eigen::Vector3i c = (position[t].cast<double>() * inverse).array().floor().cast<int>();
      if (cells.emplace(CellKey(c), t).second) chosen.push_back(t);
    }
  }
  std::vector<PixelSurface> probes(chosen.size());
  const float off = static_cast<float>(offset);
  ParallelFor(0, chosen.size(), [&](size_t i) {
    const size_t t = chosen[i];
    const Eigen::Vector3f& n = normal[t];
    // A hit within 3 offsets of the start lies within 2 offsets of the texel.
    const auto hit = tracer.tracer().Intersect(position[t] + off * n, -n, 0.0f, 3.0f * off);
    if (!hit || hit->mesh != mesh_index) return;
    const Eigen::Vector3i& f = mesh.faces[static_cast<size_t>(hit->face)];
    PixelSurface& s = probes[i];
    s.position = (1.0f - hit->b1 - hit->b2) * mesh.vertices[f[0]] + hit->b1 * mesh.vertices[f[1]] +
                 hit->b2 * mesh.vertices[f[2]];
    s.hit = true;
    s.mesh = mesh_index;
    s.face = hit->face;
    s.b1 = hit->b1;
    s.b2 = hit->b2;
    s.normal = mesh.FaceNormalScaled(static_cast<size_t>(hit->face)).normalized();
  });
  std::vector<PixelSurface> kept;
  kept.reserve(probes.size());
  for (const PixelSurface& p : probes)
    if (p.hit) kept.push_back(p);
  return kept;
}

std::vector<PixelSurface> TexelSurfaces(const TriangleMesh& mesh, const MeshColors& layout,
                                        int mesh_index) {
  std::vector<PixelSurface> out(layout.SampleCount());
  ParallelFor(0, out.size(), [&](size_t t) {
    if (t < layout.VertexSampleCount() && layout.IsolatedVertex(static_cast<int>(t))) return;
    int face = -1;
    double b1 = 0.0, b2 = 0.0;
    layout.SampleFacePoint(t, &face, &b1, &b2);
    if (face < 0) return;
    PixelSurface& s = out[t];
    s.hit = true;
    s.mesh = mesh_index;
    s.face = face;
    s.b1 = static_cast<float>(b1);
    s.b2 = static_cast<float>(b2);
    const auto& f = mesh.faces[static_cast<size_t>(face)];
    s.position = (1.0f - s.b1 - s.b2) * mesh.vertices[f[0]] + s.b1 * mesh.vertices[f[1]] +
                 s.b2 * mesh.vertices[f[2]];
    s.normal = mesh.FaceNormalScaled(static_cast<size_t>(face)).normalized();
  });
  return out;
}

std::vector<Eigen::Vector3f> DirectShading(const VoxelLightGrid& lights,
                                           const render::SceneMesh& mesh,
                                           const std::vector<PixelSurface>& at,
                                           const render::RayTracer* visibility) {
  std::vector<int> lit;  // the voxels with any intensity
  float strongest = 0.0f;
  for (int v = 0; v < lights.VoxelCount(); ++v) {
    const float largest = lights.IntensityOf(v).maxCoeff();
    if (largest <= 0.0f) continue;
    lit.push_back(v);
    strongest = std::max(strongest, largest);
  }
  std::vector<Eigen::Vector3f> center(lit.size());
  std::vector<uint8_t> traced(lit.size(), 0);  // whose visibility is traced
  for (size_t k = 0; k < lit.size(); ++k) {
    center[k] = lights.VoxelCenter(lit[k]).cast<float>();
    traced[k] = visibility != nullptr && lights.IntensityOf(lit[k]).maxCoeff() >= 1e-3f * strongest;
  }
  std::vector<Eigen::Vector3f> out(at.size(), Eigen::Vector3f::Zero());
  ParallelFor(0, at.size(), [&](size_t i) {
    const PixelSurface& p = at[i];
    if (!p.hit || p.face < 0) return;
    const Eigen::Vector3f ng = p.normal;
    const Eigen::Vector3f ns = mesh.ShadingNormal(static_cast<size_t>(p.face), p.b1, p.b2, ng);
    // The shadow rays' origin, as the renders' (path::OffsetScale along the face normal).
    const Eigen::Vector3f from = p.position + render::path::OffsetScale(p.position) * ng;
    thread_local std::vector<Eigen::Vector3f> directions;
    thread_local std::vector<float> lengths;
    thread_local std::vector<Eigen::Vector3f> terms;
    thread_local std::vector<uint8_t> blocked;
    directions.clear(), lengths.clear(), terms.clear();
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (size_t k = 0; k < lit.size(); ++k) {
      const Eigen::Vector3f to = center[k] - p.position;
      const float d2 = to.squaredNorm();
      if (!(d2 > 0.0f)) continue;
      const Eigen::Vector3f l = to / std::sqrt(d2);
      const float cos_s = ns.dot(l);
      if (cos_s <= 0.0f || ng.dot(l) <= 0.0f) continue;
      const Eigen::Vector3f term =
          lights.Intensity(lit[k], (-l).cast<double>()) * (cos_s * lights.Falloff(d2));
      if (!traced[k]) {
        sum += term;
        continue;
      }
      // As RayTracer::SegmentOccluded: the segment to the voxel's centre less its last 1e-4.
      const Eigen::Vector3f segment = center[k] - from;
      const float length = segment.norm();
      if (!(length > 0.0f)) {  // as SegmentOccluded: an empty segment is not blocked
        sum += term;
        continue;
      }
      directions.push_back(segment / length);
      lengths.push_back(length * (1.0f - 1e-4f));
      terms.push_back(term);
    }
    if (!directions.empty()) {
      blocked.assign(directions.size(), 0);
      visibility->OccludedFrom(from, directions.data(), lengths.data(),
                               static_cast<int>(directions.size()), 0.0f, blocked.data());
      for (size_t j = 0; j < directions.size(); ++j)
        if (!blocked[j]) sum += terms[j];
    }
    out[i] = sum / static_cast<float>(M_PI);
  });
  return out;
}

std::vector<Eigen::Vector3f> ProbeShading(const render::PathTracer& lit,
                                          const std::vector<PixelSurface>& probes, double offset,
                                          const render::RenderOptions& paths, int spp,
                                          uint64_t seed) {
  GS_CHECK(spp > 0);
  const render::Scene& scene = lit.scene();
  std::vector<Eigen::Vector3f> out(probes.size(), Eigen::Vector3f::Zero());
  const float off = static_cast<float>(offset);
  ParallelFor(0, probes.size(), [&](size_t i) {
    const PixelSurface& p = probes[i];
    if (!p.hit) return;
    const render::SceneMesh& m = scene.meshes[static_cast<size_t>(p.mesh)];
    const Eigen::Vector3f albedo = m.albedo.Eval(m.mesh, p.face, p.b1, p.b2);
    // Below 0.02 in a channel the radiance says too little of the shading (and an albedo of 0
    // ends the path): the probe is left out of the kernel.
    if (!(albedo.minCoeff() >= 0.02f)) {
      out[i].setConstant(std::numeric_limits<float>::quiet_NaN());
      return;
    }
    CounterRng rng(seed, i);
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (int s = 0; s < spp; ++s) {
      const double first_light_u = (s + rng.UniformDouble()) / spp;
      sum +=
          lit.Radiance(p.position + off * p.normal, -p.normal, paths, rng, nullptr, first_light_u);
    }
    out[i] = (sum / static_cast<float>(spp)).cwiseQuotient(albedo);
  });
  return out;
}

struct ShadingKernel::Impl {
  Impl(const std::vector<PixelSurface>& pixels, int mesh_index, double radius,
       float min_normal_cosine)
      : pixels(pixels),
        radius(radius),
        min_normal_cosine(min_normal_cosine),
        grids{PointGrid(pixels, mesh_index, radius), PointGrid(pixels, mesh_index, 2.0 * radius),
              PointGrid(pixels, mesh_index, 4.0 * radius)} {}
  const std::vector<PixelSurface>& pixels;
  const double radius;
  const float min_normal_cosine;
  // One grid per kernel width (cells as wide as the kernel): 27 cells per query.
  const PointGrid grids[3];
  std::vector<Eigen::Vector3f> position, normal;  // per texel
};

ShadingKernel::ShadingKernel(const TriangleMesh& mesh, const MeshColors& layout, int mesh_index,
                             const std::vector<PixelSurface>& pixels, double radius,
                             double min_normal_cosine) {
  GS_CHECK(radius > 0.0);
  impl_ = std::make_unique<Impl>(pixels, mesh_index, radius, static_cast<float>(min_normal_cosine));
  impl_->position = layout.InterpolateVertexAttribute(mesh.vertices);
  impl_->normal = TexelFaceNormals(mesh, layout);
}

ShadingKernel::~ShadingKernel() = default;

std::vector<Eigen::Vector3f> ShadingKernel::Shade(const std::vector<Eigen::Vector3f>& pixel_shading,
                                                  int min_pixels, std::vector<uint8_t>* covered,
                                                  const ShadingGuide* guide) const {
  const Impl& k = *impl_;
  const std::vector<PixelSurface>& pixels = k.pixels;
  GS_CHECK_EQ(pixels.size(), pixel_shading.size());
  const size_t texels = k.position.size();
  if (guide) {
    GS_CHECK_EQ(guide->samples.size(), pixels.size());
    GS_CHECK_EQ(guide->texels.size(), texels);
    GS_CHECK(guide->floor.minCoeff() > 0.0f);
  }
  // The value the kernel averages: the shading, or the shading over the sample's guide.
  const auto value = [&](size_t i) -> Eigen::Vector3d {
    if (!guide) return pixel_shading[i].cast<double>();
    return pixel_shading[i].cwiseQuotient(guide->samples[i] + guide->floor).cast<double>();
  };
  std::vector<Eigen::Vector3f> out(texels, Eigen::Vector3f::Zero());
  covered->assign(texels, 0);
  ParallelFor(0, texels, [&](size_t t) {
    const Eigen::Vector3f& n = k.normal[t];
    const Eigen::Vector3f& p = k.position[t];
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double weight = 0.0;
    for (int level = 0; level < 3; ++level) {
      const int reach = 1 << level;
      const float r2 = static_cast<float>(reach * reach * k.radius * k.radius);
      sum.setZero();
      weight = 0.0;
      int count = 0;
      k.grids[level].ForNear(p, [&](size_t i) {
        const float d2 = (pixels[i].position - p).squaredNorm();
        if (d2 >= r2 || pixels[i].normal.dot(n) < k.min_normal_cosine) return;
        if (!pixel_shading[i].allFinite()) return;  // a probe left out
        const double w = (1.0 - d2 / r2) * (1.0 - d2 / r2);
        sum += w * value(i);
        weight += w;
        ++count;
      });
      if (count >= min_pixels) break;
    }
    if (weight > 0.0) {
      out[t] = (sum / weight).cast<float>();
      if (guide) out[t] = out[t].cwiseProduct(guide->texels[t] + guide->floor);
      (*covered)[t] = 1;
    }
  });
  return out;
}

std::vector<Eigen::Vector3f> TexelShading(const TriangleMesh& mesh, const MeshColors& layout,
                                          int mesh_index, const std::vector<PixelSurface>& pixels,
                                          const std::vector<Eigen::Vector3f>& pixel_shading,
                                          double radius, int min_pixels,
                                          std::vector<uint8_t>* covered) {
  return ShadingKernel(mesh, layout, mesh_index, pixels, radius, kPixelNormalCosine)
      .Shade(pixel_shading, min_pixels, covered);
}

MeshColors UpdateAlbedo(const JointAlbedoInputs& in,
                        const std::vector<Eigen::Vector3f>& texel_shading,
                        const std::vector<uint8_t>& covered, double prior, double ceiling,
                        size_t* updated, double* applied_scale) {
  GS_CHECK(in.observed && in.clusters);
  const MeshColors& clusters = *in.clusters;
  const size_t n = clusters.SampleCount();
  GS_CHECK_EQ(in.observed->SampleCount(), n);
  GS_CHECK_EQ(texel_shading.size(), n);
  const std::vector<int32_t>& label = clusters.labels();
  int32_t classes = 0;
  for (int32_t l : label) classes = std::max(classes, l + 1);
  const auto ClassOf = [&](size_t t) { return label.empty() ? 0 : std::max(0, label[t]); };
  classes = std::max(classes, 1);
  // Which texels vote: observed, reached by the kernel, with shading in every channel.
  std::vector<uint8_t> uses(n, 0);
  Eigen::Vector3d shading_sq = Eigen::Vector3d::Zero();
  size_t used = 0;
  for (size_t t = 0; t < n; ++t) {
    if (!covered[t] || !Observed(in, t) || !(texel_shading[t].minCoeff() > 0.0f)) continue;
    uses[t] = 1;
    shading_sq += texel_shading[t].cast<double>().cwiseAbs2();
    ++used;
  }
  if (updated) *updated = used;
  MeshColors out = clusters;
  if (applied_scale) *applied_scale = 1.0;
  if (used == 0) {
    return out;
  }
  shading_sq /= static_cast<double>(used);
  // m_k: the cluster's least-squares albedo sum(o S) / sum(S^2) over its voting texels (the
  // clustering's albedo where none of it votes).
  std::vector<Eigen::Vector3d> os(static_cast<size_t>(classes), Eigen::Vector3d::Zero()),
      ss(static_cast<size_t>(classes), Eigen::Vector3d::Zero()),
      mean(static_cast<size_t>(classes), Eigen::Vector3d::Zero());
  std::vector<double> count(static_cast<size_t>(classes), 0.0);
  for (size_t t = 0; t < n; ++t) {
    if (!uses[t]) continue;
    const size_t k = static_cast<size_t>(ClassOf(t));
    const Eigen::Vector3d s = texel_shading[t].cast<double>();
    os[k] += in.observed->colors()[t].cast<double>().cwiseProduct(s);
    ss[k] += s.cwiseAbs2();
    count[k] += 1.0;
  }
  for (size_t k = 0; k < mean.size(); ++k)
    if (count[k] > 0.0) mean[k] = os[k].cwiseQuotient(ss[k]);
  std::vector<Eigen::Vector3f>& a = out.colors();
  for (size_t t = 0; t < n; ++t) {
    const size_t k = static_cast<size_t>(ClassOf(t));
    if (count[k] == 0.0) continue;  // keeps the cluster's albedo
    if (!uses[t]) {
      a[t] = mean[k].cast<float>();
      // A texel no keyframe saw, with shading: its observed colour is the texturing's fill (its
      // observed neighbours' colour, or the texture's mean), and it takes that over its shading
      // as the others do (the cluster's mean differs from the neighbours, most along the strips
      // an occluding edge hid).
      if (!covered[t] || !(texel_shading[t].minCoeff() > 0.0f)) continue;
    }
    const Eigen::Vector3d o = in.observed->colors()[t].cast<double>();
    const Eigen::Vector3d s = texel_shading[t].cast<double>();
    for (int c = 0; c < 3; ++c) {
      const double m = prior * shading_sq[c];
      a[t][c] = static_cast<float>((o[c] * s[c] + m * mean[k][c]) / (s[c] * s[c] + m));
    }
  }
  // The ceiling: when the 95th percentile of the largest channel over the voting texels is above
  // `ceiling`, the whole albedo is scaled down to it (the lights' solve takes the scale up).
  std::vector<float> largest;
  largest.reserve(used);
  for (size_t t = 0; t < n; ++t)
    if (uses[t]) largest.push_back(a[t].maxCoeff());
  const size_t q = std::min(largest.size() - 1, static_cast<size_t>(0.95 * largest.size()));
  std::nth_element(largest.begin(), largest.begin() + static_cast<std::ptrdiff_t>(q),
                   largest.end());
  const float scale = largest[q] > ceiling ? static_cast<float>(ceiling) / largest[q] : 1.0f;
  for (Eigen::Vector3f& v : a) v = (scale * v).cwiseMax(0.0f).cwiseMin(1.0f);
  if (applied_scale) *applied_scale = scale;
  return out;
}

}  // namespace genscene::inverse
