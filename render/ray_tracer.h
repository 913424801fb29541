// The one wrapper around Embree 3 (DESIGN.md §3): device, scene, error callback, triangle
// meshes, vertex-buffer update + refit. Nothing outside ray_tracer.cpp sees an RTC* type.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "core/mesh.h"

namespace genscene::render {

struct RayHit {
  float t = 0.0f;   // distance along the (unit or not) ray direction
  int mesh = -1;    // index of the mesh, in the order AddMesh was called
  int face = -1;    // triangle index in that mesh
  float b1 = 0.0f;  // barycentric weight of the face's second vertex
  float b2 = 0.0f;  // barycentric weight of the third vertex (first: 1 - b1 - b2)
};

class RayTracer {
 public:
  RayTracer();
  ~RayTracer();
  RayTracer(const RayTracer&) = delete;
  RayTracer& operator=(const RayTracer&) = delete;

  // Adds a mesh (vertices and faces are copied into Embree's buffers); returns its index.
  // Meshes added with `dynamic` can move later through UpdateVertices.
  int AddMesh(const TriangleMesh& mesh, bool dynamic = false);
  // Builds the acceleration structure; call after the last AddMesh and before tracing.
  void Commit();
  // Replaces the vertex positions of a dynamic mesh (same count) and refits the hierarchy.
  void UpdateVertices(int mesh, const std::vector<Eigen::Vector3f>& vertices);

  // Nearest hit with t in [t_min, t_max]. Thread-safe after Commit().
  std::optional<RayHit> Intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                                  float t_min = 0.0f, float t_max = INFINITY) const;
  // True when anything blocks the segment t in [t_min, t_max].
  bool Occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_min,
                float t_max) const;
  // True when anything blocks the open segment from `from` to `to`: the last 1e-4 of its length
  // is left out, so that the surface a shadow ray ends on (an area light) does not block it.
  bool SegmentOccluded(const Eigen::Vector3f& from, const Eigen::Vector3f& to) const;
  // Occlusion of n segments from one origin, as Occluded(origin, directions[i], t_min, t_max[i])
  // for each i, into occluded[i] (1 when blocked). Traced in packets of 16 (rtcOccluded16): the
  // shadow rays of one path vertex to many voxel lights, 1.3x faster than one by one (Embree's
  // stream API, rtcOccluded1M, was no faster than single rays).
  void OccludedFrom(const Eigen::Vector3f& origin, const Eigen::Vector3f* directions,
                    const float* t_max, int n, float t_min, uint8_t* occluded) const;

  int MeshCount() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace genscene::render
