#include "core/mesh_colors.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <unordered_map>

#include "core/binary_io.h"
#include "core/check.h"
#include "core/file_util.h"

namespace genscene {

namespace {

bool IsPowerOfTwo(int r) {
  return r > 0 && (r & (r - 1)) == 0;
}

int Log2(int r) {
  int l = 0;
  while ((1 << l) < r) ++l;
  return l;
}

}  // namespace

uint64_t MeshFingerprint(const TriangleMesh& mesh) {
  uint64_t h = kFnv1aOffset;
  auto mix = [&h](uint32_t value) {
    const unsigned char bytes[4] = {
        static_cast<unsigned char>(value), static_cast<unsigned char>(value >> 8),
        static_cast<unsigned char>(value >> 16), static_cast<unsigned char>(value >> 24)};
    h = Fnv1a64(bytes, 4, h);
  };
  mix(static_cast<uint32_t>(mesh.vertices.size()));
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) mix(static_cast<uint32_t>(f[k]));
  }
  return h;
}

MeshColors::MeshColors(const TriangleMesh& mesh, const std::vector<int>& face_resolution)
    : num_vertices_(static_cast<int>(mesh.vertices.size())),
      faces_(mesh.faces),
      face_resolution_(face_resolution),
      fingerprint_(MeshFingerprint(mesh)) {
  if (face_resolution.size() != mesh.faces.size()) {
    throw Error(Format("Mesh Colors: ", face_resolution.size(), " face resolutions for a mesh of ",
                       mesh.faces.size(), " faces"));
  }
  const int nf = num_faces();
  face_edges_.resize(3 * static_cast<size_t>(nf));
  vertex_face_.assign(num_vertices_, -1);
  std::unordered_map<uint64_t, int> edge_of;
  edge_of.reserve(3 * static_cast<size_t>(nf) / 2 + 1);
  for (int f = 0; f < nf; ++f) {
    const int r = face_resolution_[f];
    if (!IsPowerOfTwo(r) || r > kMaxResolution) {
      throw Error(Format("Mesh Colors: face ", f, " has resolution ", r,
                         " (must be a power of two in [1, ", kMaxResolution, "])"));
    }
    const Eigen::Vector3i& v = faces_[f];
    for (int k = 0; k < 3; ++k) {
      if (v[k] < 0 || v[k] >= num_vertices_) {
        throw Error(Format("Mesh Colors: face ", f, " names vertex ", v[k], " of a mesh with ",
                           num_vertices_, " vertices"));
      }
      if (vertex_face_[v[k]] < 0) vertex_face_[v[k]] = f;
    }
    for (int k = 0; k < 3; ++k) {
      const int a = std::min(v[k], v[(k + 1) % 3]);
      const int b = std::max(v[k], v[(k + 1) % 3]);
      const uint64_t key = (static_cast<uint64_t>(a) << 32) | static_cast<uint32_t>(b);
      auto [it, inserted] = edge_of.emplace(key, static_cast<int>(edges_.size()));
      if (inserted) {
        edges_.emplace_back(a, b);
        edge_resolution_.push_back(r);
        edge_face_.push_back(f);
      } else if (r > edge_resolution_[it->second]) {  // the finest face defines the edge
        edge_resolution_[it->second] = r;
        edge_face_[it->second] = f;
      }
      face_edges_[3 * f + k] = it->second;
    }
  }
  size_t offset = static_cast<size_t>(num_vertices_);
  edge_offset_.resize(edges_.size());
  for (size_t e = 0; e < edges_.size(); ++e) {
    edge_offset_[e] = offset;
    offset += static_cast<size_t>(edge_resolution_[e] - 1);
  }
  face_offset_.resize(faces_.size());
  for (size_t f = 0; f < faces_.size(); ++f) {
    face_offset_[f] = offset;
    offset += MeshColorsInteriorCount(face_resolution_[f]);
  }
  if (offset > 0xffffffffull) {
    throw Error(Format("Mesh Colors: ", offset,
                       " samples exceed the 32-bit sample index; use a coarser texel spacing"));
  }
  colors_.assign(offset, Eigen::Vector3f::Zero());
}

