// The 256 marching-cubes cases, generated at start-up from one face rule instead of a hand-typed
// table, so that their consistency can be argued and tested.
//
// Cell layout. Corner c of the cell with lower corner p is p + (c & 1, (c >> 1) & 1, (c >> 2) & 1)
// (the same order as core's trilinear interpolation). Edge e = 4 * axis + k runs along `axis`
// from corner EdgeStart(e) to EdgeStart(e) + unit(axis); k's bit 0 is the offset along axis
// (axis + 1) % 3 and bit 1 the offset along (axis + 2) % 3. The cube index has bit c set when
// corner c is INSIDE (sdf < iso).
//
// Ambiguity convention. On every face, the edges whose ends differ are joined by segments; on an
// ambiguous face (two diagonal corners inside, the other two outside) the segments cut off the
// two inside corners, i.e. the outside corners are treated as connected through the face centre.
// The segments of the six faces form closed loops (each crossed edge lies on two faces), and each
// loop is triangulated as a fan. Because a face's segments depend on its four corner signs only,
// and two cells sharing a face see the same four signs, neighbouring cells always agree: the
// surface has no cracks. No interior tunnels are created (cases 4, 6, 7, 10, 12, 13 of Lorensen's
// list take the face-connected interpretation). Complementing all signs is NOT a symmetry of this
// rule, unlike the original Lorensen table (whose complementary cases are what caused its holes).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>

namespace genscene::meshing {

constexpr int kMaxCaseTriangles = 12;  // generous upper bound; the generated maximum is checked

struct CubeCase {
  int num_triangles = 0;
  // Cell edges (0..11) of each triangle, counter-clockwise seen from outside (positive sdf), so
  // that the face normal points toward positive sdf.
  std::array<std::array<uint8_t, 3>, kMaxCaseTriangles> triangles{};
};

// The case of one cube index; the table is built once, on first use (thread-safe). The 256 cases
// are contiguous: &CubeCaseOf(0) + i == &CubeCaseOf(i), so hot loops may index the table directly.
const CubeCase& CubeCaseOf(uint8_t cube_index);

// Offset of corner c (0..7) from the cell's lower corner.
inline Eigen::Vector3i CornerOffset(int c) {
  return Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1);
}

// Axis (0 = x, 1 = y, 2 = z) of cell edge e (0..11).
inline int EdgeAxis(int e) {
  return e / 4;
}

// Offset of the lower end of cell edge e from the cell's lower corner.
inline Eigen::Vector3i EdgeStart(int e) {
  const int axis = e / 4, k = e % 4;
  Eigen::Vector3i offset = Eigen::Vector3i::Zero();
  offset[(axis + 1) % 3] = k & 1;
  offset[(axis + 2) % 3] = (k >> 1) & 1;
  return offset;
}

// Corner index of a corner offset in {0, 1}^3.
inline int CornerIndex(const Eigen::Vector3i& offset) {
  return offset.x() + 2 * offset.y() + 4 * offset.z();
}

}  // namespace genscene::meshing
