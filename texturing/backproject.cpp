#include "texturing/backproject.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <optional>

#include "core/check.h"
#include "core/color.h"
#include "core/parallel.h"
#include "texturing/raster.h"

namespace genscene::texturing {

void TexturingOptions::Validate() const {
  RequireRange("texel_spacing", texel_spacing, 1e-5, 10.0);
  if (max_resolution < 1 || max_resolution > MeshColors::kMaxResolution ||
      (max_resolution & (max_resolution - 1)) != 0) {
    throw Error(Format("option max_resolution = ", max_resolution,
                       " must be a power of two in [1, ", MeshColors::kMaxResolution, "]"));
  }
  RequireRange("depth_tolerance", depth_tolerance, 0.0, 1.0);
  RequireRange("depth_tolerance_ratio", depth_tolerance_ratio, 0.0, 1.0);
  RequireRange("depth_jump_ratio", depth_jump_ratio, 1e-4, 10.0);
  RequireRange("edge_margin", edge_margin, 0, 64);
  RequireRange("max_view_angle", max_view_angle, 1.0, 90.0);
  RequireRange("outlier_ratio", outlier_ratio, 1e-3, 100.0);
}

namespace {

using Clock = std::chrono::steady_clock;
double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

constexpr double kNear = 0.01;  // meters

// One keyframe prepared for look-ups.
struct View {
  const RgbdFrame* frame = nullptr;
  Eigen::Isometry3d camera_from_world;
  Eigen::Vector3d center;  // camera centre, world
  ImageDepth zbuffer;
  Image<uint8_t> edges;
  double sharpness_weight = 1.0;
};

struct Hit {
  double u, v, z, cos_angle;
};

// Where world point p with unit normal n lands in view `view`, if the view sees it (module
// comment of backproject.h).
std::optional<Hit> See(const View& view, const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                       const TexturingOptions& o, double cos_max_angle) {
  const Eigen::Vector3d pc = view.camera_from_world * p;
  if (pc.z() < kNear) return std::nullopt;
  const CameraIntrinsics& k = view.frame->intrinsics;
  const double u = k.fx * pc.x() / pc.z() + k.cx;
  const double v = k.fy * pc.y() / pc.z() + k.cy;
  if (!(u >= 0.0 && v >= 0.0 && u <= k.width - 1.0 && v <= k.height - 1.0)) return std::nullopt;
  const Eigen::Vector3d to_camera = view.center - p;
  const double cos_angle = n.dot(to_camera) / to_camera.norm();
  if (!(cos_angle >= cos_max_angle)) return std::nullopt;
  const int pu = static_cast<int>(std::lround(u)), pv = static_cast<int>(std::lround(v));
  if (view.edges(pu, pv)) return std::nullopt;
  const double tolerance = std::max(o.depth_tolerance, o.depth_tolerance_ratio * pc.z());
  const float zb = view.zbuffer(pu, pv);
  if (zb <= 0.0f || pc.z() > zb + tolerance) return std::nullopt;
  if (o.use_sensor_depth && !view.frame->depth.empty()) {
    const float d = view.frame->depth(pu, pv);
    if (d > 0.0f && pc.z() > d + tolerance) return std::nullopt;
  }
  return Hit{u, v, pc.z(), cos_angle};
}

Eigen::Vector3f Bilinear(const ImageRgb& image, double u, double v) {
  const int u0 = std::min(static_cast<int>(u), std::max(0, image.width() - 2));
  const int v0 = std::min(static_cast<int>(v), std::max(0, image.height() - 2));
  const int u1 = std::min(u0 + 1, image.width() - 1), v1 = std::min(v0 + 1, image.height() - 1);
  const float fu = static_cast<float>(u - u0), fv = static_cast<float>(v - v0);
  return (1 - fv) * ((1 - fu) * image(u0, v0) + fu * image(u1, v0)) +
         fv * ((1 - fu) * image(u0, v1) + fu * image(u1, v1));
}

struct ColorSample {
  Eigen::Vector3f color;
  float luminance;
  float weight;
};

// The robust weighted mean of backproject.h; returns the number of samples kept.
int RobustMean(std::vector<ColorSample>& samples, double outlier_ratio, Eigen::Vector3f* out) {
  std::sort(samples.begin(), samples.end(),
            [](const ColorSample& a, const ColorSample& b) { return a.luminance < b.luminance; });
  // One vote per view: a heavily weighted view (near, frontal, sharp) must not carry its own
  // highlight past the median.
  const size_t n = samples.size();
  const float median = n % 2 ? samples[n / 2].luminance
                             : 0.5f * (samples[n / 2 - 1].luminance + samples[n / 2].luminance);
  const double lo = median * (1.0 - outlier_ratio), hi = median * (1.0 + outlier_ratio);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  int kept = 0;
  for (const ColorSample& s : samples) {
    if (s.luminance < lo || s.luminance > hi) continue;
    sum += static_cast<double>(s.weight) * s.color.cast<double>();
    weight += s.weight;
    ++kept;
  }
  if (kept == 0) {  // two views that disagree by more than the ratio: keep the darker one
    sum = samples.front().color.cast<double>();
    weight = 1.0;
    kept = 1;
  }
  *out = (sum / weight).cast<float>();
  return kept;
}

// Per-face resolution (backproject.h): the finest pixel footprint over probe points spread over
// the face at 8x the texel spacing.
std::vector<int> FaceResolutions(const TriangleMesh& mesh, const std::vector<View>& views,
                                 const TexturingOptions& o, double cos_max_angle) {
  std::vector<int> res = ChooseFaceResolutions(mesh, o.texel_spacing, o.max_resolution);
  if (!o.limit_to_image_detail) return res;
  const std::vector<int> probes = ChooseFaceResolutions(mesh, 8.0 * o.texel_spacing, 16);
  ParallelFor(
      0, mesh.faces.size(),
      [&](size_t f) {
        const Eigen::Vector3i& tri = mesh.faces[f];
        const Eigen::Vector3d p0 = mesh.vertices[tri[0]].cast<double>();
        const Eigen::Vector3d p1 = mesh.vertices[tri[1]].cast<double>();
        const Eigen::Vector3d p2 = mesh.vertices[tri[2]].cast<double>();
        const Eigen::Vector3d scaled = (p1 - p0).cross(p2 - p0);
        if (!(scaled.norm() > 0.0)) {
          res[f] = 1;
          return;
        }
        const Eigen::Vector3d n = scaled.normalized();
        const int r = probes[f];
        double footprint = std::numeric_limits<double>::infinity();
        for (int j = 0; j <= r; ++j) {
          for (int i = 0; i + j <= r; ++i) {
            // Probe points pulled 1 % towards the centre so that they belong to this face.
            const double b1 = (0.99 * i + 0.01 * r / 3.0) / r, b2 = (0.99 * j + 0.01 * r / 3.0) / r;
            const Eigen::Vector3d p = (1.0 - b1 - b2) * p0 + b1 * p1 + b2 * p2;
            for (const View& view : views) {
              const auto hit = See(view, p, n, o, cos_max_angle);
              if (hit) footprint = std::min(footprint, hit->z / view.frame->intrinsics.fx);
            }
          }
        }
        if (!std::isfinite(footprint)) {
          res[f] = 1;  // no keyframe sees it: its colour is filled from neighbours anyway
          return;
        }
        const double longest = std::max({(p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm()});
        res[f] =
            ResolutionForSpacing(longest, std::max(o.texel_spacing, footprint), o.max_resolution);
      },
      64);
  return res;
}

// Fills texels no keyframe saw from their lattice neighbours, ring by ring (Jacobi: each ring
// uses only colours known before it, so the result does not depend on the order). Returns the
// number of texels filled; texels that no observed texel reaches keep `fallback`.
size_t FillUnobserved(const MeshColors& layout, std::vector<Eigen::Vector3f>& colors,
                      std::vector<uint8_t>& known, const Eigen::Vector3f& fallback,
                      size_t* unreached) {
  const auto pairs = layout.SampleNeighbours();
  const size_t n = colors.size();
  std::vector<uint32_t> start(n + 1, 0), adjacent(2 * pairs.size());
  for (const auto& [a, b] : pairs) ++start[a + 1], ++start[b + 1];
  for (size_t s = 0; s < n; ++s) start[s + 1] += start[s];
  std::vector<uint32_t> fill(start.begin(), start.end() - 1);
  for (const auto& [a, b] : pairs) adjacent[fill[a]++] = b, adjacent[fill[b]++] = a;
  size_t filled = 0;
  std::vector<uint32_t> frontier;
  for (size_t s = 0; s < n; ++s) {
    if (!known[s]) frontier.push_back(static_cast<uint32_t>(s));
  }
  while (!frontier.empty()) {
    std::vector<std::pair<uint32_t, Eigen::Vector3f>> ring;
    std::vector<uint32_t> rest;
    for (uint32_t s : frontier) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      int count = 0;
      for (uint32_t k = start[s]; k < start[s + 1]; ++k) {
        if (known[adjacent[k]]) sum += colors[adjacent[k]], ++count;
      }
      if (count > 0) {
        ring.emplace_back(s, sum / static_cast<float>(count));
      } else {
        rest.push_back(s);
      }
    }
    if (ring.empty()) break;
    for (const auto& [s, c] : ring) colors[s] = c, known[s] = 1;
    filled += ring.size();
    frontier.swap(rest);
  }
  for (uint32_t s : frontier) colors[s] = fallback;
  *unreached = frontier.size();
  return filled;
}

}  // namespace

TexturingResult TextureMesh(const TriangleMesh& input_mesh, const std::vector<RgbdFrame>& keyframes,
                            const TexturingOptions& options) {
  options.Validate();
  if (input_mesh.faces.empty()) throw Error("texturing: the mesh has no faces, nothing to texture");
  input_mesh.Validate("texturing mesh");
  if (keyframes.empty()) throw Error("texturing: no keyframes (posed colour images are needed)");
  for (size_t i = 0; i < keyframes.size(); ++i) {
    const RgbdFrame& f = keyframes[i];
    const std::string name = f.color_path.empty() ? Format("keyframe ", i)
                                                  : Format("keyframe ", i, " (", f.color_path, ")");
    if (!f.world_from_camera) throw Error(Format("texturing: ", name, " has no camera pose"));
    if (f.color.empty()) throw Error(Format("texturing: ", name, " has no colour image"));
    f.Validate();
  }
  TriangleMesh mesh = input_mesh;
  if (mesh.normals.size() != mesh.vertices.size()) mesh.ComputeVertexNormals();
  const double cos_max_angle = std::cos(options.max_view_angle * M_PI / 180.0);

  TexturingResult result;
  TexturingStats& stats = result.stats;
  stats.keyframes = static_cast<int>(keyframes.size());

  // Visibility: one z-buffer and edge mask per keyframe.
  auto t0 = Clock::now();
  std::vector<View> views(keyframes.size());
  ParallelFor(
      0, keyframes.size(),
      [&](size_t i) {
        View& view = views[i];
        view.frame = &keyframes[i];
        view.camera_from_world = keyframes[i].world_from_camera->inverse();
        view.center = keyframes[i].world_from_camera->translation();
        view.zbuffer = RenderDepth(mesh, keyframes[i].intrinsics, view.camera_from_world, kNear);
        // The margin shrinks on thumbnails: at most 1/40 of the image's smaller side.
        const int margin =
            std::min(options.edge_margin,
                     std::min(keyframes[i].intrinsics.width, keyframes[i].intrinsics.height) / 40);
        view.edges = DepthEdgeMask(view.zbuffer, options.depth_jump_ratio, margin);
        if (options.use_sensor_depth && !keyframes[i].depth.empty()) {
          // Discontinuities the mesh lacks (objects not fused, moved things) mix colours too.
          const Image<uint8_t> sensor = DepthEdgeMask(keyframes[i].depth, options.depth_jump_ratio,
                                                      margin, /*empty_is_edge=*/false);
          for (size_t p = 0; p < sensor.size(); ++p) view.edges.pixels()[p] |= sensor.pixels()[p];
        }
        view.sharpness_weight = Sharpness(keyframes[i].color);
      },
      1);
  double sharpest = 0.0;
  for (const View& view : views) sharpest = std::max(sharpest, view.sharpness_weight);
  for (View& view : views) {
    view.sharpness_weight = sharpest > 0.0 ? std::max(0.25, view.sharpness_weight / sharpest) : 1.0;
  }
  stats.seconds_visibility = SecondsSince(t0);

  // Layout, then every texel from every keyframe.
  t0 = Clock::now();
  result.texture = MeshColors(mesh, FaceResolutions(mesh, views, options, cos_max_angle));
  MeshColors& texture = result.texture;
  const std::vector<Eigen::Vector3f> positions = texture.InterpolateVertexAttribute(mesh.vertices);
  const std::vector<Eigen::Vector3f> normals = texture.InterpolateVertexAttribute(mesh.normals);
  const size_t n = texture.SampleCount();
  stats.texels = n;
  std::vector<uint8_t> known(n, 0);
  std::vector<uint16_t> used(n, 0), rejected(n, 0);
  std::vector<std::atomic<uint8_t>> seen_by(views.size());
  ParallelForChunks(0, n, 1024, [&](size_t begin, size_t end) {
    std::vector<ColorSample> samples;
    for (size_t s = begin; s < end; ++s) {
      if (s < texture.VertexSampleCount() && texture.IsolatedVertex(static_cast<int>(s))) continue;
      const Eigen::Vector3d p = positions[s].cast<double>();
      Eigen::Vector3d normal = normals[s].cast<double>();
      if (!(normal.norm() > 0.0)) continue;
      normal.normalize();
      samples.clear();
      for (size_t k = 0; k < views.size(); ++k) {
        const auto hit = See(views[k], p, normal, options, cos_max_angle);
        if (!hit) continue;
        ColorSample c;
        c.color = Bilinear(views[k].frame->color, hit->u, hit->v);
        c.luminance = Luminance(c.color);
        c.weight =
            static_cast<float>(hit->cos_angle / (hit->z * hit->z) * views[k].sharpness_weight);
        samples.push_back(c);
        seen_by[k].store(1, std::memory_order_relaxed);
      }
      if (samples.empty()) continue;
      const int kept = RobustMean(samples, options.outlier_ratio, &texture.colors()[s]);
      known[s] = 1;
      used[s] = static_cast<uint16_t>(std::min(kept, 65535));
      rejected[s] = static_cast<uint16_t>(std::min<size_t>(samples.size() - kept, 65535));
    }
  });
  for (size_t s = 0; s < n; ++s) {
    stats.observed += known[s];
    stats.samples_used += used[s];
    stats.samples_rejected += rejected[s];
  }
  for (const auto& b : seen_by) stats.keyframes_seeing_mesh += b.load();
  if (stats.observed == 0) {
    throw Error(
        Format("texturing: none of the ", keyframes.size(),
               " keyframes sees the mesh (check that poses and mesh share one world frame)"));
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t s = 0; s < n; ++s) {
    if (known[s]) mean += texture.colors()[s].cast<double>();
  }
  mean /= static_cast<double>(stats.observed);
  for (int v = 0; v < texture.num_vertices(); ++v) {
    if (texture.IsolatedVertex(v))
      known[v] = 1, ++stats.isolated;  // stays black; nothing to fill from
  }
  stats.filled =
      FillUnobserved(texture, texture.colors(), known, mean.cast<float>(), &stats.unreached);
  texture.labels().assign(used.begin(), used.end());
  stats.seconds_backproject = SecondsSince(t0);
  return result;
}

}  // namespace genscene::texturing
