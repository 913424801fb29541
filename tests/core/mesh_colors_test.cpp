#include "core/mesh_colors.h"

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <set>

#include "tests/test_util.h"

namespace genscene {
namespace {

using test::TempDir;

TriangleMesh OneTriangle() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}};
  return m;
}

// Two triangles sharing the edge 1-2, the second one listing it the other way round.
TriangleMesh TwoTriangles() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0.5f}};
  m.faces = {{0, 1, 2}, {2, 1, 3}};
  return m;
}

TriangleMesh Icosphere(int level) {
  const UnitIcosphere s = MakeUnitIcosphere(level);
  TriangleMesh m;
  for (const Eigen::Vector3d& v : s.vertices) m.vertices.push_back(v.cast<float>());
  m.faces = s.faces;
  return m;
}

// A linear (affine) field of the position.
Eigen::Vector3f Field(const Eigen::Vector3f& p) {
  Eigen::Matrix3f a;
  a << 0.3f, -0.2f, 0.1f, 0.05f, 0.4f, -0.3f, -0.1f, 0.2f, 0.25f;
  return a * p + Eigen::Vector3f(0.5f, 0.4f, 0.6f);
}

void SetLinearField(const TriangleMesh& mesh, MeshColors& colors) {
  std::vector<Eigen::Vector3f> per_vertex;
  for (const Eigen::Vector3f& p : mesh.vertices) per_vertex.push_back(Field(p));
  colors.colors() = colors.InterpolateVertexAttribute(per_vertex);
}

Eigen::Vector3f PointOf(const TriangleMesh& m, int f, float b1, float b2) {
  const Eigen::Vector3i& v = m.faces[f];
  return (1 - b1 - b2) * m.vertices[v[0]] + b1 * m.vertices[v[1]] + b2 * m.vertices[v[2]];
}

TEST(MeshColors, SampleCountsMatchTheFormulas) {
  for (int r : {1, 2, 4, 8, 16, 64}) {
    const MeshColors c(OneTriangle(), {r});
    EXPECT_EQ(c.SampleCount(), static_cast<size_t>((r + 1) * (r + 2) / 2)) << "R = " << r;
    EXPECT_EQ(c.VertexSampleCount(), 3u);
    EXPECT_EQ(c.EdgeSampleCount(), static_cast<size_t>(3 * (r - 1))) << "R = " << r;
    EXPECT_EQ(c.FaceSampleCount(), static_cast<size_t>((r - 1) * (r - 2) / 2)) << "R = " << r;
  }
}

TEST(MeshColors, SharedEdgeSamplesAreStoredOnce) {
  const TriangleMesh m = TwoTriangles();
  const int r = 8;
  const MeshColors c(m, {r, r});
  // 4 vertices, 5 edges of R-1 samples, 2 interiors.
  EXPECT_EQ(c.SampleCount(), 4u + 5u * (r - 1) + 2u * (r - 1) * (r - 2) / 2);
  // The shared edge seen from both faces: face 0 side 1 (v1 -> v2) at step n is face 1 side 0
  // (v2 -> v1) at step R - n.
  for (int n = 0; n <= r; ++n) {
    EXPECT_EQ(c.SampleIndex(0, r - n, n), c.SampleIndex(1, r - n, 0)) << "n = " << n;
  }
  // Every sample is reached from some face's lattice, and each exactly where it says it lives.
  std::set<uint32_t> reached;
  for (int f = 0; f < 2; ++f) {
    for (int j = 0; j <= r; ++j) {
      for (int i = 0; i + j <= r; ++i) reached.insert(c.SampleIndex(f, i, j));
    }
  }
  EXPECT_EQ(reached.size(), c.SampleCount());
  EXPECT_EQ(*reached.rbegin(), c.SampleCount() - 1);
}

