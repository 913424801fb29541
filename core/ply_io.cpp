// PLY mesh I/O. OpenMesh 9 parses and writes the PLY data; this file adds what OpenMesh lacks:
//
// - Header check first, and a normalised header (core/ply_format.h). We parse and check the
//   header ourselves, walk the data once, and hand OpenMesh a stream made of a canonical header
//   we write followed by the file's data.
// - Our own importer/exporter. OpenMesh's ImporterT builds half-edge connectivity: for a face that
//   would make the mesh non-manifold it DUPLICATES the face's vertices (appended at the end), and
//   it DROPS faces with a repeated or invalid vertex index (evidence: a 5-vertex "fin" of 3
//   triangles on one edge plus a degenerate face reads as 8 vertices / 3 faces with read_mesh into
//   a PolyMesh or TriMesh). Meshes from marching cubes are often non-manifold, so instead our
//   BaseImporter records exactly the vertices and faces of the file, in file order, without
//   connectivity; our BaseExporter writes a TriangleMesh as it is (no half-edge mesh either).
// - Custom properties: OpenMesh's PLY reader (with Options::Custom) stores non-standard properties,
//   such as the float face properties albedo_r/g/b, as named properties of the importer's kernel,
//   in ASCII and binary; its writer writes every *persistent* float property of the exporter's
//   kernel, as `property float <name>`. Both are used here for albedo_r/g/b.
//
// Polygons with more than 3 vertices are fan-triangulated: (v0, v1, ..., vn-1) becomes the
// triangles (v0, vk, vk+1), k = 1 .. n-2, in that order, each with the polygon's colour. The face
// count of the result is then the sum of (n - 2) over the file's faces. A face with a repeated
// vertex index is kept as it is (a degenerate triangle), as the file says.
//
// OpenMesh's reader and writer are singletons with mutable state, so calls into them are
// serialised by a mutex; OpenMesh's log streams are silenced during those calls (our Errors say
// what went wrong).
#include "core/ply_io.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/exporter/BaseExporter.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/Mesh/BaseKernel.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include "core/check.h"
#include "core/color.h"
#include "core/file_util.h"
#include "core/ply_format.h"

namespace genscene {

namespace {

namespace fs = std::filesystem;
using OpenMesh::EdgeHandle;
using OpenMesh::FaceHandle;
using OpenMesh::HalfedgeHandle;
using OpenMesh::VertexHandle;
using ply::kAlbedo;
using ply::PlyLayout;

// ------------------------------------------------------------------------------------------------
// OpenMesh adapters.

std::mutex& OpenMeshMutex() {
  static std::mutex mutex;
  return mutex;
}

// Silences OpenMesh's log streams for the life of the object (restores their previous state).
class QuietOpenMesh {
 public:
  QuietOpenMesh()
      : err_(omerr().is_enabled()), log_(omlog().is_enabled()), out_(omout().is_enabled()) {
    omerr().disable();
    omlog().disable();
    omout().disable();
  }
  ~QuietOpenMesh() {
    if (err_) omerr().enable();
    if (log_) omlog().enable();
    if (out_) omout().enable();
  }
  QuietOpenMesh(const QuietOpenMesh&) = delete;
  QuietOpenMesh& operator=(const QuietOpenMesh&) = delete;

 private:
  bool err_, log_, out_;
};

// Holds the named (custom) properties OpenMesh's PLY reader and writer use, for a mesh of
// n_vertices / n_faces elements without connectivity.
class PropertyKernel final : public OpenMesh::BaseKernel {
 public:
  size_t n_vertices() const override { return n_vertices_; }
  size_t n_faces() const override { return n_faces_; }
  void Reserve(size_t vertices, size_t faces) {
    vprops_reserve(vertices);
    fprops_reserve(faces);
  }
  void SetVertexCount(size_t n) {
    n_vertices_ = n;
    vprops_resize(n);
  }
  void SetFaceCount(size_t n) {
    n_faces_ = n;
    fprops_resize(n);
  }

