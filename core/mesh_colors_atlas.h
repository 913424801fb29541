// Mesh Colors baked into a texture atlas, for formats and viewers that know only UV textures
// (glTF, OBJ/MTL): every face gets its own chart, so there is no parameterisation to compute and
// no seam handling beyond a gutter.
//
// Layout. A face of baked resolution r (its Mesh Colors resolution R, or R / 2^k after a
// downscale, see below) is a right isosceles triangle whose lattice point (i, j) (barycentrics
// (i/r, j/r), as in core/mesh_colors.h) lies exactly on the centre of texel (x0 + s i, y0 + s j):
// vertex 0 at the right angle, vertex 1 along x, vertex 2 along y, legs of r texel steps. So a
// face of resolution R (R + 1 samples per edge) gets R + 1 texels per leg (the texel density
// follows the Mesh Colors density), and bilinear sampling at a sample point returns that sample's
// texel alone.
// Two faces of the same r share one square cell of side S = r + 2g + 3 (g = gutter): face A in the
// lower-left half (s = +1, x0 = cell x + g), face B rotated by 180 degrees in the upper-right half
// (s = -1, x0 = cell x + S - 1 - g); between the charts of neighbouring cells lie 2g texels.
// Pairing halves the area that one triangle per square would take; a face left without a partner
// of its resolution has a cell of its own.
// Cells are packed in rows (shelves), largest r first, into an image of power-of-two width (so
// the u coordinates of texel centres are exact in float) and the height the rows need.
//
// Texels. Texels on the lattice get the Mesh Colors value of their sample (MeshColors::Linear at
// the lattice point, which is the sample itself; a coarser baked lattice reads every 2^k-th
// sample). The ring just past the long edge (i + j = r + 1) gets the linear extrapolation
// c(i, j-1) + c(i-1, j) - c(i-1, j-1), so that bilinear sampling anywhere in the sub-triangles
// along the long edge equals the Mesh Colors linear lookup there (in the 8-bit image, where the
// extrapolation stays within [0, 1]). Every other texel (the gutter, unused space) is filled by
// dilation: in order of distance to the filled texels, each takes the mean of its already filled
// 8-neighbours. Bilinear sampling inside a chart therefore reads only that chart's texels. Across
// a cell's diagonal lie three texel diagonals: A's extrapolated ring, one dilated from both
// charts, B's ring. The first mip level (2x2 means) keeps the charts apart across the 2g texels
// between cells; across the A/B diagonal and from the second level on, minified sampling blends
// neighbouring charts, as in any per-face atlas.
//
// What bilinear sampling cannot reproduce: inside the lattice, a texel square covers two Mesh
// Colors sub-triangles, which bilinear interpolation blends (a field linear over the face is
// exact; a field with a kink along the square's diagonal is smoothed there).
//
// Size cap. When the packed image would exceed max_size in width or height, every face's
// resolution is halved (at least 1) until it fits, with a warning; when even resolution 1 does
// not fit, Error. Colours: `linear` holds the baked linear RGB (the extrapolated ring, and the
// gutter dilated from it, may leave [0, 1]), `srgb8` the same clamped to [0, 1] and sRGB-encoded,
// 8 bits per channel (glTF base colour textures are sRGB).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/mesh_colors.h"

namespace genscene {

struct AtlasOptions {
  int gutter = 2;       // empty texels between a chart's legs and its cell border
  int max_size = 8192;  // largest width or height of the image, texels
};

// Where each face lies in the atlas (the same for every Mesh Colors baked with it).
struct AtlasLayout {
  int width = 0, height = 0;
  int downscale = 0;                    // every face's resolution was halved this many times
  std::vector<int> resolution;          // baked resolution r per face
  std::vector<Eigen::Vector2i> origin;  // texel of lattice point (0, 0) per face
  std::vector<int8_t> step;             // +1 (cell's lower-left chart) or -1 (upper-right)
  std::vector<std::string> warnings;    // the downscale, when there was one

  int num_faces() const { return static_cast<int>(resolution.size()); }
  // Texel coordinates (pixel centres at integers, x right, y down the image) of barycentric point
  // (b1, b2) of `face`.
  Eigen::Vector2d TexelPosition(int face, double b1, double b2) const;
  // Normalised texture coordinates of the same point, glTF convention: (0, 0) is the top-left
  // corner of the first texel, (1, 1) the bottom-right corner of the last.
  Eigen::Vector2f Uv(int face, double b1, double b2) const;
  // Per face corner (3 per face, in face order): the UVs of the face's vertices 0, 1, 2.
  std::vector<Eigen::Vector2f> CornerUvs() const;
};

// The layout for per-face resolutions `face_resolution` (powers of two, as in MeshColors). To bake
// several Mesh Colors of one mesh into one layout, pass the per-face maximum of their
// resolutions. Throws Error when the options are out of range or the faces do not fit max_size
// even at resolution 1.
AtlasLayout MakeAtlasLayout(const std::vector<int>& face_resolution,
                            const AtlasOptions& options = AtlasOptions());

struct AtlasImage {
  int width = 0, height = 0;
  std::vector<Eigen::Vector3f> linear;  // width * height, row-major from the top row
  std::vector<uint8_t> srgb8;           // width * height * 3, RGB, row-major from the top row
};

// Bakes `colors` into `layout` (see above). Throws Error when the face counts differ.
AtlasImage BakeAtlas(const AtlasLayout& layout, const MeshColors& colors);

}  // namespace genscene
