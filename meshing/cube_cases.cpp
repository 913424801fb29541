#include "meshing/cube_cases.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <vector>

#include "core/check.h"

namespace genscene::meshing {

namespace {

// The cell edge joining two corners that differ in exactly one axis.
int EdgeBetween(int corner_a, int corner_b) {
  const Eigen::Vector3i a = CornerOffset(corner_a), b = CornerOffset(corner_b);
  const Eigen::Vector3i lower = a.cwiseMin(b);
  const Eigen::Vector3i diff = (a - b).cwiseAbs();
  GS_CHECK_EQ(diff.sum(), 1);
  const int axis = diff.x() ? 0 : (diff.y() ? 1 : 2);
  const int k = lower[(axis + 1) % 3] + 2 * lower[(axis + 2) % 3];
  return 4 * axis + k;
}

// Segments on the six faces for one cube index: partner[e] lists the (up to two) edges that edge
// e is joined to, one per face it lies on.
std::array<std::vector<int>, 12> FaceSegments(int cube_index) {
  std::array<std::vector<int>, 12> partner;
  auto inside = [&](int c) { return ((cube_index >> c) & 1) != 0; };
  auto join = [&](int e0, int e1) {
    partner[e0].push_back(e1);
    partner[e1].push_back(e0);
  };
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      // The face's corners in cyclic order in the plane of the two other axes.
      const int b = (axis + 1) % 3, c = (axis + 2) % 3;
      int q[4];
      const int cycle[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
      for (int i = 0; i < 4; ++i) {
        Eigen::Vector3i offset = Eigen::Vector3i::Zero();
        offset[axis] = side;
        offset[b] = cycle[i][0];
        offset[c] = cycle[i][1];
        q[i] = CornerIndex(offset);
      }
      int edge[4];  // edge[i] joins q[i] and q[i + 1]
      std::vector<int> crossed;
      for (int i = 0; i < 4; ++i) {
        edge[i] = EdgeBetween(q[i], q[(i + 1) % 4]);
        if (inside(q[i]) != inside(q[(i + 1) % 4])) crossed.push_back(i);
      }
      if (crossed.size() == 2) {
        join(edge[crossed[0]], edge[crossed[1]]);
      } else if (crossed.size() == 4) {
        // Ambiguous face: cut off the two inside corners (outside connected through the centre).
        if (inside(q[0])) {
          join(edge[3], edge[0]);  // around q0
          join(edge[1], edge[2]);  // around q2
        } else {
          join(edge[0], edge[1]);  // around q1
          join(edge[2], edge[3]);  // around q3
        }
      }
    }
  }
  return partner;
}

// True when cell edges a and b lie on a common face of the cell (face id = 2 * axis + side).
bool ShareFace(int a, int b) {
  auto faces = [](int e) {
    const int axis = EdgeAxis(e), u = (axis + 1) % 3, w = (axis + 2) % 3;
    const Eigen::Vector3i start = EdgeStart(e);
    return std::array<int, 2>{2 * u + start[u], 2 * w + start[w]};
  };
  const auto fa = faces(a), fb = faces(b);
  return fa[0] == fb[0] || fa[0] == fb[1] || fa[1] == fb[0] || fa[1] == fb[1];
}

// True when no fan diagonal from loop[apex] joins two edges of one face.
bool DiagonalsLeaveFaces(const std::vector<int>& loop, size_t apex) {
  const size_t n = loop.size();
  for (size_t i = 2; i + 1 < n; ++i) {
    if (ShareFace(loop[apex], loop[(apex + i) % n])) return false;
  }
  return true;
}

CubeCase MakeCase(int cube_index) {
  const std::array<std::vector<int>, 12> partner = FaceSegments(cube_index);
  auto inside = [&](int c) { return ((cube_index >> c) & 1) != 0; };
  CubeCase result;
  bool visited[12] = {};
  for (int start = 0; start < 12; ++start) {
    if (visited[start] || partner[start].empty()) continue;
    GS_CHECK_EQ(partner[start].size(), 2u);  // a crossed edge lies on two faces
    // Walk the loop through the segments.
    std::vector<int> loop = {start};
    visited[start] = true;
    int previous = start, current = partner[start][0];
    while (current != start) {
      GS_CHECK(!visited[current]);
      visited[current] = true;
      loop.push_back(current);
      const int next = partner[current][0] == previous ? partner[current][1] : partner[current][0];
      previous = current;
      current = next;
    }
    // Orient the loop: its vector area (edge midpoints) must point outside, i.e. along the sum
    // of the crossed edges' inside -> outside directions.
    Eigen::Vector3d area = Eigen::Vector3d::Zero(), outward = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < loop.size(); ++i) {
      auto midpoint = [](int e) {
        Eigen::Vector3d m = EdgeStart(e).cast<double>();
        m[EdgeAxis(e)] += 0.5;
        return m;
      };
      area += midpoint(loop[i]).cross(midpoint(loop[(i + 1) % loop.size()]));
      const int e = loop[i];
      const bool start_inside = inside(CornerIndex(EdgeStart(e)));
      outward[EdgeAxis(e)] += start_inside ? 1.0 : -1.0;
    }
    const double orientation = area.dot(outward);
    GS_CHECK_NE(orientation, 0.0);
    if (orientation < 0) std::reverse(loop.begin() + 1, loop.end());
    // Fan triangulation from the first apex whose diagonals all cross the cell's interior. A
    // diagonal lying in a cell face could be created by the neighbour across that face too, and
    // the edge would then have four triangles.
    const size_t n = loop.size();
    size_t apex = 0;
    while (apex < n && !DiagonalsLeaveFaces(loop, apex)) ++apex;
    GS_CHECK_LT(apex, n);
    for (size_t i = 1; i + 1 < n; ++i) {
      GS_CHECK_LT(result.num_triangles, kMaxCaseTriangles);
      result.triangles[result.num_triangles++] = {static_cast<uint8_t>(loop[apex]),
                                                  static_cast<uint8_t>(loop[(apex + i) % n]),
                                                  static_cast<uint8_t>(loop[(apex + i + 1) % n])};
    }
  }
  return result;
}

}  // namespace

const CubeCase& CubeCaseOf(uint8_t cube_index) {
  static const std::array<CubeCase, 256> table = [] {
    std::array<CubeCase, 256> t;
    for (int i = 0; i < 256; ++i) t[i] = MakeCase(i);
    return t;
  }();
  return table[cube_index];
}

}  // namespace genscene::meshing