 private:
  size_t n_vertices_ = 0;
  size_t n_faces_ = 0;
};

// Reads the three float or double properties `names` of every element of one kind; false when
// the kernel does not have them.
template <template <typename> class PropHandle, typename ElementHandle, typename T>
bool ReadChannels(const OpenMesh::BaseKernel& kernel, const std::array<const char*, 3>& names,
                  size_t n, std::vector<Eigen::Vector3f>* out) {
  PropHandle<T> handles[3];
  for (int c = 0; c < 3; ++c) {
    if (!kernel.get_property_handle(handles[c], names[static_cast<size_t>(c)])) return false;
  }
  out->resize(n);
  for (size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      (*out)[i][c] =
          static_cast<float>(kernel.property(handles[c], ElementHandle(static_cast<int>(i))));
    }
  }
  return true;
}

template <template <typename> class PropHandle, typename ElementHandle>
bool ReadFloatChannels(const OpenMesh::BaseKernel& kernel, const std::array<const char*, 3>& names,
                       size_t n, std::vector<Eigen::Vector3f>* out) {
  return ReadChannels<PropHandle, ElementHandle, float>(kernel, names, n, out) ||
         ReadChannels<PropHandle, ElementHandle, double>(kernel, names, n, out);
}

Eigen::Vector3f SrgbBytesToLinear(const OpenMesh::Vec3uc& c) {
  return {SrgbToLinear(c[0] / 255.0f), SrgbToLinear(c[1] / 255.0f), SrgbToLinear(c[2] / 255.0f)};
}

// Receives what OpenMesh's PLY reader parses, exactly as the file has it: no connectivity, no
// duplicated vertices, no dropped faces. Problems are recorded, not thrown, because OpenMesh's
// reader must not be unwound mid-read (it toggles global log state).
class CollectingImporter final : public OpenMesh::IO::BaseImporter {
 public:
  using BaseImporter::add_vertex;
  CollectingImporter(size_t file_vertices, size_t file_faces, const PlyLayout& layout)
      : file_vertices_(file_vertices), layout_(layout) {
    first_triangle_.reserve(file_faces + 1);
    first_triangle_.push_back(0);
  }

  const std::string& problem() const { return problem_; }
  size_t polygon_count() const { return first_triangle_.size() - 1; }

  TriangleMesh Build(const std::string& name) {
    TriangleMesh mesh;
    const size_t nv = positions_.size();
    mesh.vertices = std::move(positions_);
    if (layout_.vertex_normals) mesh.normals = std::move(normals_);
    if (layout_.vertex_albedo) {
      if (!ReadFloatChannels<OpenMesh::VPropHandleT, VertexHandle>(kernel_, kAlbedo, nv,
                                                                   &mesh.vertex_colors) &&
          nv > 0) {
        throw Error(Format(name, ": OpenMesh did not deliver the vertex albedo_r/g/b properties"));
      }
    } else if (layout_.vertex_rgb) {
      mesh.vertex_colors.resize(nv);
      for (size_t i = 0; i < nv; ++i) mesh.vertex_colors[i] = SrgbBytesToLinear(vertex_rgb_[i]);
    }
    mesh.faces = std::move(triangles_);
    const size_t polygons = polygon_count();
    std::vector<Eigen::Vector3f> polygon_colors;
    if (layout_.face_albedo) {
      if (!ReadFloatChannels<OpenMesh::FPropHandleT, FaceHandle>(kernel_, kAlbedo, polygons,
                                                                 &polygon_colors) &&
          polygons > 0) {
        throw Error(Format(name, ": OpenMesh did not deliver the face albedo_r/g/b properties"));
      }
    } else if (layout_.face_rgb) {
      polygon_colors.resize(polygons);
      for (size_t f = 0; f < polygons; ++f) polygon_colors[f] = SrgbBytesToLinear(face_rgb_[f]);
    }
    if (layout_.face_albedo || layout_.face_rgb) {
      mesh.face_colors.resize(mesh.faces.size());
      for (size_t f = 0; f < polygons; ++f) {
        for (size_t t = first_triangle_[f]; t < first_triangle_[f + 1]; ++t)
          mesh.face_colors[t] = polygon_colors[f];
      }
    }
    return mesh;
  }