uint32_t MeshColors::SampleIndex(int face, int i, int j) const {
  const int r = face_resolution_[face];
  GS_CHECK(i >= 0 && j >= 0 && i + j <= r);
  const Eigen::Vector3i& v = faces_[face];
  if (i == 0 && j == 0) return static_cast<uint32_t>(v[0]);
  if (i == r) return static_cast<uint32_t>(v[1]);
  if (j == r) return static_cast<uint32_t>(v[2]);
  int side = -1, n = 0;
  if (j == 0) {
    side = 0, n = i;  // v0 -> v1
  } else if (i + j == r) {
    side = 1, n = j;  // v1 -> v2
  } else if (i == 0) {
    side = 2, n = r - j;  // v2 -> v0
  }
  if (side >= 0) {
    const int e = face_edges_[3 * face + side];
    const int re = edge_resolution_[e];
    int m = n * (re / r);
    if (edges_[e][0] != v[side]) m = re - m;
    return static_cast<uint32_t>(edge_offset_[e] + static_cast<size_t>(m - 1));
  }
  const size_t row = static_cast<size_t>(j - 1) * static_cast<size_t>(r - 1) -
                     static_cast<size_t>(j - 1) * static_cast<size_t>(j) / 2;
  return static_cast<uint32_t>(face_offset_[face] + row + static_cast<size_t>(i - 1));
}

MeshColors::SampleSite MeshColors::Site(size_t sample) const {
  GS_CHECK_LT(sample, colors_.size());
  if (sample < static_cast<size_t>(num_vertices_)) {
    return {SampleKind::kVertex, static_cast<int>(sample), 0, 0};
  }
  const size_t first_face_sample = face_offset_.empty() ? colors_.size() : face_offset_.front();
  if (sample < first_face_sample) {
    const auto it = std::upper_bound(edge_offset_.begin(), edge_offset_.end(), sample);
    const int e = static_cast<int>(std::distance(edge_offset_.begin(), it)) - 1;
    return {SampleKind::kEdge, e, static_cast<int>(sample - edge_offset_[e]) + 1, 0};
  }
  const auto it = std::upper_bound(face_offset_.begin(), face_offset_.end(), sample);
  const int f = static_cast<int>(std::distance(face_offset_.begin(), it)) - 1;
  const int r = face_resolution_[f];
  size_t local = sample - face_offset_[f];
  for (int j = 1; j <= r - 2; ++j) {
    const size_t row = static_cast<size_t>(r - 1 - j);
    if (local < row) return {SampleKind::kFace, f, static_cast<int>(local) + 1, j};
    local -= row;
  }
  GS_CHECK(false);
  return {};
}

void MeshColors::SampleFacePoint(size_t sample, int* face, double* b1, double* b2) const {
  const SampleSite site = Site(sample);
  switch (site.kind) {
    case SampleKind::kVertex: {
      const int f = vertex_face_[site.element];
      GS_CHECK_GE(f, 0);  // isolated vertices have no face
      const Eigen::Vector3i& v = faces_[f];
      *face = f;
      *b1 = v[1] == site.element ? 1.0 : 0.0;
      *b2 = v[2] == site.element && v[1] != site.element ? 1.0 : 0.0;
      return;
    }
    case SampleKind::kEdge: {
      const int e = site.element;
      const int f = edge_face_[e];
      const Eigen::Vector3i& v = faces_[f];
      int side = 0;
      while (face_edges_[3 * f + side] != e) ++side;
      double t = static_cast<double>(site.a) / edge_resolution_[e];  // from edges_[e][0]
      if (v[side] != edges_[e][0]) t = 1.0 - t;                      // from v[side]
      *face = f;
      if (side == 0) *b1 = t, *b2 = 0.0;
      if (side == 1) *b1 = 1.0 - t, *b2 = t;
      if (side == 2) *b1 = 0.0, *b2 = 1.0 - t;
      return;
    }
    case SampleKind::kFace: {
      const double r = face_resolution_[site.element];
      *face = site.element;
      *b1 = site.a / r;
      *b2 = site.b / r;
      return;
    }
  }
}

