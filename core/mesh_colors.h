// Mesh Colors (Yuksel, Keyser, House, "Mesh Colors", 2010): colour samples that live on the mesh
// itself instead of in a 2D atlas, so there are no seams and no parameterisation.
//
// Face f of resolution R holds samples at the barycentric lattice points (b1, b2) = (i/R, j/R),
// i, j >= 0, i + j <= R (b0 = 1 - b1 - b2 belongs to the face's first vertex). A sample on a vertex
// or an edge is shared with every face around it and stored once:
//   - one sample per vertex;
//   - R_e - 1 samples per edge, where the edge's resolution R_e is the largest resolution of the
//     faces sharing it; a coarser face reads every (R_e / R)-th of them;
//   - (R - 1)(R - 2) / 2 samples inside each face.
// Resolutions are powers of two (1, 2, 4, ...) so that coarser faces land exactly on the samples
// of finer edges. Storage order: vertex samples (by vertex index), then edge samples (edges in
// order of first appearance in the face list, samples from the edge's lower-index vertex to the
// higher), then face-interior samples (faces in order, rows j = 1..R-2, i = 1..R-1-j).
//
// Lookups: Nearest returns the lattice sample nearest the point within the containing
// sub-triangle; Linear interpolates the three samples of that sub-triangle barycentrically, so
// a field that is linear over each face is reproduced exactly.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/mesh.h"

namespace genscene {

class MeshColors {
 public:
  static constexpr int kMaxResolution = 256;

  // What a sample is: a mesh vertex, a point on an edge, or a point inside a face.
  enum class SampleKind : uint8_t { kVertex, kEdge, kFace };
  struct SampleSite {
    SampleKind kind;
    int element;  // vertex, edge or face index
    int a, b;     // kEdge: lattice step a of R_e along the edge; kFace: lattice point (i, j)
  };

  MeshColors() = default;
  // The layout for `mesh` with one resolution per face (each a power of two in
  // [1, kMaxResolution]); every sample starts at (0, 0, 0). Throws Error when a resolution is not
  // a power of two in range, the counts disagree, or a face index is out of range.
  MeshColors(const TriangleMesh& mesh, const std::vector<int>& face_resolution);

  int num_vertices() const { return num_vertices_; }
  int num_faces() const { return static_cast<int>(faces_.size()); }
  int num_edges() const { return static_cast<int>(edges_.size()); }
  int FaceResolution(int face) const { return face_resolution_[face]; }
  int EdgeResolution(int edge) const { return edge_resolution_[edge]; }
  const std::vector<int>& face_resolutions() const { return face_resolution_; }
  // The two vertices of edge e (lower index first) and the edge of face side k (vertex k to k+1).
  const Eigen::Vector2i& Edge(int edge) const { return edges_[edge]; }
  // True for a vertex no face uses (its sample has no neighbours and no face point).
  bool IsolatedVertex(int vertex) const { return vertex_face_[vertex] < 0; }
  int FaceEdge(int face, int side) const { return face_edges_[3 * face + side]; }

  size_t SampleCount() const { return colors_.size(); }
  size_t VertexSampleCount() const { return static_cast<size_t>(num_vertices_); }
  size_t EdgeSampleCount() const {
    return face_offset_.empty() ? 0 : face_offset_.front() - num_vertices_;
  }
  size_t FaceSampleCount() const { return SampleCount() - VertexSampleCount() - EdgeSampleCount(); }

  // Global index of the sample at lattice point (i, j) of `face` (0 <= i, j; i + j <= R).
  uint32_t SampleIndex(int face, int i, int j) const;
  // What and where sample s is.
  SampleSite Site(size_t sample) const;
  // A face containing sample s and its lattice point there (for positions and normals): for an
  // edge sample, the finest face on the edge, so (b1, b2) * R is an integer lattice point.
  void SampleFacePoint(size_t sample, int* face, double* b1, double* b2) const;

  std::vector<Eigen::Vector3f>& colors() { return colors_; }
  const std::vector<Eigen::Vector3f>& colors() const { return colors_; }
  // Optional per-sample labels (e.g. albedo cluster ids); empty or one per sample.
  std::vector<int32_t>& labels() { return labels_; }
  const std::vector<int32_t>& labels() const { return labels_; }

