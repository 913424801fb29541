// Albedo initialisation by chromaticity clustering: the Cornell box
// rendered by Blender Cycles with full global illumination (../shared/data/cbox-cycles), so the
// observed colours carry shading, shadows and colour bleeding.
#include "texturing/albedo.h"

#include <map>

#include "core/frame_source.h"
#include "core/ply_io.h"
#include "tests/test_util.h"
#include "texturing/backproject.h"

namespace genscene::texturing {
namespace {

Eigen::Vector3f ChromaOf(const Eigen::Vector3f& c) {
  return c / c.sum();
}

struct CboxFigures {
  int clusters = 0;           // clusters holding >= 0.5 % of the observed texels
  int distinct_albedos = 0;   // in the ground truth of the faces the keyframes see
  double worst_chroma = 0.0;  // largest |chromaticity - truth| over those clusters and channels
  double mislabelled = 0.0;  // fraction of observed texels in a cluster standing for another albedo
};

CboxFigures RunCbox(const std::filesystem::path& data, const std::string& views) {
  const auto root = data / "cbox-cycles";
  const TriangleMesh mesh = ReadPly(root / "geometry" / "scene.ply");
  EXPECT_EQ(mesh.face_colors.size(), mesh.faces.size());
  auto source = OpenFrameSource((root / "views" / views).string(), SourceOptions());
  const std::vector<RgbdFrame> frames = ReadAllFrames(*source);
  TexturingOptions to;
  to.texel_spacing = 0.01;
  const TexturingResult texture = TextureMesh(mesh, frames, to);
  const AlbedoResult albedo =
      EstimateAlbedo(texture.texture, texture.texture.labels(), AlbedoOptions());

  CboxFigures fig;
  std::map<std::tuple<float, float, float>, size_t> truth_seen;
  // Per cluster: the true albedo most of its observed texels lie on.
  std::vector<std::map<std::tuple<float, float, float>, size_t>> votes(albedo.clusters.size());
  for (size_t s = 0; s < texture.texture.SampleCount(); ++s) {
    if (texture.texture.labels()[s] == 0) continue;
    int f;
    double b1, b2;
    texture.texture.SampleFacePoint(s, &f, &b1, &b2);
    const Eigen::Vector3f& t = mesh.face_colors[f];
    const auto key = std::make_tuple(t.x(), t.y(), t.z());
    ++truth_seen[key];
    ++votes[albedo.albedo.labels()[s]][key];
  }
  size_t observed = 0;
  for (const auto& [key, count] : truth_seen) observed += count;
  for (const auto& [key, count] : truth_seen) fig.distinct_albedos += count > 0.005 * observed;
  // The albedo and the lights' colour share a per-channel gauge (light estimation fixes it): the
  // white balance that best maps the recovered albedos onto the true ones, in log space,
  // weighted by observed texels.
  Eigen::Array3d log_balance = Eigen::Array3d::Zero();
  double balance_weight = 0.0;
  std::vector<Eigen::Vector3f> cluster_truth(albedo.clusters.size(), Eigen::Vector3f::Zero());
  for (const AlbedoCluster& c : albedo.clusters) {
    if (votes[c.id].empty()) continue;
    const auto best =
        std::max_element(votes[c.id].begin(), votes[c.id].end(),
                         [](const auto& a, const auto& b) { return a.second < b.second; });
    cluster_truth[c.id] = Eigen::Vector3f(std::get<0>(best->first), std::get<1>(best->first),
                                          std::get<2>(best->first));
    log_balance +=
        static_cast<double>(c.observed_texels) * (cluster_truth[c.id].cast<double>().array().log() -
                                                  c.albedo.cast<double>().array().max(1e-6).log());
    balance_weight += static_cast<double>(c.observed_texels);
  }
  const Eigen::Vector3f balance = (log_balance / balance_weight).exp().cast<float>();
  std::cout << "white balance (per-channel gauge): " << balance.transpose() / balance.maxCoeff()
            << "\n";
  for (const AlbedoCluster& c : albedo.clusters) {
    std::cout << "cluster " << c.id << ": albedo " << c.albedo.transpose() << ", " << c.texels
              << " texels (" << c.observed_texels << " observed), " << c.pieces << " pieces"
              << (c.dark ? ", dark" : "") << "\n";
    if (c.observed_texels < 0.005 * observed) continue;
    ++fig.clusters;
    const Eigen::Vector3f& truth = cluster_truth[c.id];
    const double err =
        (ChromaOf(c.albedo.cwiseProduct(balance)) - ChromaOf(truth)).cwiseAbs().maxCoeff();
    std::cout << "  truth " << truth.transpose() << ": chromaticity error " << err
              << " (without the balance "
              << (ChromaOf(c.albedo) - ChromaOf(truth)).cwiseAbs().maxCoeff() << ")\n";
    fig.worst_chroma = std::max(fig.worst_chroma, err);
  }
  // Texels whose cluster stands for another albedo than their own face's.
  size_t wrong = 0;
  for (size_t s = 0; s < texture.texture.SampleCount(); ++s) {
    if (texture.texture.labels()[s] == 0) continue;
    int f;
    double b1, b2;
    texture.texture.SampleFacePoint(s, &f, &b1, &b2);
    wrong += (cluster_truth[albedo.albedo.labels()[s]] - mesh.face_colors[f]).norm() > 1e-6f;
  }
  fig.mislabelled = static_cast<double>(wrong) / static_cast<double>(observed);
  std::cout << views << ": " << 100.0 * fig.mislabelled
            << " % of the observed texels in a cluster of another albedo\n";
  std::cout << views << ": " << fig.clusters << " clusters for " << fig.distinct_albedos
            << " distinct albedos; " << albedo.stats.chroma_classes << " chromaticity classes, "
            << albedo.stats.pieces << " pieces, worst chromaticity error " << fig.worst_chroma
            << "\n";
  return fig;
}

TEST(Albedo, CyclesCornellBoxClustersIntoItsAlbedos) {
  GS_REQUIRE_SHARED_DATA(data);
  const CboxFigures fig = RunCbox(data, "train");
  EXPECT_EQ(fig.distinct_albedos, 3);
  EXPECT_LE(std::abs(fig.clusters - fig.distinct_albedos), 1);
  EXPECT_LE(fig.worst_chroma, 0.02);
  // Regression guard, not an acceptance figure: 16 % today. The blocks' sides that face the red
  // and green walls get no direct light, only light from those walls, and are as saturated as
  // the walls themselves (tall block side: chromaticity (0.80, 0.13) vs the red wall's (0.89,
  // 0.07)); chromaticity alone cannot tell them apart. Light estimation and refinement, which
  // divide by the path-traced irradiance, are where this gets fixed.
  EXPECT_LT(fig.mislabelled, 0.2);
}

TEST(Albedo, BadInputsAreClearErrors) {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.faces = {{0, 1, 2}};
  const MeshColors c(m, {4});
  EXPECT_CONTAINS(test::ErrorOf([&] {
                    EstimateAlbedo(c, std::vector<int32_t>(c.SampleCount(), 0), AlbedoOptions());
                  }),
                  "no texel of the texture was observed");
  EXPECT_CONTAINS(test::ErrorOf([&] {
                    EstimateAlbedo(c, {1, 2}, AlbedoOptions());
                  }),
                  "2 view counts for 15 texels");
  EXPECT_CONTAINS(test::ErrorOf([&] { EstimateAlbedo(MeshColors(), {}, AlbedoOptions()); }),
                  "no samples");
}

}  // namespace
}  // namespace genscene::texturing
