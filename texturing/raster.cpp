#include "texturing/raster.h"

#include <algorithm>
#include <cmath>

namespace genscene::texturing {

namespace {

// A camera-space vertex with its barycentric coordinates in the original (unclipped) triangle.
struct ClipVertex {
  Eigen::Vector3d p;
  Eigen::Vector3d bary;
};

// Sutherland-Hodgman clip of a camera-space triangle against z >= near.
int ClipNear(const ClipVertex in[3], double near, ClipVertex out[4]) {
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    const ClipVertex& a = in[k];
    const ClipVertex& b = in[(k + 1) % 3];
    const bool a_in = a.p.z() >= near, b_in = b.p.z() >= near;
    if (a_in) out[n++] = a;
    if (a_in != b_in) {
      const double t = (near - a.p.z()) / (b.p.z() - a.p.z());
      out[n++] = {a.p + t * (b.p - a.p), a.bary + t * (b.bary - a.bary)};
    }
  }
  return n;
}

// Calls pixel(u, v, z, bary) for every pixel centre inside one camera-space triangle (all
// z >= near); bary is perspective-correct, in the original triangle's coordinates.
template <typename Pixel>
void DrawTriangle(const ClipVertex& c0, const ClipVertex& c1, const ClipVertex& c2,
                  const CameraIntrinsics& k, const Pixel& pixel) {
  const Eigen::Vector3d &p0 = c0.p, &p1 = c1.p, &p2 = c2.p;
  const Eigen::Vector2d s0(k.fx * p0.x() / p0.z() + k.cx, k.fy * p0.y() / p0.z() + k.cy);
  const Eigen::Vector2d s1(k.fx * p1.x() / p1.z() + k.cx, k.fy * p1.y() / p1.z() + k.cy);
  const Eigen::Vector2d s2(k.fx * p2.x() / p2.z() + k.cx, k.fy * p2.y() / p2.z() + k.cy);
  const double area = (s1 - s0).x() * (s2 - s0).y() - (s1 - s0).y() * (s2 - s0).x();
  if (!(std::abs(area) > 1e-12)) return;  // degenerate, or edge-on
  const double lo_u = std::min({s0.x(), s1.x(), s2.x()}), hi_u = std::max({s0.x(), s1.x(), s2.x()});
  const double lo_v = std::min({s0.y(), s1.y(), s2.y()}), hi_v = std::max({s0.y(), s1.y(), s2.y()});
  if (hi_u < 0.0 || hi_v < 0.0 || lo_u > k.width - 1.0 || lo_v > k.height - 1.0) return;
  const int u0 = std::max(0, static_cast<int>(std::ceil(lo_u)));
  const int u1 = std::min(k.width - 1, static_cast<int>(std::floor(hi_u)));
  const int v0 = std::max(0, static_cast<int>(std::ceil(lo_v)));
  const int v1 = std::min(k.height - 1, static_cast<int>(std::floor(hi_v)));
  const double inv_area = 1.0 / area;
  const double iz0 = 1.0 / p0.z(), iz1 = 1.0 / p1.z(), iz2 = 1.0 / p2.z();
  for (int v = v0; v <= v1; ++v) {
    for (int u = u0; u <= u1; ++u) {
      const Eigen::Vector2d p(u, v);
      // Screen-space barycentrics; inclusive edges (a z-buffer does not mind double coverage).
      const double w0 = ((s1 - p).x() * (s2 - p).y() - (s1 - p).y() * (s2 - p).x()) * inv_area;
      const double w1 = ((s2 - p).x() * (s0 - p).y() - (s2 - p).y() * (s0 - p).x()) * inv_area;
      const double w2 = 1.0 - w0 - w1;
      if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) continue;
      const double inv_z = w0 * iz0 + w1 * iz1 + w2 * iz2;
      pixel(u, v, 1.0 / inv_z, [&] {
        return Eigen::Vector3d((w0 * iz0 * c0.bary + w1 * iz1 * c1.bary + w2 * iz2 * c2.bary) /
                               inv_z);
      });
    }
  }
}

