// The Mesh Colors texture atlas: every sample read back by bilinear sampling at its UV, a field
// linear over each face reproduced anywhere inside the faces (the extrapolated ring and the
// gutter), the layout's texel density and disjoint charts, the size cap.
#include "core/mesh_colors_atlas.h"

#include <cmath>
#include <random>
#include <set>

#include "core/color.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

using test::ErrorOf;

// An n x n grid of quads (2 triangles each) on z = 0, counter-clockwise seen from +z.
TriangleMesh Grid(int n) {
  TriangleMesh mesh;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) mesh.vertices.emplace_back(0.1f * x, 0.1f * y, 0.0f);
  }
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const int a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      mesh.faces.emplace_back(a, b, d);
      mesh.faces.emplace_back(a, d, c);
    }
  }
  return mesh;
}

// Mesh Colors on Grid(n) with resolutions drawn from {1, 2, 4, 8, 16} and random colours.
MeshColors RandomColors(const TriangleMesh& mesh, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<int> resolution(mesh.faces.size());
  for (int& r : resolution) r = 1 << std::uniform_int_distribution<int>(0, 4)(rng);
  MeshColors colors(mesh, resolution);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (Eigen::Vector3f& c : colors.colors()) c = {unit(rng), unit(rng), unit(rng)};
  return colors;
}

// Bilinear sample (texel centres at integer + 0.5 in UV x size, clamp to edge) of channel data
// `at(x, y)` (an Eigen::Vector3d).
template <typename At>
Eigen::Vector3d Bilinear(int width, int height, const Eigen::Vector2f& uv, const At& at) {
  const double x = uv.x() * width - 0.5, y = uv.y() * height - 0.5;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  auto clamped = [&](int xi, int yi) -> Eigen::Vector3d {
    return at(std::clamp(xi, 0, width - 1), std::clamp(yi, 0, height - 1));
  };
  return ((1 - fx) * (1 - fy)) * clamped(x0, y0) + (fx * (1 - fy)) * clamped(x0 + 1, y0) +
         ((1 - fx) * fy) * clamped(x0, y0 + 1) + (fx * fy) * clamped(x0 + 1, y0 + 1);
}

Eigen::Vector3d SampleSrgb8(const AtlasImage& image, const Eigen::Vector2f& uv) {
  return Bilinear(image.width, image.height, uv, [&](int x, int y) {
    const uint8_t* p = &image.srgb8[3 * (static_cast<size_t>(y) * image.width + x)];
    return Eigen::Vector3d(p[0], p[1], p[2]);
  });
}

Eigen::Vector3d SampleLinear(const AtlasImage& image, const Eigen::Vector2f& uv) {
  return Bilinear(image.width, image.height, uv, [&](int x, int y) {
    return image.linear[static_cast<size_t>(y) * image.width + x].cast<double>();
  });
}

// The UV of barycentric point (b1, b2) of face f from the per-corner UVs, as a renderer
// interpolates them.
Eigen::Vector2f CornerUv(const std::vector<Eigen::Vector2f>& uv, int f, float b1, float b2) {
  return (1.0f - b1 - b2) * uv[3 * f] + b1 * uv[3 * f + 1] + b2 * uv[3 * f + 2];
}