  // Colour at barycentric point (b1, b2) of `face`; the point is clamped into the triangle.
  Eigen::Vector3f Nearest(int face, float b1, float b2) const;
  Eigen::Vector3f Linear(int face, float b1, float b2) const;

  // Sets every sample from a per-vertex quantity interpolated linearly along edges and over faces
  // (positions, normals, colours). Shared samples are computed once, from their own element, so
  // neighbouring faces agree bit for bit.
  std::vector<Eigen::Vector3f> InterpolateVertexAttribute(
      const std::vector<Eigen::Vector3f>& per_vertex) const;

  // Pairs of samples that are neighbours on the lattice of some face (each pair once, lower
  // index first): the sample graph for smoothing, hole filling and connected components.
  std::vector<std::pair<uint32_t, uint32_t>> SampleNeighbours() const;

  // The mesh subdivided along every face's lattice (R^2 small triangles per face), one vertex per
  // sample with the sample's colour as vertex colour: for MeshLab, Open3D and Blender.
  TriangleMesh ToSubdividedMesh(const TriangleMesh& mesh) const;

  // 64-bit FNV-1a hash of the vertex count and face indices this layout was built for: a .mcol
  // file refuses to load onto another mesh.
  uint64_t mesh_fingerprint() const { return fingerprint_; }

 private:
  void Locate(int face, float b1, float b2, uint32_t idx[3], float w[3]) const;

  int num_vertices_ = 0;
  std::vector<Eigen::Vector3i> faces_;
  std::vector<int> face_resolution_;
  std::vector<Eigen::Vector2i> edges_;
  std::vector<int> edge_resolution_;
  std::vector<int> face_edges_;      // 3 per face
  std::vector<size_t> edge_offset_;  // first sample of each edge
  std::vector<size_t> face_offset_;  // first interior sample of each face
  std::vector<int> edge_face_;       // the finest face containing each edge
  std::vector<int> vertex_face_;     // one face containing each vertex (-1: isolated)
  std::vector<Eigen::Vector3f> colors_;
  std::vector<int32_t> labels_;
  uint64_t fingerprint_ = 0;
};

// Barycentrics (b1, b2) moved into the triangle: NaN and negatives to 0, each at most 1, a sum
// above 1 scaled back onto the long edge (along the ray from the first vertex). Every lookup by
// barycentrics (Mesh Colors, per-vertex albedo) does this first: a ray hit on an edge, or a few
// ulps past it, reads the face's own values.
void ClampToFace(float* b1, float* b2);

// The sub-triangle of a resolution-R lattice that holds barycentric point (b1, b2), its three
// lattice points (i[k], j[k]) and barycentric weights w (each in [0, 1], summing to 1 up to
// rounding). Any input is accepted (ClampToFace first), so the lattice points always satisfy
// 0 <= i, j and i + j <= R. viewer/shaders.h repeats it in GLSL.
struct LatticeCell {
  int i[3], j[3];
  float w[3];
};
LatticeCell LocateInLattice(int r, float b1, float b2);

// Sample counts for a face of resolution R: (R+1)(R+2)/2 in all, of which 3 at vertices,
// 3(R-1) on edges and (R-1)(R-2)/2 inside.
constexpr size_t MeshColorsInteriorCount(int r) {
  return r < 2 ? 0 : size_t(r - 1) * size_t(r - 2) / 2;
}

uint64_t MeshFingerprint(const TriangleMesh& mesh);

// The smallest power of two R with longest_edge / R <= spacing, at most max_resolution.
int ResolutionForSpacing(double longest_edge, double spacing, int max_resolution);

// Per-face resolution for a target sample spacing in meters: ResolutionForSpacing of each face's
// longest edge.
std::vector<int> ChooseFaceResolutions(const TriangleMesh& mesh, double spacing,
                                       int max_resolution);

// .mcol: "GSMCOL01", u32 vertex count, u32 face count, u64 mesh fingerprint, one u8 log2(R) per
// face, u64 sample count, u8 has-labels, float32 RGB per sample, then int32 per sample when
// labelled. Little-endian. Written atomically.
void WriteMeshColors(const std::filesystem::path& path, const MeshColors& colors);
// Reads a .mcol for `mesh`. Throws Error naming the file when it is not a .mcol, is truncated,
// holds non-finite colours, or was made for another mesh (vertex/face counts or fingerprint).
MeshColors ReadMeshColors(const std::filesystem::path& path, const TriangleMesh& mesh);

}  // namespace genscene