void ClampToFace(float* b1, float* b2) {
  float x = *b1 > 0.0f ? std::min(*b1, 1.0f) : 0.0f;
  float y = *b2 > 0.0f ? std::min(*b2, 1.0f) : 0.0f;
  if (x + y > 1.0f) {
    const float s = x + y;
    x /= s;
    y /= s;
  }
  *b1 = x;
  *b2 = y;
}

LatticeCell LocateInLattice(int r, float b1, float b2) {
  ClampToFace(&b1, &b2);
  const float x = b1 * static_cast<float>(r);
  const float y = b2 * static_cast<float>(r);
  int i = std::min(static_cast<int>(x), r);  // x, y >= 0: truncation is floor
  int j = std::min(static_cast<int>(y), r);
  // On the face's hypotenuse (or past it by rounding): use the sub-triangle below it.
  while (i + j > r - 1) {
    if (i >= j && i > 0) {
      --i;
    } else {
      --j;
    }
  }
  float fx = x - static_cast<float>(i);
  float fy = y - static_cast<float>(j);
  LatticeCell cell;
  // The upside-down sub-triangle exists only below the lattice's last diagonal; on that diagonal a
  // point past it (by rounding, or by the rescaling above) is projected back onto it.
  if (fx + fy > 1.0f && i + j < r - 1) {
    cell = {{i + 1, i, i + 1},
            {j + 1, j + 1, j},
            {fx + fy - 1.0f, std::max(0.0f, 1.0f - fx), std::max(0.0f, 1.0f - fy)}};
  } else {
    if (fx + fy > 1.0f) {
      const float s = fx + fy;
      fx /= s;
      fy /= s;
    }
    cell = {{i, i + 1, i}, {j, j, j + 1}, {std::max(0.0f, 1.0f - fx - fy), fx, fy}};
  }
  return cell;
}

void MeshColors::Locate(int face, float b1, float b2, uint32_t idx[3], float w[3]) const {
  const LatticeCell cell = LocateInLattice(face_resolution_[face], b1, b2);
  for (int k = 0; k < 3; ++k) {
    idx[k] = SampleIndex(face, cell.i[k], cell.j[k]);
    w[k] = cell.w[k];
  }
}

Eigen::Vector3f MeshColors::Nearest(int face, float b1, float b2) const {
  uint32_t idx[3];
  float w[3];
  Locate(face, b1, b2, idx, w);
  int best = 0;
  for (int k = 1; k < 3; ++k) {
    if (w[k] > w[best]) best = k;
  }
  return colors_[idx[best]];
}

Eigen::Vector3f MeshColors::Linear(int face, float b1, float b2) const {
  uint32_t idx[3];
  float w[3];
  Locate(face, b1, b2, idx, w);
  return w[0] * colors_[idx[0]] + w[1] * colors_[idx[1]] + w[2] * colors_[idx[2]];
}

std::vector<Eigen::Vector3f> MeshColors::InterpolateVertexAttribute(
    const std::vector<Eigen::Vector3f>& per_vertex) const {
  GS_CHECK_EQ(per_vertex.size(), static_cast<size_t>(num_vertices_));
  std::vector<Eigen::Vector3f> out(colors_.size());
  std::copy(per_vertex.begin(), per_vertex.end(), out.begin());
  for (size_t e = 0; e < edges_.size(); ++e) {
    const Eigen::Vector3d a = per_vertex[edges_[e][0]].cast<double>();
    const Eigen::Vector3d b = per_vertex[edges_[e][1]].cast<double>();
    const int re = edge_resolution_[e];
    for (int m = 1; m < re; ++m) {
      const double t = static_cast<double>(m) / re;
      out[edge_offset_[e] + m - 1] = ((1.0 - t) * a + t * b).cast<float>();
    }
  }
  for (size_t f = 0; f < faces_.size(); ++f) {
    const int r = face_resolution_[f];
    if (r < 3) continue;
    const Eigen::Vector3d p0 = per_vertex[faces_[f][0]].cast<double>();
    const Eigen::Vector3d p1 = per_vertex[faces_[f][1]].cast<double>();
    const Eigen::Vector3d p2 = per_vertex[faces_[f][2]].cast<double>();
    size_t s = face_offset_[f];
    for (int j = 1; j <= r - 2; ++j) {
      for (int i = 1; i + j <= r - 1; ++i) {
        const double b1 = static_cast<double>(i) / r, b2 = static_cast<double>(j) / r;
        out[s++] = ((1.0 - b1 - b2) * p0 + b1 * p1 + b2 * p2).cast<float>();
      }
    }
  }
  return out;
}