TEST(MeshColors, MixedResolutionsShareTheFinerEdge) {
  const TriangleMesh m = TwoTriangles();
  const MeshColors c(m, {2, 8});
  EXPECT_EQ(c.EdgeResolution(c.FaceEdge(0, 1)), 8);
  EXPECT_EQ(c.EdgeResolution(c.FaceEdge(0, 0)), 2);
  // Face 0's edge midpoint (R = 2) is face 1's edge sample 4 of 8.
  EXPECT_EQ(c.SampleIndex(0, 1, 1), c.SampleIndex(1, 4, 0));
  // Shared edge 7, face 1's other edges 2 x 7, face 0's other edges 2 x 1; interiors 0 and 21.
  EXPECT_EQ(c.SampleCount(), 4u + (7u + 2u * 7u + 2u * 1u) + 0u + 21u);
}

TEST(MeshColors, LinearFieldRoundTripsWithLinearLookup) {
  const TriangleMesh m = Icosphere(2);
  std::mt19937 rng(7);
  std::vector<int> res(m.faces.size());
  for (int& r : res) r = 1 << std::uniform_int_distribution<int>(0, 4)(rng);
  MeshColors c(m, res);
  SetLinearField(m, c);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  double worst = 0.0;
  for (int f = 0; f < static_cast<int>(m.faces.size()); ++f) {
    for (int k = 0; k < 20; ++k) {
      float b1 = u(rng), b2 = u(rng);
      if (b1 + b2 > 1.0f) b1 = 1.0f - b1, b2 = 1.0f - b2;
      if (k == 0) b1 = 0.0f, b2 = 1.0f;  // corners and edges too
      if (k == 1) b1 = 0.5f, b2 = 0.5f;
      if (k == 2) b1 = 0.25f, b2 = 0.0f;
      const Eigen::Vector3f want = Field(PointOf(m, f, b1, b2));
      worst =
          std::max(worst, static_cast<double>((c.Linear(f, b1, b2) - want).cwiseAbs().maxCoeff()));
    }
  }
  EXPECT_LT(worst, 2e-6) << "a linear field must come back up to float rounding";
}

TEST(MeshColors, NearestReturnsTheLatticeSample) {
  const TriangleMesh m = TwoTriangles();
  MeshColors c(m, {4, 4});
  for (size_t s = 0; s < c.SampleCount(); ++s) c.colors()[s] = Eigen::Vector3f(float(s), 0, 0);
  for (int j = 0; j <= 4; ++j) {
    for (int i = 0; i + j <= 4; ++i) {
      const float eps = 0.01f;  // a little off the lattice point, towards the face's centre
      const float b1 = (i + eps * (1.0f / 3 * 4 - i)) / 4, b2 = (j + eps * (1.0f / 3 * 4 - j)) / 4;
      EXPECT_EQ(c.Nearest(1, b1, b2)[0], float(c.SampleIndex(1, i, j))) << i << "," << j;
    }
  }
}

TEST(MeshColors, SitesAndFacePointsAgreeWithTheLattice) {
  const TriangleMesh m = Icosphere(1);
  std::vector<int> res(m.faces.size());
  for (size_t f = 0; f < res.size(); ++f) res[f] = 1 << (f % 4);
  const MeshColors c(m, res);
  const std::vector<Eigen::Vector3f> positions = c.InterpolateVertexAttribute(m.vertices);
  for (size_t s = 0; s < c.SampleCount(); ++s) {
    int f;
    double b1, b2;
    c.SampleFacePoint(s, &f, &b1, &b2);
    EXPECT_LT((PointOf(m, f, float(b1), float(b2)) - positions[s]).norm(), 1e-6) << "sample " << s;
    const int r = c.FaceResolution(f);
    const int i = static_cast<int>(std::lround(b1 * r)), j = static_cast<int>(std::lround(b2 * r));
    EXPECT_EQ(c.SampleIndex(f, i, j), s);
  }
}

