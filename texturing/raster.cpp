#include "texturing/raster.h"

#include <algorithm>
#include <cmath>

namespace genscene::texturing {

namespace {

// Sutherland-Hodgman clip of a camera-space polygon against z >= near.
int ClipNear(const Eigen::Vector3d in[3], double near, Eigen::Vector3d out[4]) {
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d& a = in[k];
    const Eigen::Vector3d& b = in[(k + 1) % 3];
    const bool a_in = a.z() >= near, b_in = b.z() >= near;
    if (a_in) out[n++] = a;
    if (a_in != b_in) {
      const double t = (near - a.z()) / (b.z() - a.z());
      out[n++] = a + t * (b - a);
    }
  }
  return n;
}

// Draws one camera-space triangle (all z >= near) into the z-buffer.
void DrawTriangle(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                  const CameraIntrinsics& k, ImageDepth& depth) {
  const Eigen::Vector2d s0(k.fx * p0.x() / p0.z() + k.cx, k.fy * p0.y() / p0.z() + k.cy);
  const Eigen::Vector2d s1(k.fx * p1.x() / p1.z() + k.cx, k.fy * p1.y() / p1.z() + k.cy);
  const Eigen::Vector2d s2(k.fx * p2.x() / p2.z() + k.cx, k.fy * p2.y() / p2.z() + k.cy);
  const double area = (s1 - s0).x() * (s2 - s0).y() - (s1 - s0).y() * (s2 - s0).x();
  if (!(std::abs(area) > 1e-12)) return;  // degenerate, or edge-on
  const double lo_u = std::min({s0.x(), s1.x(), s2.x()}), hi_u = std::max({s0.x(), s1.x(), s2.x()});
  const double lo_v = std::min({s0.y(), s1.y(), s2.y()}), hi_v = std::max({s0.y(), s1.y(), s2.y()});
  if (hi_u < 0.0 || hi_v < 0.0 || lo_u > depth.width() - 1.0 || lo_v > depth.height() - 1.0) return;
  const int u0 = std::max(0, static_cast<int>(std::ceil(lo_u)));
  const int u1 = std::min(depth.width() - 1, static_cast<int>(std::floor(hi_u)));
  const int v0 = std::max(0, static_cast<int>(std::ceil(lo_v)));
  const int v1 = std::min(depth.height() - 1, static_cast<int>(std::floor(hi_v)));
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
      const float z = static_cast<float>(1.0 / (w0 * iz0 + w1 * iz1 + w2 * iz2));
      float& d = depth(u, v);
      if (d == 0.0f || z < d) d = z;
    }
  }
}

}  // namespace

ImageDepth RenderDepth(const TriangleMesh& mesh, const CameraIntrinsics& intrinsics,
                       const Eigen::Isometry3d& camera_from_world, double near) {
  ImageDepth depth(intrinsics.width, intrinsics.height, 0.0f);
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d p[3] = {camera_from_world * mesh.vertices[f[0]].cast<double>(),
                                  camera_from_world * mesh.vertices[f[1]].cast<double>(),
                                  camera_from_world * mesh.vertices[f[2]].cast<double>()};
    if (p[0].z() < near && p[1].z() < near && p[2].z() < near) continue;
    Eigen::Vector3d clipped[4];
    const int n = ClipNear(p, near, clipped);
    for (int k = 1; k + 1 < n; ++k) DrawTriangle(clipped[0], clipped[k], clipped[k + 1], intrinsics, depth);
  }
  return depth;
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
