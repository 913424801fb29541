// The fold guard of vertex refinement (HoldFoldingVertices) and the count of flipped faces that
// judges a refinement (FlippedFaces); see vertex_refinement.h.
#include "core/check.h"
#include "inverse/refine/vertex_refinement.h"

namespace genscene::inverse {

namespace {

// (x_b - x_a) x (x_c - x_a) for face f = (a, b, c): its normal, twice its area long.
Eigen::Vector3d FaceNormalAt(const Eigen::VectorXd& x, const Eigen::Vector3i& f) {
  const Eigen::Vector3d a = x.segment<3>(3 * f[0]), b = x.segment<3>(3 * f[1]),
                        c = x.segment<3>(3 * f[2]);
  return (b - a).cross(c - a);
}

}  // namespace

// A face is folded at `at` when n0 . n <= 0 or n = 0 (n0, n its normals at `start` and `at`).
// Each pass holds the vertices of the faces the step folds; holding them can fold a neighbour
// that the held vertices' step kept flat, hence the passes.
int HoldFoldingVertices(const std::vector<Eigen::Vector3i>& faces, const Eigen::VectorXd& start,
                        const Eigen::VectorXd& x, Eigen::VectorXd* step) {
  const auto folded = [&](const Eigen::VectorXd& at, const Eigen::Vector3i& f) {
    const Eigen::Vector3d n0 = FaceNormalAt(start, f), n = FaceNormalAt(at, f);
    return n0.squaredNorm() > 0.0 && (n.squaredNorm() == 0.0 || n0.dot(n) <= 0.0);
  };
  std::vector<bool> held(static_cast<size_t>(x.size() / 3), false);
  int count = 0;
  for (int pass = 0; pass < 100; ++pass) {
    const Eigen::VectorXd trial = x + *step;
    bool any = false;
    for (const Eigen::Vector3i& f : faces) {
      if (!folded(trial, f) || folded(x, f)) continue;
      for (int k = 0; k < 3; ++k) {
        if (held[f[k]]) continue;
        held[f[k]] = true;
        step->segment<3>(3 * f[k]).setZero();
        ++count;
        any = true;
      }
    }
    if (!any) break;
  }
  return count;
}

int FlippedFaces(const TriangleMesh& before, const TriangleMesh& after) {
  GS_CHECK_EQ(before.faces.size(), after.faces.size());
  int flipped = 0;
  for (size_t f = 0; f < before.faces.size(); ++f) {
    const Eigen::Vector3f a = before.FaceNormalScaled(f), b = after.FaceNormalScaled(f);
    if (b.squaredNorm() == 0.0f || a.dot(b) <= 0.0f) ++flipped;
  }
  return flipped;
}

}  // namespace genscene::inverse