std::vector<std::pair<uint32_t, uint32_t>> MeshColors::SampleNeighbours() const {
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  auto add = [&pairs](uint32_t a, uint32_t b) {
    if (a != b) pairs.emplace_back(std::min(a, b), std::max(a, b));
  };
  for (int f = 0; f < num_faces(); ++f) {
    const int r = face_resolution_[f];
    for (int j = 0; j < r; ++j) {
      for (int i = 0; i + j < r; ++i) {
        const uint32_t s00 = SampleIndex(f, i, j);
        const uint32_t s10 = SampleIndex(f, i + 1, j);
        const uint32_t s01 = SampleIndex(f, i, j + 1);
        add(s00, s10);
        add(s00, s01);
        add(s10, s01);
      }
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

TriangleMesh MeshColors::ToSubdividedMesh(const TriangleMesh& mesh) const {
  if (MeshFingerprint(mesh) != fingerprint_) {
    throw Error(
        "Mesh Colors: ToSubdividedMesh called with a mesh other than the one of the layout");
  }
  TriangleMesh out;
  out.vertices = InterpolateVertexAttribute(mesh.vertices);
  out.vertex_colors = colors_;
  if (mesh.normals.size() == mesh.vertices.size()) {
    out.normals = InterpolateVertexAttribute(mesh.normals);
    for (Eigen::Vector3f& n : out.normals) {
      const float length = n.norm();
      n = length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::UnitZ();
    }
  }
  for (int f = 0; f < num_faces(); ++f) {
    const int r = face_resolution_[f];
    for (int j = 0; j < r; ++j) {
      for (int i = 0; i + j < r; ++i) {
        const int s00 = static_cast<int>(SampleIndex(f, i, j));
        const int s10 = static_cast<int>(SampleIndex(f, i + 1, j));
        const int s01 = static_cast<int>(SampleIndex(f, i, j + 1));
        out.faces.emplace_back(s00, s10, s01);
        if (i + j + 2 <= r) {
          out.faces.emplace_back(s10, static_cast<int>(SampleIndex(f, i + 1, j + 1)), s01);
        }
      }
    }
  }
  return out;
}

int ResolutionForSpacing(double longest_edge, double spacing, int max_resolution) {
  int r = 1;
  while (longest_edge / r > spacing && r < max_resolution) r *= 2;
  return r;
}

std::vector<int> ChooseFaceResolutions(const TriangleMesh& mesh, double spacing,
                                       int max_resolution) {
  if (!(spacing > 0.0) || !std::isfinite(spacing)) {
    throw Error(Format("texel spacing = ", spacing, " m must be positive"));
  }
  if (!IsPowerOfTwo(max_resolution) || max_resolution > MeshColors::kMaxResolution) {
    throw Error(Format("max face resolution = ", max_resolution, " must be a power of two in [1, ",
                       MeshColors::kMaxResolution, "]"));
  }
  std::vector<int> out(mesh.faces.size(), 1);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const Eigen::Vector3i& v = mesh.faces[f];
    double longest = 0.0;
    for (int k = 0; k < 3; ++k) {
      longest = std::max(
          longest, (mesh.vertices[v[k]] - mesh.vertices[v[(k + 1) % 3]]).cast<double>().norm());
    }
    out[f] = ResolutionForSpacing(longest, spacing, max_resolution);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// File I/O

namespace {
constexpr char kMagic[8] = {'G', 'S', 'M', 'C', 'O', 'L', '0', '1'};
}  // namespace

void WriteMeshColors(const std::filesystem::path& path, const MeshColors& colors) {
  std::string out;
  out.reserve(64 + colors.num_faces() +
              colors.SampleCount() * (12 + (colors.labels().empty() ? 0 : 4)));
  out.append(kMagic, sizeof(kMagic));
  PutBinary(out, static_cast<uint32_t>(colors.num_vertices()));
  PutBinary(out, static_cast<uint32_t>(colors.num_faces()));
  PutBinary(out, colors.mesh_fingerprint());
  for (int r : colors.face_resolutions()) PutBinary(out, static_cast<uint8_t>(Log2(r)));
  PutBinary(out, static_cast<uint64_t>(colors.SampleCount()));
  const bool labelled = !colors.labels().empty();
  GS_CHECK(!labelled || colors.labels().size() == colors.SampleCount());
  PutBinary(out, static_cast<uint8_t>(labelled ? 1 : 0));
  for (const Eigen::Vector3f& c : colors.colors()) {
    for (int k = 0; k < 3; ++k) PutBinary(out, c[k]);
  }
  for (int32_t label : colors.labels()) PutBinary(out, label);
  WriteFileAtomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream file(tmp, std::ios::binary);
    file.write(out.data(), static_cast<std::streamsize>(out.size()));
    file.close();
    if (!file) throw Error(Format(path.string(), ": cannot write Mesh Colors"));
  });
}

MeshColors ReadMeshColors(const std::filesystem::path& path, const TriangleMesh& mesh) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw Error(Format(path.string(), ": cannot open Mesh Colors file"));
  const std::string data((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const std::string where = path.string();
  if (data.size() < sizeof(kMagic) || std::memcmp(data.data(), kMagic, sizeof(kMagic)) != 0) {
    throw Error(Format(where, ": not a Mesh Colors file (expected magic GSMCOL01)"));
  }
  BinaryReader reader(data, path, "Mesh Colors");
  for (size_t k = 0; k < sizeof(kMagic); ++k) reader.Get<char>("magic");
  const auto nv = reader.Get<uint32_t>("vertex count");
  const auto nf = reader.Get<uint32_t>("face count");
  const auto fingerprint = reader.Get<uint64_t>("mesh fingerprint");
  if (nv != mesh.vertices.size() || nf != mesh.faces.size()) {
    throw Error(Format(where, ": made for a mesh of ", nv, " vertices and ", nf,
                       " faces, but the mesh has ", mesh.vertices.size(), " and ",
                       mesh.faces.size()));
  }
  if (fingerprint != MeshFingerprint(mesh)) {
    throw Error(Format(where, ": made for another mesh (same counts, different faces)"));
  }
  std::vector<int> resolution(nf);
  for (uint32_t f = 0; f < nf; ++f) {
    const auto l = reader.Get<uint8_t>("face resolution");
    if ((1 << std::min<int>(l, 30)) > MeshColors::kMaxResolution) {
      throw Error(Format(where, ": face ", f, " has resolution 2^", int(l), " (at most ",
                         MeshColors::kMaxResolution, ")"));
    }
    resolution[f] = 1 << l;
  }
  MeshColors colors(mesh, resolution);
  const auto count = reader.Get<uint64_t>("sample count");
  if (count != colors.SampleCount()) {
    throw Error(Format(where, ": declares ", count, " samples but its resolutions give ",
                       colors.SampleCount()));
  }
  const auto labelled = reader.Get<uint8_t>("label flag");
  const size_t need = count * 12 + (labelled ? count * 4 : 0);
  if (reader.remaining() != need) {
    throw Error(Format(where, ": holds ", reader.remaining(), " bytes of samples, expected ", need,
                       " (truncated or corrupt)"));
  }
  for (Eigen::Vector3f& c : colors.colors()) {
    for (int k = 0; k < 3; ++k) c[k] = reader.Get<float>("colour");
    if (!c.allFinite()) throw Error(Format(where, ": holds a non-finite colour"));
  }
  if (labelled) {
    colors.labels().resize(count);
    for (int32_t& label : colors.labels()) label = reader.Get<int32_t>("label");
  }
  return colors;
}

}  // namespace genscene
