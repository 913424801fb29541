// Albedo initialisation (the paper, section V-A; Garces, Munoz, Lopez-Moreno, Gutierrez,
// "Intrinsic images by clustering", 2012, carried from image pixels to Mesh Colors texels).
//
// The back-projected colour I of a texel is albedo x shading, with direct and indirect light baked
// in. Shading changes brightness far more than chromaticity, so:
//   1. texels are clustered by chromaticity c = (r, g) / (r + g + b) with mean shift (flat kernel
//      of radius chroma_bandwidth) over a 2D histogram; modes holding less than
//      min_mode_fraction of the observed texels are dropped and their texels join the nearest
//      mode. Near-black texels (luminance below dark_fraction x the median), whose
//      chromaticity is noise, form a class of their own.
//      White balance (a stated prior; neutral_distance 0 turns it off): of the modes holding at
//      least 10 % of the texels, the one nearest to neutral (1/3, 1/3) is taken as a white or
//      grey surface when it lies within neutral_distance of neutral. Its tint is the light's:
//      every texel's colour is divided by it per channel and the modes are found again. The
//      lights' colour then carries the tint (light estimation starts the lights white and lets
//      each voxel's colour free). A room with no large near-neutral surface keeps its colours.
//   2. each class is split into connected pieces on the mesh (the Mesh Colors lattice graph);
//      pieces smaller than min_piece_texels join the neighbour they share most boundary with.
//   3. each piece P gets albedo s_P m_P, where m_P has the chromaticity of its class's mode (the
//      least tinted by colour bleeding) and the mean observed luminance of the piece. The scales
//      x_P = log s_P minimise, over every lattice edge (a in P, b in Q) across a piece boundary,
//      the jump in shading S = L(I) / L(albedo) (L = luminance):
//          E = sum_(a,b) w_ab (x_P - x_Q - [log(L(I_a) / L(m_P)) - log(L(I_b) / L(m_Q))])^2
//            + sum_P w_prior (x_P + log L(m_P) - x_C - log L(m_C))^2
//      where C is the largest piece of P's class: a weak prior that pieces of one chromaticity
//      share one albedo, which decides only for pieces with no boundary (separate objects).
//      w_ab = exp(-(|c_a - mode_a|^2 + |c_b - mode_b|^2) / 2 h^2) (h: chroma_bandwidth), and
//      edges with w_ab < 0.01 are left out: where two colours meet, keyframes that disagree by a
//      pixel and light bled from one surface onto the other leave texels of mixed colour, whose
//      luminance belongs to the other surface (a white wall's pink border classed red made the
//      red wall as bright as the white one). Edges at near-black texels are left out too (noise
//      in both chromaticity and log luminance). Pieces that no edge joins keep their own mean
//      observed luminance. The
//      gauge (a global scale) is fixed on purpose: the texel-weighted mean of x is 0, then all
//      albedos are scaled so that the 95th percentile of the largest channel is max_albedo.
//      Light estimation fixes the true global scale.
//   4. pieces of one class whose albedo luminances agree within merge_tolerance are one cluster.
// Unobserved texels (view count 0, e.g. filled by the texturing stage) take part in the graph but
// do not vote for modes or piece colours.
#pragma once

#include <vector>

#include "core/mesh_colors.h"
#include "core/options.h"

namespace genscene::texturing {

struct AlbedoOptions {
  static constexpr const char* kSection = "albedo";
  double chroma_bandwidth = 0.05;   // mean-shift radius in (r, g) chromaticity
  double min_mode_fraction = 0.02;  // modes with less of the observed texels are dropped
  double dark_fraction = 0.05;      // darker texels (x the median luminance) form the dark class
  int min_piece_texels = 30;        // smaller connected pieces join a neighbour
  double merge_tolerance = 0.2;   // pieces of one class within this luminance ratio share an albedo
  double max_albedo = 0.9;        // gauge: 95th percentile of the largest albedo channel
  double prior_weight = 1.0;      // weight of the same-chromaticity-same-albedo prior
  double neutral_distance = 0.2;  // white balance: a large mode this near neutral is grey (0: off)

  template <typename V>
  void Visit(V&& v) {
    v("chroma_bandwidth", chroma_bandwidth, "", "mean-shift radius in rg chromaticity");
    v("min_mode_fraction", min_mode_fraction, "",
      "chromaticity modes holding less of the surface are dropped");
    v("dark_fraction", dark_fraction, "",
      "texels darker than this x the median luminance form the dark class");
    v("min_piece_texels", min_piece_texels, "",
      "connected pieces with fewer texels join a neighbour");
    v("merge_tolerance", merge_tolerance, "",
      "pieces of one class whose albedos agree within this ratio merge");
    v("max_albedo", max_albedo, "", "global scale: 95th percentile of the largest albedo channel");
    v("prior_weight", prior_weight, "", "weight of the prior that one chromaticity has one albedo");
    v("neutral_distance", neutral_distance, "",
      "white balance: the most neutral mode with 10 % of the texels, when this near neutral in rg "
      "chromaticity, is taken as grey and its tint as the light's (0 = off)");
  }
  void Validate() const;
};

struct AlbedoCluster {
  int id = 0;
  Eigen::Vector3f albedo = Eigen::Vector3f::Zero();        // linear RGB in [0, 1]
  Eigen::Vector3f chromaticity = Eigen::Vector3f::Zero();  // albedo / (r + g + b)
  size_t texels = 0;
  size_t observed_texels = 0;
  int pieces = 0;
  bool dark = false;  // from the near-black class
};

struct AlbedoStats {
  int chroma_classes = 0;         // chromaticity modes (+1 when there are dark texels)
  int pieces = 0;                 // connected pieces after merging small ones
  size_t boundary_edges = 0;      // texel edges across piece boundaries that the solve uses
  double shading_jump_rms = 0.0;  // weighted RMS of the boundary residuals (log units)
  // The per-channel factor the albedo was white-balanced by before the gauge (1, 1, 1: none); the
  // lights take up the tint it took out.
  Eigen::Vector3f white_balance = Eigen::Vector3f::Ones();
};

struct AlbedoResult {
  MeshColors albedo;                    // the cluster albedo at every texel; labels() = cluster id
  std::vector<AlbedoCluster> clusters;  // by texel count, largest first (id = index)

  AlbedoStats stats;
};

// `view_counts`: keyframe samples per texel (0 = not observed); empty = all observed. Throws
// Error when the texture is empty or no texel is observed.
AlbedoResult EstimateAlbedo(const MeshColors& texture, const std::vector<int32_t>& view_counts,
                            const AlbedoOptions& options);

}  // namespace genscene::texturing