  // --- what the PLY reader calls.
  VertexHandle add_vertex(const OpenMesh::Vec3f& point) override {
    const VertexHandle vh = add_vertex();
    set_point(vh, point);
    return vh;
  }
  VertexHandle add_vertex() override {
    positions_.emplace_back(0.0f, 0.0f, 0.0f);
    if (layout_.vertex_normals) normals_.emplace_back(0.0f, 0.0f, 0.0f);
    if (layout_.vertex_rgb) vertex_rgb_.emplace_back(0, 0, 0);
    kernel_.SetVertexCount(positions_.size());
    return VertexHandle(static_cast<int>(positions_.size() - 1));
  }
  FaceHandle add_face(const VHandles& indices) override {
    const size_t polygon = polygon_count();
    if (indices.size() < 3) Note(Format("face ", polygon, " has ", indices.size(), " vertices"));
    for (size_t i = 0; i < indices.size() && problem_.empty(); ++i) {
      const int index = indices[i].idx();
      if (index < 0 || static_cast<size_t>(index) >= file_vertices_) {
        Note(Format("face ", polygon, " uses vertex ", index, " but the file has ", file_vertices_,
                    " vertices"));
      }
    }
    // After a problem the file is refused: count the polygon, build nothing (a corrupt ASCII file
    // fed OpenMesh's reader faces of millions of bogus indices, found by fuzz_ply: a 1.8 KB file
    // took 1.9 s, a message formatted per index).
    for (size_t k = 1; problem_.empty() && k + 1 < indices.size(); ++k) {  // fan triangulation
      triangles_.emplace_back(indices[0].idx(), indices[k].idx(), indices[k + 1].idx());
    }
    first_triangle_.push_back(triangles_.size());
    if (layout_.face_rgb) face_rgb_.emplace_back(0, 0, 0);
    kernel_.SetFaceCount(polygon + 1);
    return FaceHandle(static_cast<int>(polygon));
  }
  void set_point(VertexHandle vh, const OpenMesh::Vec3f& p) override {
    if (ValidVertex(vh)) positions_[Index(vh)] = Eigen::Vector3f(p[0], p[1], p[2]);
  }
  void set_normal(VertexHandle vh, const OpenMesh::Vec3f& n) override {
    if (layout_.vertex_normals && ValidVertex(vh))
      normals_[Index(vh)] = Eigen::Vector3f(n[0], n[1], n[2]);
  }
  void set_normal(VertexHandle vh, const OpenMesh::Vec3d& n) override {
    set_normal(vh, OpenMesh::Vec3f(static_cast<float>(n[0]), static_cast<float>(n[1]),
                                   static_cast<float>(n[2])));
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec4uc& c) override {
    if (layout_.vertex_rgb && ValidVertex(vh))
      vertex_rgb_[Index(vh)] = OpenMesh::Vec3uc(c[0], c[1], c[2]);
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec3uc& c) override {
    set_color(vh, OpenMesh::Vec4uc(c[0], c[1], c[2], 255));
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec3f& c) override {
    set_color(vh, ToBytes(c[0], c[1], c[2]));
  }
  void set_color(VertexHandle vh, const OpenMesh::Vec4f& c) override {
    set_color(vh, ToBytes(c[0], c[1], c[2]));
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec4uc& c) override {
    if (layout_.face_rgb && fh.idx() >= 0 && static_cast<size_t>(fh.idx()) < face_rgb_.size()) {
      face_rgb_[static_cast<size_t>(fh.idx())] = OpenMesh::Vec3uc(c[0], c[1], c[2]);
    }
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec3uc& c) override {
    set_color(fh, OpenMesh::Vec4uc(c[0], c[1], c[2], 255));
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec3f& c) override {
    set_color(fh, ToBytes(c[0], c[1], c[2]));
  }
  void set_color(FaceHandle fh, const OpenMesh::Vec4f& c) override {
    set_color(fh, ToBytes(c[0], c[1], c[2]));
  }
  OpenMesh::BaseKernel* kernel() override { return &kernel_; }
  void reserve(unsigned int vertices, unsigned int /*edges*/, unsigned int faces) override {
    // The counts come from a header already checked against the file size.
    positions_.reserve(vertices);
    if (layout_.vertex_normals) normals_.reserve(vertices);
    if (layout_.vertex_rgb) vertex_rgb_.reserve(vertices);
    if (layout_.face_rgb) face_rgb_.reserve(faces);
    triangles_.reserve(faces);
    kernel_.Reserve(vertices, faces);
  }
  size_t n_vertices() const override { return positions_.size(); }
  size_t n_faces() const override { return polygon_count(); }
  size_t n_edges() const override { return 0; }