// Every Mesh Colors sample, read back bilinearly at its UV from the 8-bit sRGB atlas, against the
// sample's colour sRGB-encoded to [0, 255]: mean |error| over samples and channels at most 1
// (1/255 of full scale). Only 8-bit rounding should remain (at most 0.5).
TEST(AtlasTest, EverySampleReadsBackFromTheSrgbAtlas) {
  const TriangleMesh mesh = Grid(6);
  const MeshColors colors = RandomColors(mesh, 7);
  const AtlasLayout layout = MakeAtlasLayout(colors.face_resolutions());
  const AtlasImage image = BakeAtlas(layout, colors);
  ASSERT_EQ(image.width, layout.width);
  ASSERT_EQ(image.srgb8.size(), 3u * image.width * image.height);
  EXPECT_EQ(layout.downscale, 0);
  EXPECT_TRUE(layout.warnings.empty());
  const std::vector<Eigen::Vector2f> uv = layout.CornerUvs();
  ASSERT_EQ(uv.size(), 3 * mesh.faces.size());
  double sum = 0.0, worst = 0.0;
  size_t count = 0;
  for (int f = 0; f < colors.num_faces(); ++f) {
    const int r = colors.FaceResolution(f);
    for (int j = 0; j <= r; ++j) {
      for (int i = 0; i + j <= r; ++i) {
        const float b1 = static_cast<float>(i) / r, b2 = static_cast<float>(j) / r;
        const Eigen::Vector3f truth = colors.colors()[colors.SampleIndex(f, i, j)];
        const Eigen::Vector3d got = SampleSrgb8(image, CornerUv(uv, f, b1, b2));
        for (int c = 0; c < 3; ++c) {
          const double error = std::abs(got[c] - 255.0 * LinearToSrgb(truth[c]));
          sum += error, worst = std::max(worst, error), ++count;
        }
      }
    }
  }
  const double mean = sum / count;
  RecordProperty("mean_error_8bit", std::to_string(mean));
  std::printf("%zu sample channels, atlas %dx%d: mean |error| %.3f/255, max %.3f/255\n", count,
              image.width, image.height, mean, worst);
  EXPECT_LE(mean, 1.0);
  EXPECT_LE(worst, 0.51);
}

// A colour field linear over each face (vertex colours interpolated) is reproduced by bilinear
// sampling of the linear atlas anywhere in the faces, their edges and vertices included: the
// texels past the long edge are extrapolated, and no other chart's colour leaks in.
TEST(AtlasTest, LinearFieldIsReproducedInsideEveryFace) {
  const TriangleMesh mesh = Grid(5);
  MeshColors colors = RandomColors(mesh, 11);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<Eigen::Vector3f> per_vertex(mesh.vertices.size());
  for (Eigen::Vector3f& c : per_vertex) c = Eigen::Vector3f(unit(rng), unit(rng), unit(rng));
  colors.colors() = colors.InterpolateVertexAttribute(per_vertex);
  const AtlasLayout layout = MakeAtlasLayout(colors.face_resolutions());
  const AtlasImage image = BakeAtlas(layout, colors);
  const std::vector<Eigen::Vector2f> uv = layout.CornerUvs();
  double worst = 0.0;
  for (int f = 0; f < colors.num_faces(); ++f) {
    for (const auto& [b1, b2] : test::HardBarycentrics(rng, 40, 10)) {
      if (!(b1 >= 0.0f && b2 >= 0.0f && b1 + b2 <= 1.0f)) continue;  // inside the face only
      const Eigen::Vector3d got = SampleLinear(image, CornerUv(uv, f, b1, b2));
      worst =
          std::max(worst, (got - colors.Linear(f, b1, b2).cast<double>()).cwiseAbs().maxCoeff());
    }
  }
  std::printf("linear field: max |error| %.2e\n", worst);
  EXPECT_LT(worst, 1e-4);
}