TEST(MeshColors, SubdividedMeshIsClosedAndCarriesTheColours) {
  const TriangleMesh m = Icosphere(1);
  MeshColors c(m, std::vector<int>(m.faces.size(), 4));
  SetLinearField(m, c);
  const TriangleMesh sub = c.ToSubdividedMesh(m);
  EXPECT_EQ(sub.vertices.size(), c.SampleCount());
  EXPECT_EQ(sub.faces.size(), m.faces.size() * 16);
  std::map<std::pair<int, int>, int> uses;
  for (const Eigen::Vector3i& f : sub.faces) {
    for (int k = 0; k < 3; ++k)
      ++uses[{std::min(f[k], f[(k + 1) % 3]), std::max(f[k], f[(k + 1) % 3])}];
  }
  for (const auto& [edge, n] : uses) EXPECT_EQ(n, 2) << edge.first << "-" << edge.second;
  // V - E + F = 2 for the subdivided sphere too.
  EXPECT_EQ(static_cast<long>(sub.vertices.size()) - static_cast<long>(uses.size()) +
                static_cast<long>(sub.faces.size()),
            2);
  for (size_t s = 0; s < sub.vertices.size(); ++s) {
    EXPECT_LT((sub.vertex_colors[s] - Field(sub.vertices[s])).norm(), 1e-5);
  }
}

TEST(MeshColors, ResolutionFollowsTheTexelSpacing) {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {0.1f, 0, 0}, {0, 0.05f, 0}, {2, 0, 0}, {2, 2, 0}};
  m.faces = {{0, 1, 2}, {0, 3, 4}};
  const std::vector<int> r = ChooseFaceResolutions(m, 0.01, 64);
  EXPECT_EQ(r[0], 16);  // 0.1 m / 16 = 6.3 mm <= 10 mm; / 8 = 12.5 mm is too coarse
  EXPECT_EQ(r[1], 64);  // 2.8 m would need 512: capped
  EXPECT_CONTAINS(test::ErrorOf([&] { ChooseFaceResolutions(m, 0.0, 64); }), "texel spacing");
  EXPECT_CONTAINS(test::ErrorOf([&] { ChooseFaceResolutions(m, 0.01, 48); }), "power of two");
  EXPECT_CONTAINS(test::ErrorOf([&] { MeshColors(m, {3, 4}); }), "resolution 3");
}

TEST(MeshColors, FileRoundTripIsExactAndRefusesAnotherMesh) {
  TempDir dir;
  const TriangleMesh m = Icosphere(2);
  std::vector<int> res(m.faces.size());
  for (size_t f = 0; f < res.size(); ++f) res[f] = 1 << (f % 5);
  MeshColors c(m, res);
  SetLinearField(m, c);
  c.labels().resize(c.SampleCount());
  for (size_t s = 0; s < c.SampleCount(); ++s) c.labels()[s] = static_cast<int32_t>(s % 11) - 1;
  WriteMeshColors(dir / "a.mcol", c);
  const MeshColors back = ReadMeshColors(dir / "a.mcol", m);
  EXPECT_EQ(back.face_resolutions(), c.face_resolutions());
  ASSERT_EQ(back.SampleCount(), c.SampleCount());
  for (size_t s = 0; s < c.SampleCount(); ++s) EXPECT_EQ(back.colors()[s], c.colors()[s]);
  EXPECT_EQ(back.labels(), c.labels());

  TriangleMesh other = m;
  std::swap(other.faces[0][0], other.faces[0][1]);
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadMeshColors(dir / "a.mcol", other); }), "another mesh");
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadMeshColors(dir / "a.mcol", Icosphere(1)); }),
                  "made for a mesh of 162 vertices");
  // Truncated and foreign files.
  std::ifstream in(dir / "a.mcol", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  test::WriteFile(dir / "cut.mcol", bytes.substr(0, bytes.size() - 5));
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadMeshColors(dir / "cut.mcol", m); }), "cut.mcol: holds");
  test::WriteFile(dir / "x.mcol", "ply\nformat ascii 1.0\n");
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadMeshColors(dir / "x.mcol", m); }),
                  "not a Mesh Colors file");
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadMeshColors(dir / "missing.mcol", m); }), "cannot open");
}

