#include "render/ray_tracer.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <string>

#include "core/check.h"

namespace genscene::render {

namespace {

// Embree reports errors through a callback; we turn the first one into an exception at the next
// checkpoint of the calling thread (throwing through Embree's C frames is not allowed).
struct ErrorState {
  std::mutex mutex;
  std::string message;
};

void OnEmbreeError(void* user, RTCError code, const char* text) {
  auto* state = static_cast<ErrorState*>(user);
  std::lock_guard<std::mutex> lock(state->mutex);
  if (state->message.empty())
    state->message = Format("Embree error ", static_cast<int>(code), ": ", text ? text : "");
}

}  // namespace

struct RayTracer::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ErrorState errors;
  std::vector<RTCGeometry> geometries;  // owned references, index = mesh
  std::vector<size_t> vertex_counts;
  std::vector<bool> dynamic;
  bool committed = false;

  void ThrowIfError(const char* where) {
    std::lock_guard<std::mutex> lock(errors.mutex);
    if (!errors.message.empty()) {
      const std::string message = Format(where, ": ", errors.message);
      errors.message.clear();
      throw Error(message);
    }
  }
};

RayTracer::RayTracer() : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  if (!impl_->device)
    throw Error(Format("cannot create the Embree device (error ", rtcGetDeviceError(nullptr), ")"));
  rtcSetDeviceErrorFunction(impl_->device, OnEmbreeError, &impl_->errors);
  impl_->scene = rtcNewScene(impl_->device);
  // Robust mode: no missed hits on shared edges, at a small cost in speed.
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  impl_->ThrowIfError("RayTracer");
}

RayTracer::~RayTracer() {
  for (RTCGeometry g : impl_->geometries) rtcReleaseGeometry(g);
  if (impl_->scene) rtcReleaseScene(impl_->scene);
  if (impl_->device) rtcReleaseDevice(impl_->device);
}

int RayTracer::AddMesh(const TriangleMesh& mesh, bool dynamic) {
  mesh.Validate("RayTracer::AddMesh");
  RTCGeometry geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0,
                                                               RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                               mesh.vertices.size()));
  auto* indices = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                              3 * sizeof(unsigned), mesh.faces.size()));
  impl_->ThrowIfError("RayTracer::AddMesh");
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    std::memcpy(vertices + 3 * i, mesh.vertices[i].data(), 3 * sizeof(float));
  }
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) indices[3 * f + k] = static_cast<unsigned>(mesh.faces[f][k]);
  }
  // Dynamic meshes are refitted, not rebuilt, when their vertices move.
  if (dynamic) rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_REFIT);
  rtcCommitGeometry(geometry);
  const int id = static_cast<int>(impl_->geometries.size());
  rtcAttachGeometryByID(impl_->scene, geometry, static_cast<unsigned>(id));
  impl_->geometries.push_back(geometry);
  impl_->vertex_counts.push_back(mesh.vertices.size());
  impl_->dynamic.push_back(dynamic);
  impl_->committed = false;
  impl_->ThrowIfError("RayTracer::AddMesh");
  return id;
}

void RayTracer::Commit() {
  rtcCommitScene(impl_->scene);
  impl_->committed = true;
  impl_->ThrowIfError("RayTracer::Commit");
}

void RayTracer::UpdateVertices(int mesh, const std::vector<Eigen::Vector3f>& vertices) {
  GS_CHECK(mesh >= 0 && mesh < MeshCount());
  if (!impl_->dynamic[mesh])
    throw Error(Format("RayTracer: mesh ", mesh, " was not added as dynamic"));
  GS_CHECK_EQ(vertices.size(), impl_->vertex_counts[mesh]);
  RTCGeometry geometry = impl_->geometries[mesh];
  auto* buffer = static_cast<float*>(rtcGetGeometryBufferData(geometry, RTC_BUFFER_TYPE_VERTEX, 0));
  for (size_t i = 0; i < vertices.size(); ++i) {
    if (!vertices[i].allFinite())
      throw Error(Format("RayTracer: vertex ", i, " of mesh ", mesh, " is not finite"));
    std::memcpy(buffer + 3 * i, vertices[i].data(), 3 * sizeof(float));
  }
  rtcUpdateGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0);
  rtcCommitGeometry(geometry);
  Commit();
}

namespace {

void FillRay(RTCRay& ray, const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t_min,
             float t_max) {
  ray.org_x = o.x();
  ray.org_y = o.y();
  ray.org_z = o.z();
  ray.dir_x = d.x();
  ray.dir_y = d.y();
  ray.dir_z = d.z();
  ray.tnear = t_min;
  ray.tfar = t_max;
  ray.time = 0.0f;
  ray.mask = 0xFFFFFFFFu;
  ray.id = 0;
  ray.flags = 0;
}

}  // namespace

std::optional<RayHit> RayTracer::Intersect(const Eigen::Vector3f& origin,
                                           const Eigen::Vector3f& direction, float t_min,
                                           float t_max) const {
  GS_CHECK(impl_->committed);
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  FillRay(rh.ray, origin, direction, t_min, t_max);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  RayHit hit;
  hit.t = rh.ray.tfar;
  hit.mesh = static_cast<int>(rh.hit.geomID);
  hit.face = static_cast<int>(rh.hit.primID);
  hit.b1 = rh.hit.u;
  hit.b2 = rh.hit.v;
  return hit;
}

bool RayTracer::Occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                         float t_min, float t_max) const {
  GS_CHECK(impl_->committed);
  if (!(t_max > t_min)) return false;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray;
  FillRay(ray, origin, direction, t_min, t_max);
  rtcOccluded1(impl_->scene, &context, &ray);
  return ray.tfar == -INFINITY;
}

bool RayTracer::SegmentOccluded(const Eigen::Vector3f& from, const Eigen::Vector3f& to) const {
  const Eigen::Vector3f d = to - from;
  const float length = d.norm();
  if (!(length > 0.0f)) return false;
  return Occluded(from, d / length, 0.0f, length * (1.0f - 1e-4f));
}

void RayTracer::OccludedFrom(const Eigen::Vector3f& origin, const Eigen::Vector3f* directions,
                             const float* t_max, int n, float t_min, uint8_t* occluded) const {
  GS_CHECK(impl_->committed);
  RTCRay16 packet;
  alignas(64) int valid[16];
  for (int begin = 0; begin < n; begin += 16) {
    const int count = std::min(16, n - begin);
    bool any = false;
    for (int r = 0; r < 16; ++r) {
      const int i = begin + r;
      valid[r] = r < count && t_max[i] > t_min ? -1 : 0;
      any = any || valid[r] != 0;
      const Eigen::Vector3f d = r < count ? directions[i] : Eigen::Vector3f::UnitZ();
      packet.org_x[r] = origin.x();
      packet.org_y[r] = origin.y();
      packet.org_z[r] = origin.z();
      packet.dir_x[r] = d.x();
      packet.dir_y[r] = d.y();
      packet.dir_z[r] = d.z();
      packet.tnear[r] = t_min;
      packet.tfar[r] = r < count ? t_max[i] : t_min;
      packet.time[r] = 0.0f;
      packet.mask[r] = 0xFFFFFFFFu;
      packet.id[r] = 0;
      packet.flags[r] = 0;
    }
    if (any) {
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      rtcOccluded16(valid, impl_->scene, &context, &packet);
    }
    for (int r = 0; r < count; ++r)
      occluded[begin + r] = valid[r] != 0 && packet.tfar[r] == -INFINITY ? 1 : 0;
  }
}

int RayTracer::MeshCount() const {
  return static_cast<int>(impl_->geometries.size());
}

}  // namespace genscene::render