// Legs of r texel steps along x and y (r the face's resolution), charts on distinct texels
// inside the image, and an atlas no larger than a few times the charts' own texels.
TEST(AtlasTest, ChartsFollowTheTexelDensityAndDoNotOverlap) {
  const TriangleMesh mesh = Grid(8);
  const MeshColors colors = RandomColors(mesh, 5);
  const AtlasLayout layout = MakeAtlasLayout(colors.face_resolutions());
  EXPECT_EQ(layout.width & (layout.width - 1), 0) << "width " << layout.width;
  std::set<std::pair<int, int>> used;
  size_t lattice_texels = 0;
  for (int f = 0; f < layout.num_faces(); ++f) {
    const int r = colors.FaceResolution(f);
    ASSERT_EQ(layout.resolution[f], r);
    const Eigen::Vector2d o = layout.TexelPosition(f, 0.0, 0.0);
    const double s = layout.step[f];
    EXPECT_EQ(layout.TexelPosition(f, 1.0, 0.0), o + Eigen::Vector2d(s * r, 0.0));
    EXPECT_EQ(layout.TexelPosition(f, 0.0, 1.0), o + Eigen::Vector2d(0.0, s * r));
    // The lattice and the ring past the long edge.
    for (int j = 0; j <= r + 1; ++j) {
      for (int i = 0; i + j <= r + 1; ++i) {
        const Eigen::Vector2d t = layout.TexelPosition(f, double(i) / r, double(j) / r);
        ASSERT_TRUE(t.x() >= 0 && t.y() >= 0 && t.x() < layout.width && t.y() < layout.height);
        EXPECT_TRUE(used.emplace(int(t.x()), int(t.y())).second)
            << "face " << f << " (" << i << ", " << j << ")";
        ++lattice_texels;
      }
    }
  }
  const double area = double(layout.width) * layout.height;
  std::printf("%zu chart texels in %dx%d (%.0f %%)\n", lattice_texels, layout.width, layout.height,
              100.0 * lattice_texels / area);
  EXPECT_LT(area, 6.0 * lattice_texels);
}

// Past max_size every face's resolution is halved until the atlas fits, with a warning; the
// baked lattice then holds every 2^k-th sample. Faces that cannot fit at all are an Error.
TEST(AtlasTest, TooLargeAtlasIsDownscaledWithAWarning) {
  const TriangleMesh mesh = Grid(4);
  MeshColors colors(mesh, std::vector<int>(mesh.faces.size(), 32));
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (Eigen::Vector3f& c : colors.colors()) c = {unit(rng), unit(rng), unit(rng)};
  AtlasOptions options;
  options.max_size = 128;
  const AtlasLayout layout = MakeAtlasLayout(colors.face_resolutions(), options);
  EXPECT_GT(layout.downscale, 0);
  EXPECT_LE(layout.width, 128);
  EXPECT_LE(layout.height, 128);
  ASSERT_EQ(layout.warnings.size(), 1u);
  EXPECT_CONTAINS(layout.warnings[0], "halved");
  const AtlasImage image = BakeAtlas(layout, colors);
  const std::vector<Eigen::Vector2f> uv = layout.CornerUvs();
  double worst = 0.0;
  for (int f = 0; f < colors.num_faces(); ++f) {
    const int r = layout.resolution[f], step = 32 / r;
    for (int j = 0; j <= r; ++j) {
      for (int i = 0; i + j <= r; ++i) {
        const Eigen::Vector3f truth = colors.colors()[colors.SampleIndex(f, i * step, j * step)];
        const Eigen::Vector3d got = SampleLinear(
            image, CornerUv(uv, f, static_cast<float>(i) / r, static_cast<float>(j) / r));
        worst = std::max(worst, (got - truth.cast<double>()).cwiseAbs().maxCoeff());
      }
    }
  }
  EXPECT_LT(worst, 1e-4);

  options.max_size = 16;
  EXPECT_CONTAINS(ErrorOf([&] { MakeAtlasLayout(std::vector<int>(200, 1), options); }),
                  "do not fit");
}

TEST(AtlasTest, BadInputsAreErrors) {
  const TriangleMesh mesh = Grid(2);
  const MeshColors colors = RandomColors(mesh, 1);
  EXPECT_CONTAINS(ErrorOf([] { MakeAtlasLayout({1, 3}); }), "face 1 has resolution 3");
  AtlasOptions options;
  options.gutter = 0;
  EXPECT_CONTAINS(ErrorOf([&] { MakeAtlasLayout({1}, options); }), "gutter");
  const AtlasLayout other = MakeAtlasLayout({1, 2});
  EXPECT_CONTAINS(ErrorOf([&] { BakeAtlas(other, colors); }), "the layout has 2 faces");
}

}  // namespace
}  // namespace genscene