  // --- not used by the PLY reader (connectivity, texture coordinates, status, edges).
  HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
  FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<OpenMesh::Vec2f>&) override {}
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<OpenMesh::Vec3f>&) override {}
  void set_face_texindex(FaceHandle, int) override {}
  void set_halfedge(VertexHandle, HalfedgeHandle) override {}
  void set_texcoord(VertexHandle, const OpenMesh::Vec2f&) override {}
  void set_texcoord(HalfedgeHandle, const OpenMesh::Vec2f&) override {}
  void set_texcoord(VertexHandle, const OpenMesh::Vec3f&) override {}
  void set_texcoord(HalfedgeHandle, const OpenMesh::Vec3f&) override {}
  void set_status(VertexHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_status(HalfedgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_status(EdgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_status(FaceHandle, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_next(HalfedgeHandle, HalfedgeHandle) override {}
  void set_face(HalfedgeHandle, FaceHandle) override {}
  void request_face_texcoords2D() override {}
  void set_color(EdgeHandle, const OpenMesh::Vec3uc&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec4uc&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec3f&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec4f&) override {}
  void set_normal(FaceHandle, const OpenMesh::Vec3f&) override {}
  void set_normal(FaceHandle, const OpenMesh::Vec3d&) override {}
  void add_texture_information(int, std::string) override {}

 private:
  static OpenMesh::Vec4uc ToBytes(float r, float g, float b) {
    auto byte = [](float v) {
      return static_cast<unsigned char>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
    };
    return OpenMesh::Vec4uc(byte(r), byte(g), byte(b), 255);
  }
  bool ValidVertex(VertexHandle vh) const {
    return vh.idx() >= 0 && static_cast<size_t>(vh.idx()) < positions_.size();
  }
  static size_t Index(VertexHandle vh) { return static_cast<size_t>(vh.idx()); }
  void Note(const std::string& problem) {
    if (problem_.empty()) problem_ = problem;
  }

  size_t file_vertices_;
  PlyLayout layout_;
  std::string problem_;
  std::vector<Eigen::Vector3f> positions_;
  std::vector<Eigen::Vector3f> normals_;
  std::vector<OpenMesh::Vec3uc> vertex_rgb_;
  std::vector<Eigen::Vector3i> triangles_;
  std::vector<size_t>
      first_triangle_;  // polygon f -> triangles [first_triangle_[f], first_triangle_[f+1])
  std::vector<OpenMesh::Vec3uc> face_rgb_;
  PropertyKernel kernel_;
};

unsigned char LinearToSrgbByte(float linear) {
  return static_cast<unsigned char>(
      std::lround(LinearToSrgb(std::clamp(linear, 0.0f, 1.0f)) * 255.0f));
}

// Presents a TriangleMesh to OpenMesh's PLY writer as it is: vertices and triangles in order,
// colours as sRGB bytes (for viewers), and the exact linear vertex and face colours as persistent
// float properties albedo_r/g/b of a property kernel (written by OpenMesh as
// `property float albedo_r` ...).
class TriangleMeshExporter final : public OpenMesh::IO::BaseExporter {
 public:
  explicit TriangleMeshExporter(const TriangleMesh& mesh) : mesh_(mesh) {
    vertex_rgb_.reserve(mesh.vertex_colors.size());
    for (const Eigen::Vector3f& c : mesh.vertex_colors) {
      vertex_rgb_.emplace_back(LinearToSrgbByte(c[0]), LinearToSrgbByte(c[1]),
                               LinearToSrgbByte(c[2]));
    }
    face_rgb_.reserve(mesh.face_colors.size());
    for (const Eigen::Vector3f& c : mesh.face_colors) {
      face_rgb_.emplace_back(LinearToSrgbByte(c[0]), LinearToSrgbByte(c[1]),
                             LinearToSrgbByte(c[2]));
    }
    kernel_.SetVertexCount(mesh.vertices.size());
    kernel_.SetFaceCount(mesh.faces.size());
    if (!mesh.vertex_colors.empty()) {
      for (int c = 0; c < 3; ++c) {
        OpenMesh::VPropHandleT<float> handle;
        kernel_.add_property(handle, kAlbedo[static_cast<size_t>(c)]);
        kernel_.property(handle).set_persistent(true);
        for (size_t v = 0; v < mesh.vertices.size(); ++v) {
          kernel_.property(handle, VertexHandle(static_cast<int>(v))) = mesh.vertex_colors[v][c];
        }
      }
    }
    if (!mesh.face_colors.empty()) {
      for (int c = 0; c < 3; ++c) {
        OpenMesh::FPropHandleT<float> handle;
        kernel_.add_property(handle, kAlbedo[static_cast<size_t>(c)]);
        kernel_.property(handle).set_persistent(true);
        for (size_t f = 0; f < mesh.faces.size(); ++f) {
          kernel_.property(handle, FaceHandle(static_cast<int>(f))) = mesh.face_colors[f][c];
        }
      }
    }
  }

  OpenMesh::Vec3f point(VertexHandle vh) const override { return ToOm(mesh_.vertices[Index(vh)]); }
  OpenMesh::Vec3d pointd(VertexHandle vh) const override { return OpenMesh::Vec3d(point(vh)); }
  bool is_point_double() const override { return false; }
  OpenMesh::Vec3f normal(VertexHandle vh) const override { return ToOm(mesh_.normals[Index(vh)]); }
  OpenMesh::Vec3d normald(VertexHandle vh) const override { return OpenMesh::Vec3d(normal(vh)); }
  bool is_normal_double() const override { return false; }
  OpenMesh::Vec3uc color(VertexHandle vh) const override { return vertex_rgb_[Index(vh)]; }
  OpenMesh::Vec4uc colorA(VertexHandle vh) const override { return WithAlpha(color(vh)); }
  OpenMesh::Vec3ui colori(VertexHandle vh) const override { return ToUi(color(vh)); }
  OpenMesh::Vec4ui colorAi(VertexHandle vh) const override { return ToUiA(color(vh)); }
  OpenMesh::Vec3f colorf(VertexHandle vh) const override { return ToF(color(vh)); }
  OpenMesh::Vec4f colorAf(VertexHandle vh) const override { return ToFA(color(vh)); }
  OpenMesh::Vec2f texcoord(VertexHandle) const override { return OpenMesh::Vec2f(0.0f, 0.0f); }
  OpenMesh::Vec2f texcoord(HalfedgeHandle) const override { return OpenMesh::Vec2f(0.0f, 0.0f); }
  OpenMesh::Attributes::StatusInfo status(VertexHandle) const override { return {}; }

  unsigned int get_vhandles(FaceHandle fh, std::vector<VertexHandle>& handles) const override {
    const Eigen::Vector3i& f = mesh_.faces[static_cast<size_t>(fh.idx())];
    handles = {VertexHandle(f[0]), VertexHandle(f[1]), VertexHandle(f[2])};
    return 3;
  }
  HalfedgeHandle getHeh(FaceHandle, VertexHandle) const override { return HalfedgeHandle(); }
  unsigned int get_face_texcoords(std::vector<OpenMesh::Vec2f>& texcoords) const override {
    texcoords.clear();
    return 0;
  }
  OpenMesh::Vec3f normal(FaceHandle fh) const override {
    return ToOm(mesh_.FaceNormalScaled(static_cast<size_t>(fh.idx())).normalized());
  }
  OpenMesh::Vec3d normald(FaceHandle fh) const override { return OpenMesh::Vec3d(normal(fh)); }
  OpenMesh::Vec3uc color(FaceHandle fh) const override {
    return face_rgb_[static_cast<size_t>(fh.idx())];
  }
  OpenMesh::Vec4uc colorA(FaceHandle fh) const override { return WithAlpha(color(fh)); }
  OpenMesh::Vec3ui colori(FaceHandle fh) const override { return ToUi(color(fh)); }
  OpenMesh::Vec4ui colorAi(FaceHandle fh) const override { return ToUiA(color(fh)); }
  OpenMesh::Vec3f colorf(FaceHandle fh) const override { return ToF(color(fh)); }
  OpenMesh::Vec4f colorAf(FaceHandle fh) const override { return ToFA(color(fh)); }
  OpenMesh::Attributes::StatusInfo status(FaceHandle) const override { return {}; }

  OpenMesh::Vec3uc color(EdgeHandle) const override { return OpenMesh::Vec3uc(0, 0, 0); }
  OpenMesh::Vec4uc colorA(EdgeHandle) const override { return OpenMesh::Vec4uc(0, 0, 0, 255); }
  OpenMesh::Vec3ui colori(EdgeHandle) const override { return OpenMesh::Vec3ui(0, 0, 0); }
  OpenMesh::Vec4ui colorAi(EdgeHandle) const override { return OpenMesh::Vec4ui(0, 0, 0, 255); }
  OpenMesh::Vec3f colorf(EdgeHandle) const override { return OpenMesh::Vec3f(0.0f, 0.0f, 0.0f); }
  OpenMesh::Vec4f colorAf(EdgeHandle) const override {
    return OpenMesh::Vec4f(0.0f, 0.0f, 0.0f, 1.0f);
  }
  OpenMesh::Attributes::StatusInfo status(EdgeHandle) const override { return {}; }

  int get_halfedge_id(VertexHandle) override { return -1; }
  int get_halfedge_id(FaceHandle) override { return -1; }
  int get_next_halfedge_id(HalfedgeHandle) override { return -1; }
  int get_to_vertex_id(HalfedgeHandle) override { return -1; }
  int get_face_id(HalfedgeHandle) override { return -1; }
  OpenMesh::Attributes::StatusInfo status(HalfedgeHandle) const override { return {}; }

  const OpenMesh::BaseKernel* kernel() override { return &kernel_; }
  size_t n_vertices() const override { return mesh_.vertices.size(); }
  size_t n_faces() const override { return mesh_.faces.size(); }
  size_t n_edges() const override { return 0; }
  bool is_triangle_mesh() const override { return true; }
  bool has_vertex_normals() const override { return !mesh_.normals.empty(); }
  bool has_vertex_colors() const override { return !mesh_.vertex_colors.empty(); }
  bool has_face_colors() const override { return !mesh_.face_colors.empty(); }

 private:
  static size_t Index(VertexHandle vh) { return static_cast<size_t>(vh.idx()); }
  static OpenMesh::Vec3f ToOm(const Eigen::Vector3f& v) {
    return OpenMesh::Vec3f(v[0], v[1], v[2]);
  }
  static OpenMesh::Vec4uc WithAlpha(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec4uc(c[0], c[1], c[2], 255);
  }
  static OpenMesh::Vec3ui ToUi(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec3ui(c[0], c[1], c[2]);
  }
  static OpenMesh::Vec4ui ToUiA(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec4ui(c[0], c[1], c[2], 255);
  }
  static OpenMesh::Vec3f ToF(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec3f(c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f);
  }
  static OpenMesh::Vec4f ToFA(const OpenMesh::Vec3uc& c) {
    return OpenMesh::Vec4f(c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f, 1.0f);
  }

  const TriangleMesh& mesh_;
  std::vector<OpenMesh::Vec3uc> vertex_rgb_;
  std::vector<OpenMesh::Vec3uc> face_rgb_;
  PropertyKernel kernel_;
};

// Vertex and face colours are stored exactly as float albedo_r/g/b (their 8-bit red/green/blue
// copy, for viewers, is clamped to [0, 1]); they only have to be finite.
void CheckColorsWritable(const TriangleMesh& mesh, const std::string& name) {
  for (size_t i = 0; i < mesh.vertex_colors.size(); ++i) {
    if (!mesh.vertex_colors[i].allFinite()) {
      throw Error(Format(name, ": vertex colour ", i, " is not finite"));
    }
  }
  for (size_t f = 0; f < mesh.face_colors.size(); ++f) {
    if (!mesh.face_colors[f].allFinite())
      throw Error(Format(name, ": face colour ", f, " is not finite"));
  }
}

}  // namespace

TriangleMesh ReadPly(const fs::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(Format(name, ": file not found"));
  if (fs::is_directory(path, ec)) throw Error(Format(name, ": is a folder, not a PLY file"));
  const uint64_t file_size = fs::file_size(path, ec);
  if (ec) throw Error(Format(name, ": cannot read the file size (", ec.message(), ")"));
  if (file_size == 0) throw Error(Format(name, ": empty file, not a PLY mesh"));

  const ply::PlyHeader header = ply::ParseHeader(path, file_size);
  const PlyLayout layout = ply::CheckHeader(header, name);
  ply::CheckCountsFitInFile(header, file_size, name);
  ply::WalkData(path, header, layout, file_size);

  const size_t file_vertices = header.elements[static_cast<size_t>(layout.vertex)].count;
  const size_t file_faces =
      layout.face >= 0 ? header.elements[static_cast<size_t>(layout.face)].count : 0;
  CollectingImporter importer(file_vertices, file_faces, layout);
  // ASCII: a final newline so that a file without one still parses (OpenMesh treats end of file
  // before the last element as an error).
  ply::SplicedFileBuf buffer(ply::CanonicalHeader(header), path, header.data_offset, file_size,
                             header.format == ply::PlyFormat::kAscii ? "\n" : "");
  std::istream stream(&buffer);
  OpenMesh::IO::Options options = OpenMesh::IO::Options::VertexNormal |
                                  OpenMesh::IO::Options::VertexColor |
                                  OpenMesh::IO::Options::FaceColor | OpenMesh::IO::Options::Custom;
  bool ok = false;
  {
    std::lock_guard<std::mutex> lock(OpenMeshMutex());
    QuietOpenMesh quiet;
    ok = OpenMesh::IO::IOManager().read(stream, "ply", importer, options);
  }
  if (!ok) throw Error(Format(name, ": OpenMesh could not read the PLY data (corrupt file?)"));
  if (stream.fail()) {
    throw Error(Format(
        name, ": malformed PLY data (a value that is not a number, or a file that ends early)"));
  }
  if (!importer.problem().empty()) throw Error(Format(name, ": ", importer.problem()));
  if (importer.n_vertices() != file_vertices) {
    throw Error(Format(name, ": read ", importer.n_vertices(), " vertices but the header declares ",
                       file_vertices));
  }
  if (importer.polygon_count() != file_faces) {
    throw Error(Format(name, ": read ", importer.polygon_count(), " faces but the header declares ",
                       file_faces));
  }
  TriangleMesh mesh = importer.Build(name);
  mesh.Validate(name);
  return mesh;
}

void WritePly(const fs::path& path, const TriangleMesh& mesh, const PlyWriteOptions& options) {
  const std::string name = path.string();
  mesh.Validate(name);
  CheckColorsWritable(mesh, name);
  TriangleMeshExporter exporter(mesh);
  OpenMesh::IO::Options om_options = OpenMesh::IO::Options::Default;
  if (options.binary) om_options += OpenMesh::IO::Options::Binary;
  if (!mesh.normals.empty()) om_options += OpenMesh::IO::Options::VertexNormal;
  if (!mesh.vertex_colors.empty()) om_options += OpenMesh::IO::Options::VertexColor;
  if (!mesh.face_colors.empty()) om_options += OpenMesh::IO::Options::FaceColor;

  WriteFileAtomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out)
      throw Error(Format(name, ": cannot write ", tmp.string(), " (", std::strerror(errno), ")"));
    bool ok = false;
    {
      std::lock_guard<std::mutex> lock(OpenMeshMutex());
      QuietOpenMesh quiet;
      // Precision 9 = std::numeric_limits<float>::max_digits10: ASCII floats read back exactly.
      ok = OpenMesh::IO::IOManager().write(out, "ply", exporter, om_options, 9);
    }
    if (!ok) throw Error(Format(name, ": OpenMesh's PLY writer failed"));
    out.close();
    if (!out) throw Error(Format(name, ": write failed (disk full?)"));
  });
}

}  // namespace genscene