// Clips and draws every face of the mesh.
template <typename Pixel>
void DrawMesh(const TriangleMesh& mesh, const CameraIntrinsics& intrinsics,
              const Eigen::Isometry3d& camera_from_world, double near, const Pixel& pixel) {
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const Eigen::Vector3i& tri = mesh.faces[f];
    const ClipVertex c[3] = {
        {camera_from_world * mesh.vertices[tri[0]].cast<double>(), Eigen::Vector3d::UnitX()},
        {camera_from_world * mesh.vertices[tri[1]].cast<double>(), Eigen::Vector3d::UnitY()},
        {camera_from_world * mesh.vertices[tri[2]].cast<double>(), Eigen::Vector3d::UnitZ()}};
    if (c[0].p.z() < near && c[1].p.z() < near && c[2].p.z() < near) continue;
    ClipVertex clipped[4];
    const int n = ClipNear(c, near, clipped);
    for (int k = 1; k + 1 < n; ++k) {
      DrawTriangle(clipped[0], clipped[k], clipped[k + 1], intrinsics,
                   [&](int u, int v, double z, const auto& bary) {
                     pixel(static_cast<int>(f), u, v, z, bary);
                   });
    }
  }
}

}  // namespace

ImageDepth RenderDepth(const TriangleMesh& mesh, const CameraIntrinsics& intrinsics,
                       const Eigen::Isometry3d& camera_from_world, double near) {
  ImageDepth depth(intrinsics.width, intrinsics.height, 0.0f);
  DrawMesh(mesh, intrinsics, camera_from_world, near,
           [&](int, int u, int v, double z, const auto&) {
             float& d = depth(u, v);
             if (d == 0.0f || z < d) d = static_cast<float>(z);
           });
  return depth;
}

SurfaceImage RenderSurface(const TriangleMesh& mesh, const CameraIntrinsics& intrinsics,
                           const Eigen::Isometry3d& camera_from_world, double near) {
  SurfaceImage out;
  out.depth = ImageDepth(intrinsics.width, intrinsics.height, 0.0f);
  out.face = Image<int>(intrinsics.width, intrinsics.height, -1);
  out.b1 = ImageDepth(intrinsics.width, intrinsics.height, 0.0f);
  out.b2 = ImageDepth(intrinsics.width, intrinsics.height, 0.0f);
  DrawMesh(mesh, intrinsics, camera_from_world, near,
           [&](int f, int u, int v, double z, const auto& bary) {
             float& d = out.depth(u, v);
             if (d != 0.0f && z >= d) return;
             d = static_cast<float>(z);
             const Eigen::Vector3d b = bary();
             out.face(u, v) = f;
             out.b1(u, v) = static_cast<float>(b.y());
             out.b2(u, v) = static_cast<float>(b.z());
           });
  return out;
}

Image<uint8_t> DepthEdgeMask(const ImageDepth& depth, double jump_ratio, int radius,
                             bool empty_is_edge) {
  const int w = depth.width(), h = depth.height();
  Image<uint8_t> edge(w, h, 0);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const float z = depth(u, v);
      if (z <= 0.0f) continue;
      const int du[4] = {1, -1, 0, 0}, dv[4] = {0, 0, 1, -1};
      for (int k = 0; k < 4; ++k) {
        const int uu = u + du[k], vv = v + dv[k];
        if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
        const float zn = depth(uu, vv);
        if (zn <= 0.0f ? empty_is_edge : std::abs(zn - z) > jump_ratio * std::min(z, zn)) {
          edge(u, v) = 1;
          break;
        }
      }
    }
  }
  if (radius <= 0) return edge;
  // Square dilation, separable: rows then columns.
  Image<uint8_t> rows(w, h, 0), out(w, h, 0);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      if (!edge(u, v)) continue;
      for (int x = std::max(0, u - radius); x <= std::min(w - 1, u + radius); ++x) rows(x, v) = 1;
    }
  }
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      if (!rows(u, v)) continue;
      for (int y = std::max(0, v - radius); y <= std::min(h - 1, v + radius); ++y) out(u, y) = 1;
    }
  }
  return out;
}

}  // namespace genscene::texturing