// Every resolution, millions of hard inputs: the cell's lattice points lie in the face, its
// weights are in [0, 1] and sum to 1, and for points in the triangle the weights reproduce it.
TEST(MeshColorsProperty, LocateInLatticeStaysInTheFaceForAnyInput) {
  std::mt19937 rng(7);
  size_t checked = 0;
  for (int r = 1; r <= MeshColors::kMaxResolution; r *= 2) {
    for (const auto& [b1, b2] : test::HardBarycentrics(rng, 150000, 50000)) {
      const LatticeCell c = LocateInLattice(r, b1, b2);
      float sum = 0.0f;
      double x = 0.0, y = 0.0;
      for (int k = 0; k < 3; ++k) {
        ASSERT_TRUE(c.i[k] >= 0 && c.j[k] >= 0 && c.i[k] + c.j[k] <= r)
            << "r " << r << " (" << b1 << ", " << b2 << ") gives (" << c.i[k] << ", " << c.j[k]
            << ")";
        ASSERT_TRUE(c.w[k] >= 0.0f && c.w[k] <= 1.0f)
            << "r " << r << " (" << b1 << ", " << b2 << ") weight " << c.w[k];
        sum += c.w[k];
        x += c.w[k] * c.i[k];
        y += c.w[k] * c.j[k];
      }
      ASSERT_NEAR(sum, 1.0f, 1e-5f) << "r " << r << " (" << b1 << ", " << b2 << ")";
      if (b1 >= 0.0f && b2 >= 0.0f && b1 + b2 <= 1.0f) {
        ASSERT_NEAR(x, b1 * r, 2e-4 * r) << "r " << r << " (" << b1 << ", " << b2 << ")";
        ASSERT_NEAR(y, b2 * r, 2e-4 * r) << "r " << r << " (" << b1 << ", " << b2 << ")";
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 4000000u);
}

// The lookups on faces of every resolution: never throw, finite, and a linear field comes back
// at points in the face (the face where a lookup just off the long edge once failed included).
TEST(MeshColorsProperty, LookupsOfEveryResolutionTakeAnyBarycentrics) {
  TriangleMesh mesh;
  std::vector<int> resolution;
  for (int r = 1; r <= MeshColors::kMaxResolution; r *= 2) {
    const int v = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(),
                         {{0, 0, float(r)}, {1, 0, float(r)}, {0, 1, float(r)}});
    mesh.faces.emplace_back(v, v + 1, v + 2);
    resolution.push_back(r);
  }
  MeshColors colors(mesh, resolution);
  SetLinearField(mesh, colors);
  std::mt19937 rng(11);
  for (int f = 0; f < static_cast<int>(mesh.faces.size()); ++f) {
    for (const auto& [b1, b2] : test::HardBarycentrics(rng, 20000, 20000)) {
      Eigen::Vector3f linear, nearest;
      ASSERT_NO_THROW(linear = colors.Linear(f, b1, b2))
          << "face " << f << " (" << b1 << ", " << b2 << ")";
      ASSERT_NO_THROW(nearest = colors.Nearest(f, b1, b2))
          << "face " << f << " (" << b1 << ", " << b2 << ")";
      ASSERT_TRUE(linear.allFinite() && nearest.allFinite());
      if (b1 >= 0.0f && b2 >= 0.0f && b1 + b2 <= 1.0f) {
        ASSERT_LT((linear - Field(PointOf(mesh, f, b1, b2))).norm(), 1e-4f)
            << "face " << f << " (" << b1 << ", " << b2 << ")";
      }
    }
  }
}

// The lookup that stopped refinement on real recordings: a face of resolution 4, a point whose
// float coordinates sum to just above 1 on the long edge.
TEST(MeshColorsProperty, PointJustPastTheLongEdgeOfAResolution4Face) {
  const TriangleMesh mesh = OneTriangle();
  MeshColors colors(mesh, {4});
  SetLinearField(mesh, colors);
  const Eigen::Vector3f c = colors.Linear(0, 0.205793679f, 0.794206858f);
  EXPECT_LT((c - Field(PointOf(mesh, 0, 0.205793679f, 0.794206321f))).norm(), 1e-5f);
}

}  // namespace
}  // namespace genscene
