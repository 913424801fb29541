#include "inverse/refine/vertex_refinement.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>

#include "core/check.h"
#include "core/options.h"
#include "core/parallel.h"
#include "core/rng.h"

namespace genscene::inverse {
using namespace genscene::render;  // the renderer the inverse stages are built on

void RefineOptions::Validate() const {
  RequireRange("iterations", iterations, 0, 1000);
  paths.Validate();
  RequireRange("pixels_per_view", pixels_per_view, 0, 1 << 26);
  const auto require_depth = [](const char* name, int depth) {
    if (depth == 0 || depth < -1)
      throw Error(Format("option ", name, " = ", depth, " must be -1 or >= 1"));
  };
  require_depth("jacobian_max_depth", jacobian_max_depth);
  RequireRange("noise", noise, 1e-6, 10.0);
  RequireRange("prior_sigma", prior_sigma, 1e-9, 1e6);
  if (prior_tangent_sigma != 0.0)
    RequireRange("prior_tangent_sigma", prior_tangent_sigma, 1e-9, 1e6);
  if (relax_sigma != 0.0) RequireRange("relax_sigma", relax_sigma, 1e-9, 1e6);
  if (smooth_sigma != 0.0) RequireRange("smooth_sigma", smooth_sigma, 1e-9, 1e6);
  RequireRange("damping", damping, 0.0, 1e12);
  RequireRange("max_step", max_step, 1e-6, 100.0);
  RequireRange("max_retries", max_retries, 0, 100);
  RequireRange("average_after", average_after, 0, 1000);
  RequireRange("tolerance", tolerance, 0.0, 1.0);
  RequireRange("robust", robust, 0.0, 1e6);
  RequireRange("prior_robust", prior_robust, 0.0, 1e6);
  RequireRange("edge_margin", edge_margin, 0, 100);
  RequireRange("direct_max_vertices", direct_max_vertices, 0, 1 << 30);
}

namespace {

struct PixelRef {
  int target = 0, u = 0, v = 0;
};

// The sampled pixels: every pixel, or `per_view` drawn without replacement per view, leaving out
// pixels within `margin` pixels of a silhouette (where the object seen through the pixel centre
// changes, in the starting geometry): their residuals come from visibility, which the derivatives
// do not see, and would pull the vertices the wrong way.
// `ids` is a plain tracer of the tracer's scene (its object buffer gives what each pixel sees).
std::vector<PixelRef> SamplePixels(const DifferentiablePathTracer& tracer, const PathTracer& ids,
                                   const std::vector<PosedImage>& targets, int per_view, int margin,
                                   bool refined_only, uint64_t seed) {
  std::vector<PixelRef> pixels;
  RenderOptions one;
  one.spp = 1;
  for (size_t t = 0; t < targets.size(); ++t) {
    const int w = targets[t].image.width(), h = targets[t].image.height();
    const Image<int> object = ids.Render(targets[t].view, one, 1).object;
    const auto near_edge = [&](int u, int v) {
      for (int dv = -margin; dv <= margin; ++dv) {
        for (int du = -margin; du <= margin; ++du) {
          const int x = std::clamp(u + du, 0, w - 1), y = std::clamp(v + dv, 0, h - 1);
          if (object(x, y) != object(u, v)) return true;
        }
      }
      return false;
    };
    std::vector<int> order;
    for (int p = 0; p < w * h; ++p) {
      if (refined_only) {
        const int m = object(p % w, p / w);
        if (m < 0 || tracer.ParameterVertex(m, 0) < 0) continue;
      }
      if (margin <= 0 || !near_edge(p % w, p / w)) order.push_back(p);
    }
    if (per_view > 0 && per_view < static_cast<int>(order.size())) {
      CounterRng rng(seed, 0x5e1ec7, t);
      for (int i = 0; i < per_view; ++i) {  // partial Fisher-Yates
        std::swap(order[i], order[i + rng.UniformInt(static_cast<uint32_t>(order.size() - i))]);
      }
      order.resize(per_view);
      std::sort(order.begin(), order.end());
    }
    for (int p : order) pixels.push_back({static_cast<int>(t), p % w, p / w});
  }
  if (pixels.empty())
    throw Error(
        "vertex refinement: no pixels to fit (no pixel sees a refined mesh away from a "
        "silhouette)");
  return pixels;
}

// Huber's loss of a residual r (in noise units) with threshold k: r^2 / 2 inside, linear outside,
// so that pixels whose visibility differs from the reference (a silhouette or shadow edge in the
// wrong place, residuals of many noise units that no smooth move explains) do not dominate the
// step. k = 0: plain least squares.
double HuberCost(double r, double k) {
  const double a = std::abs(r);
  return k <= 0.0 || a <= k ? 0.5 * r * r : k * (a - 0.5 * k);
}
// IRLS weight of a residual under Huber's loss: the normal equations use w J^T J and w J^T r.
double HuberWeight(double r, double k) {
  const double a = std::abs(r);
  return k <= 0.0 || a <= k ? 1.0 : k / a;
}

// RMS of the reference over the sampled pixels and channels (> 0).
double ReferenceRms(const std::vector<PosedImage>& targets, const std::vector<PixelRef>& pixels) {
  double sum = 0.0;
  for (const PixelRef& p : pixels)
    sum += targets[p.target].image(p.u, p.v).cast<double>().squaredNorm();
  const double rms = std::sqrt(sum / (3.0 * pixels.size()));
  if (!(rms > 0.0)) throw Error("vertex refinement: the reference images are black where sampled");
  return rms;
}

// One trace of every sampled pixel: residual rows (r_c = (I_c - I*_c) / (noise s), with their
// derivatives when asked) and the data cost.
struct Evaluation {
  std::vector<DualRgb> rows;  // per pixel
  double data_cost = 0.0;
  double sum_squared = 0.0;  // of I - I*, for the RMSE
  RayCounts rays;
};

Evaluation Evaluate(const DifferentiablePathTracer& tracer, const std::vector<PosedImage>& targets,
                    const std::vector<PixelRef>& pixels, const RefineOptions& options,
                    uint64_t seed, double scale, bool derivatives) {
  Evaluation e;
  e.rows.resize(pixels.size());
  std::vector<RayCounts> rays(pixels.size());
  const RenderOptions render = options.paths;
  RenderOptions jacobian = render;
  if (options.jacobian_max_depth > 0 &&
      (render.max_depth < 0 || options.jacobian_max_depth < render.max_depth)) {
    jacobian.max_depth = options.jacobian_max_depth;  // never deeper than the residuals' paths
  }
  const bool separate = derivatives && jacobian.max_depth != render.max_depth;
  ParallelFor(
      0, pixels.size(),
      [&](size_t i) {
        const PixelRef& p = pixels[i];
        const PosedImage& t = targets[p.target];
        DualRgb row =
            tracer.Pixel(t.view, p.u, p.v, render, seed, derivatives && !separate, &rays[i]);
        if (separate) {  // the values of the full paths, the derivatives of the short ones
          const DualRgb d = tracer.Pixel(t.view, p.u, p.v, jacobian, seed, true, &rays[i]);
          for (int c = 0; c < 3; ++c)
            row[c] = SparseDual::Linear(1.0, d[c], 0.0, SparseDual(), row[c].value());
        }
        for (int c = 0; c < 3; ++c)
          row[c] = (std::move(row[c]) - t.image(p.u, p.v)[c]) * (1.0 / scale);
        e.rows[i] = std::move(row);
      },
      8);
  for (size_t i = 0; i < pixels.size(); ++i) {  // fixed order: the same sums with any thread count
    for (int c = 0; c < 3; ++c) {
      const double r = e.rows[i][c].value();
      e.sum_squared += r * r * scale * scale;
      e.data_cost += HuberCost(r, options.robust);
    }
    e.rays.intersect += rays[i].intersect;
    e.rays.occluded += rays[i].occluded;
  }
  return e;
}

// The normal equations of the data term, J^T W J and J^T W r. Small problems keep J^T W J as 3 x 3
// blocks per pair of vertices for a sparse Cholesky factorisation; large ones keep the Jacobian
// rows themselves (compressed) for conjugate gradients, which only need products J^T W J v: a
// path-traced pixel depends on vertices all over the scene, so the factor of a large J^T W J
// fills in (87k vertices: minutes and gigabytes), while a product costs O(non-zeros).
struct NormalEquations {
  bool blocks_kept = false;
  std::map<std::pair<int, int>, Eigen::Matrix3d> blocks;  // (i, j) with i <= j, when kept
  std::vector<Eigen::Matrix3d> diagonal;                  // (i, i) blocks, always
  std::vector<size_t> row_start;                          // compressed rows, when not kept
  std::vector<int> row_vertex;
  std::vector<Eigen::Vector3d> row_d;
  std::vector<double> row_weight;
  Eigen::VectorXd gradient;
  double nonzeros = 0.0;  // scalar Jacobian entries

  // out = J^T W J v
  void Multiply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const {
    out->setZero(v.size());
    for (size_t r = 0; r + 1 < row_start.size(); ++r) {
      double s = 0.0;
      for (size_t k = row_start[r]; k < row_start[r + 1]; ++k)
        s += row_d[k].dot(v.segment<3>(3 * row_vertex[k]));
      s *= row_weight[r];
      for (size_t k = row_start[r]; k < row_start[r + 1]; ++k)
        out->segment<3>(3 * row_vertex[k]) += s * row_d[k];
    }
  }
};

NormalEquations Assemble(const Evaluation& e, int vertices, double robust, bool keep_blocks) {
  NormalEquations n;
  n.blocks_kept = keep_blocks;
  n.gradient = Eigen::VectorXd::Zero(3 * vertices);
  n.diagonal.assign(vertices, Eigen::Matrix3d::Zero());
  if (!keep_blocks) n.row_start.push_back(0);
  for (const DualRgb& row : e.rows) {
    for (const SparseDual& r : row) {
      const auto& d = r.partials();
      const double w = HuberWeight(r.value(), robust);
      n.nonzeros += 3.0 * d.size();
      for (size_t a = 0; a < d.size(); ++a) {
        n.gradient.segment<3>(3 * d[a].vertex) += (w * r.value()) * d[a].d;
        n.diagonal[d[a].vertex] += w * d[a].d * d[a].d.transpose();
        if (keep_blocks) {
          for (size_t b = a + 1; b < d.size(); ++b) {
            auto [it, fresh] =
                n.blocks.try_emplace({d[a].vertex, d[b].vertex}, Eigen::Matrix3d::Zero());
            it->second += w * d[a].d * d[b].d.transpose();
          }
        } else {
          n.row_vertex.push_back(d[a].vertex);
          n.row_d.push_back(d[a].d);
        }
      }
      if (!keep_blocks) {
        n.row_weight.push_back(w);
        n.row_start.push_back(n.row_vertex.size());
      }
    }
  }
  return n;
}

// Solves (H + mu diag(H)) dx = -g with H = J^T W J + P + Q and g = J^T W r + the prior's gradient,
// P the prior's 3 x 3 blocks (PriorBlocks), Q the relaxation's matrix (Relaxation; may be
// empty):
// by sparse Cholesky (Eigen's SimplicialLDLT) when the blocks are kept, else by conjugate
// gradients preconditioned with the inverse 3 x 3 diagonal blocks, to a relative residual of
// 1e-10 (at most 1000 iterations; serial, so the same with any thread count).
Eigen::VectorXd SolveStep(const NormalEquations& n, const Eigen::VectorXd& prior_gradient,
                          const std::vector<Eigen::Matrix3d>& prior,
                          const Eigen::SparseMatrix<double>& coupling, double mu) {
  const int size = static_cast<int>(n.gradient.size());
  const int vertices = size / 3;
  const bool coupled = coupling.nonZeros() > 0;
  Eigen::VectorXd diagonal(size);  // diag(H)
  for (int i = 0; i < vertices; ++i)
    diagonal.segment<3>(3 * i) = (n.diagonal[i] + prior[i]).diagonal();
  if (coupled) diagonal += coupling.diagonal();
  const Eigen::VectorXd rhs = -(n.gradient + prior_gradient);
  Eigen::VectorXd step;
  if (n.blocks_kept) {
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(n.blocks.size() * 18 + 9 * vertices);
    for (int i = 0; i < vertices; ++i) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
          const double value =
              r == c ? diagonal[3 * i + r] * (1.0 + mu) : n.diagonal[i](r, c) + prior[i](r, c);
          triplets.emplace_back(3 * i + r, 3 * i + c, value);
        }
      }
    }
    for (int c = 0; coupled && c < coupling.outerSize(); ++c) {  // its diagonal is in `diagonal`
      for (Eigen::SparseMatrix<double>::InnerIterator e(coupling, c); e; ++e) {
        if (e.row() != e.col())
          triplets.emplace_back(static_cast<int>(e.row()), static_cast<int>(e.col()), e.value());
      }
    }
    for (const auto& [ij, block] : n.blocks) {
      const auto [i, j] = ij;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
          triplets.emplace_back(3 * i + r, 3 * j + c, block(r, c));
          triplets.emplace_back(3 * j + c, 3 * i + r, block(r, c));
        }
      }
    }
    Eigen::SparseMatrix<double> h(size, size);
    h.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(h);
    if (solver.info() != Eigen::Success)
      throw Error("vertex refinement: the normal equations could not be factorised");
    step = solver.solve(rhs);
  } else {
    std::vector<Eigen::Matrix3d> preconditioner(vertices);
    for (int i = 0; i < vertices; ++i) {
      Eigen::Matrix3d m = n.diagonal[i] + prior[i];
      for (int r = 0; coupled && r < 3; ++r) {
        for (int c = 0; c < 3; ++c) m(r, c) += coupling.coeff(3 * i + r, 3 * i + c);
      }
      m.diagonal() = diagonal.segment<3>(3 * i) * (1.0 + mu);
      preconditioner[i] = m.inverse();
    }
    const auto apply = [&](const Eigen::VectorXd& v, Eigen::VectorXd* out) {
      n.Multiply(v, out);
      for (int i = 0; i < vertices; ++i) out->segment<3>(3 * i) += prior[i] * v.segment<3>(3 * i);
      if (coupled) *out += coupling * v;
      *out += mu * diagonal.cwiseProduct(v);
    };
    const auto precondition = [&](const Eigen::VectorXd& r) {
      Eigen::VectorXd z(size);
      for (int i = 0; i < vertices; ++i)
        z.segment<3>(3 * i) = preconditioner[i] * r.segment<3>(3 * i);
      return z;
    };
    step = Eigen::VectorXd::Zero(size);
    Eigen::VectorXd residual = rhs, z = precondition(residual), direction = z, product(size);
    double rz = residual.dot(z);
    const double stop = 1e-20 * rhs.squaredNorm();
    for (int k = 0; k < 1000 && residual.squaredNorm() > stop; ++k) {
      apply(direction, &product);
      const double curvature = direction.dot(product);
      if (!(curvature > 0.0)) break;
      const double alpha = rz / curvature;
      step += alpha * direction;
      residual -= alpha * product;
      z = precondition(residual);
      const double rz_next = residual.dot(z);
      direction = z + (rz_next / rz) * direction;
      rz = rz_next;
    }
  }
  if (!step.allFinite()) throw Error("vertex refinement: the step is not finite");
  return step;
}

// Mean edge length of the refined meshes (each edge counted once per face side).
double MeanEdgeLength(const DifferentiablePathTracer& tracer) {
  double sum = 0.0;
  size_t count = 0;
  for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
    if (tracer.ParameterVertex(static_cast<int>(m), 0) < 0) continue;
    const TriangleMesh& mesh = tracer.scene().meshes[m].mesh;
    for (const Eigen::Vector3i& f : mesh.faces) {
      for (int k = 0; k < 3; ++k)
        sum += (mesh.vertices[f[k]] - mesh.vertices[f[(k + 1) % 3]]).norm(), ++count;
    }
  }
  return count > 0 ? sum / count : 1.0;
}

// The faces of the refined meshes in parameter-vertex indices (3 v per face: x at 3 v).
std::vector<Eigen::Vector3i> ParameterFaces(const DifferentiablePathTracer& tracer) {
  std::vector<Eigen::Vector3i> faces;
  for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
    const int mesh = static_cast<int>(m);
    if (tracer.ParameterVertex(mesh, 0) < 0) continue;
    for (const Eigen::Vector3i& f : tracer.scene().meshes[m].mesh.faces) {
      faces.emplace_back(tracer.ParameterVertex(mesh, f[0]), tracer.ParameterVertex(mesh, f[1]),
                         tracer.ParameterVertex(mesh, f[2]));
    }
  }
  return faces;
}

Eigen::Vector3d FaceNormalAt(const Eigen::VectorXd& x, const Eigen::Vector3i& f) {
  const Eigen::Vector3d a = x.segment<3>(3 * f[0]), b = x.segment<3>(3 * f[1]),
                        c = x.segment<3>(3 * f[2]);
  return (b - a).cross(c - a);
}

// The prior's information matrix per parameter vertex: 1 / sigma_n^2 along the vertex's starting
// normal (area-weighted), 1 / sigma_t^2 across it (by default the same: the relaxation term, not
// this prior, keeps the vertices from sliding across the surface, and a firm prior across the
// starting normal of a noisy mesh, whose normals are tilted, also holds the moves along the true
// normal that the images ask for). Vertices without a normal (no face) get the isotropic 1 /
// sigma_n^2.
std::vector<Eigen::Matrix3d> PriorBlocks(const DifferentiablePathTracer& tracer,
                                         const RefineOptions& options) {
  const double wn = 1.0 / (options.prior_sigma * options.prior_sigma);
  const double sigma_t =
      options.prior_tangent_sigma > 0.0 ? options.prior_tangent_sigma : options.prior_sigma;
  const double wt = 1.0 / (sigma_t * sigma_t);
  std::vector<Eigen::Matrix3d> blocks(tracer.VertexCount(), wn * Eigen::Matrix3d::Identity());
  if (wt == wn) return blocks;
  for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
    if (tracer.ParameterVertex(static_cast<int>(m), 0) < 0) continue;
    TriangleMesh mesh = tracer.scene().meshes[m].mesh;
    mesh.ComputeVertexNormals();
    for (size_t v = 0; v < mesh.vertices.size(); ++v) {
      const Eigen::Vector3d n = mesh.normals[v].cast<double>();
      if (n.squaredNorm() < 0.5) continue;  // no incident face
      blocks[tracer.ParameterVertex(static_cast<int>(m), static_cast<int>(v))] =
          wt * Eigen::Matrix3d::Identity() + (wn - wt) * n * n.transpose();
    }
  }
  return blocks;
}

// The relaxation term's matrix Q = A^T A / relax_sigma^2, so that the term is x^T Q x / 2. A has
// three rows per refined vertex inside its mesh (not on a boundary, where the one-ring's centroid
// lies inside the surface): T_i (x_i - the mean of x_i's neighbours), T_i = I - n_i n_i^T the
// projection across the surface at the vertex's area-weighted normal at `x` (held for the
// iteration, so the term is quadratic). It is the vertex's offset across the surface from the
// centroid of its one-ring: zero where the vertices are evenly spread, and blind to moves along the
// normal, which the images see. The images barely see a vertex slide across a smooth surface, so
// noise across the surface in the starting positions stays where the prior on them holds it; this
// term spreads the vertices evenly instead (tangential relaxation, as in isotropic remeshing).
// With smooth_sigma, Q also holds the bending term B^T B / smooth_sigma^2 (see Matrix): a change of
// curvature from a vertex to its ring, one row per vertex whose ring has rows too.
// The connectivity (one-rings, boundaries) is found once; only the normals change with x.
class Relaxation {
 public:
  Relaxation(const DifferentiablePathTracer& tracer, double sigma, double smooth_sigma)
      : size_(3 * tracer.VertexCount()), sigma_(sigma), smooth_sigma_(smooth_sigma) {
    if (sigma <= 0.0 && smooth_sigma <= 0.0) return;
    for (size_t m = 0; m < tracer.scene().meshes.size(); ++m) {
      const int mesh = static_cast<int>(m);
      if (tracer.ParameterVertex(mesh, 0) < 0) continue;
      const TriangleMesh& triangles = tracer.scene().meshes[m].mesh;
      const size_t n = triangles.vertices.size();
      std::vector<std::vector<int>> ring(n);
      std::map<std::pair<int, int>, int> edges;  // faces per undirected edge
      for (const Eigen::Vector3i& f : triangles.faces) {
        Eigen::Vector3i face;
        for (int k = 0; k < 3; ++k) {
          const int a = f[k], b = f[(k + 1) % 3];
          ring[a].push_back(b), ring[b].push_back(a);
          ++edges[{std::min(a, b), std::max(a, b)}];
          face[k] = tracer.ParameterVertex(mesh, a);
        }
        faces_.push_back(face);
      }
      std::vector<bool> boundary(n, false);
      for (const auto& [edge, faces] : edges) {
        if (faces != 2) boundary[edge.first] = boundary[edge.second] = true;
      }
      for (size_t v = 0; v < n; ++v) {
        std::sort(ring[v].begin(), ring[v].end());
        ring[v].erase(std::unique(ring[v].begin(), ring[v].end()), ring[v].end());
        if (boundary[v] || ring[v].empty()) continue;
        Row row{tracer.ParameterVertex(mesh, static_cast<int>(v)), {}, {}};
        for (int j : ring[v]) row.ring.push_back(tracer.ParameterVertex(mesh, j));
        rows_.push_back(std::move(row));
      }
    }
    std::vector<int> row_of(tracer.VertexCount(), -1);
    for (size_t r = 0; r < rows_.size(); ++r) row_of[rows_[r].vertex] = static_cast<int>(r);
    for (Row& row : rows_) {  // the bending row needs every neighbour's offset
      for (int j : row.ring) {
        if (row_of[j] < 0) {
          row.ring_rows.clear();
          break;
        }
        row.ring_rows.push_back(row_of[j]);
      }
    }
  }

  // Q at the parameter vectors `x`; empty when relax_sigma and smooth_sigma are 0.
  Eigen::SparseMatrix<double> Matrix(const Eigen::VectorXd& x) const {
    Eigen::SparseMatrix<double> q(size_, size_);
    if (sigma_ <= 0.0 && smooth_sigma_ <= 0.0) return q;
    std::vector<Eigen::Vector3d> normal(size_ / 3, Eigen::Vector3d::Zero());
    for (const Eigen::Vector3i& f : faces_) {
      const auto at = [&](int k) -> Eigen::Vector3d { return x.segment<3>(3 * f[k]); };
      const Eigen::Vector3d area = (at(1) - at(0)).cross(at(2) - at(0));  // twice the area
      for (int k = 0; k < 3; ++k) normal[f[k]] += area;
    }
    std::vector<Eigen::Vector3d> unit(rows_.size(), Eigen::Vector3d::Zero());  // 0: no normal
    for (size_t r = 0; r < rows_.size(); ++r) {
      if (normal[rows_[r].vertex].norm() > 0.0) unit[r] = normal[rows_[r].vertex].normalized();
    }
    if (sigma_ > 0.0) {
      std::vector<Eigen::Triplet<double>> entries;
      for (size_t r = 0; r < rows_.size(); ++r) {
        const Row& row = rows_[r];
        if (unit[r].isZero()) continue;
        const Eigen::Matrix3d t = Eigen::Matrix3d::Identity() - unit[r] * unit[r].transpose();
        const auto put = [&](int vertex, double scale) {
          for (int i = 0; i < 3; ++i) {
            for (int c = 0; c < 3; ++c)
              entries.emplace_back(3 * row.vertex + i, 3 * vertex + c, scale * t(i, c));
          }
        };
        put(row.vertex, 1.0);
        for (int j : row.ring) put(j, -1.0 / row.ring.size());
      }
      Eigen::SparseMatrix<double> a(size_, size_);
      a.setFromTriplets(entries.begin(), entries.end());
      q = (a.transpose() * a) / (sigma_ * sigma_);
    }
    if (smooth_sigma_ > 0.0) {
      // Row r of B: k_r - the mean of k over its ring, k_r = h_r / l_r * l, where h_r = n_r . (x_r
      // - c_r) is the vertex's offset along its normal from its one-ring's centroid (the umbrella
      // Laplacian along the normal), l_r the mean squared length of its edges and l the mean of l_r
      // over the vertices. h_r / l_r is half the mean curvature wherever the ring lies on a sphere
      // (a neighbour at distance d is d^2 / 2R below the tangent plane), whatever the valence and
      // the edge lengths, so a sphere or a plane bends at no cost; h_r alone differs by 19 %
      // between the icosphere's vertices of valence 5 and 6, which this term would then flatten.
      std::vector<double> spread(rows_.size(), 0.0);  // l_r
      double mean_spread = 0.0;
      for (size_t r = 0; r < rows_.size(); ++r) {
        const Eigen::Vector3d at = x.segment<3>(3 * rows_[r].vertex);
        for (int j : rows_[r].ring) spread[r] += (x.segment<3>(3 * j) - at).squaredNorm();
        spread[r] /= rows_[r].ring.size();
        mean_spread += spread[r] / rows_.size();
      }
      std::vector<Eigen::Triplet<double>> entries;
      int rows = 0;
      for (size_t r = 0; r < rows_.size(); ++r) {
        const Row& row = rows_[r];
        if (row.ring_rows.empty() || unit[r].isZero() || !(spread[r] > 0.0)) continue;
        bool complete = true;
        for (int k : row.ring_rows) complete = complete && !unit[k].isZero() && spread[k] > 0.0;
        if (!complete) continue;
        const auto put_h = [&](int k, double scale) {  // scale * k_k
          const Row& of = rows_[k];
          const Eigen::Vector3d n = unit[k] * (scale * mean_spread / spread[k]);
          for (int c = 0; c < 3; ++c) {
            entries.emplace_back(rows, 3 * of.vertex + c, n[c]);
            for (int j : of.ring) entries.emplace_back(rows, 3 * j + c, -n[c] / of.ring.size());
          }
        };
        put_h(static_cast<int>(r), 1.0);
        for (int k : row.ring_rows) put_h(k, -1.0 / row.ring_rows.size());
        ++rows;
      }
      Eigen::SparseMatrix<double> b(rows, size_);
      b.setFromTriplets(entries.begin(), entries.end());
      const Eigen::SparseMatrix<double> bend =
          (b.transpose() * b) / (smooth_sigma_ * smooth_sigma_);
      q = sigma_ > 0.0 ? Eigen::SparseMatrix<double>(q + bend) : bend;
    }
    q.prune(0.0);
    return q;
  }

 private:
  struct Row {
    int vertex;                  // parameter vertex
    std::vector<int> ring;       // its neighbours' parameter vertices
    std::vector<int> ring_rows;  // their rows (empty when a neighbour has none: no bending row)
  };
  int size_;
  double sigma_, smooth_sigma_;
  std::vector<Eigen::Vector3i> faces_;  // of the refined meshes, as parameter vertices
  std::vector<Row> rows_;               // the vertices inside their mesh
};

// A prior this many times the usual one holds a vertex in place (its steps come out ~1e-10 of
// the others') without taking it out of the linear system.
constexpr double kHeld = 1e10;

// The vertices that a sampled pixel sees directly: those the shading of its pixel-centre ray's
// first hit depends on (the hit triangle's vertices and, with smooth normals, their one-rings,
// whose faces make the vertex normals). The others show only through indirect light, whose
// derivatives are mostly Monte Carlo noise. Found geometrically, not from a trace's derivatives:
// a vertex in shadow or lit only by a few light samples must not be held or freed by chance
// (a 1-sample trace left the Cycles dent held on some seeds).
// `rays` is a plain tracer of the tracer's scene.
std::vector<bool> SeenVertices(const DifferentiablePathTracer& tracer, const PathTracer& rays,
                               const std::vector<PosedImage>& targets,
                               const std::vector<PixelRef>& pixels) {
  const Scene& scene = tracer.scene();
  std::vector<std::vector<std::vector<int>>> incident(
      scene.meshes.size());  // mesh -> vertex -> faces
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    if (tracer.ParameterVertex(static_cast<int>(m), 0) < 0) continue;
    const TriangleMesh& mesh = scene.meshes[m].mesh;
    incident[m].resize(mesh.vertices.size());
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      for (int k = 0; k < 3; ++k) incident[m][mesh.faces[f][k]].push_back(static_cast<int>(f));
    }
  }
  std::vector<bool> seen(tracer.VertexCount(), false);
  for (const PixelRef& p : pixels) {  // one ray per pixel: cheap, serial
    const auto hit = rays.PixelCentreHit(targets[p.target].view, p.u, p.v);
    if (!hit || incident[hit->mesh].empty()) continue;
    const TriangleMesh& mesh = scene.meshes[hit->mesh].mesh;
    const auto mark = [&](int v) { seen[tracer.ParameterVertex(hit->mesh, v)] = true; };
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.faces[hit->face][k];
      mark(v);
      if (!scene.meshes[hit->mesh].smooth_shading) continue;
      for (int f : incident[hit->mesh][v]) {
        for (int j = 0; j < 3; ++j) mark(mesh.faces[f][j]);
      }
    }
  }
  return seen;
}

}  // namespace

RefineLinearization LinearizeRefinement(const DifferentiablePathTracer& tracer,
                                        const std::vector<PosedImage>& targets,
                                        const RefineOptions& options, uint64_t seed,
                                        const Eigen::VectorXd* direction) {
  const std::vector<PixelRef> pixels =
      SamplePixels(tracer, PathTracer(tracer.scene()), targets, options.pixels_per_view,
                   options.edge_margin, options.refined_pixels_only, seed);
  const double scale = options.noise * ReferenceRms(targets, pixels);
  const Evaluation e = Evaluate(tracer, targets, pixels, options, seed, scale, true);
  RefineLinearization l;
  l.cost = e.data_cost;
  const NormalEquations n = Assemble(e, tracer.VertexCount(), options.robust, false);
  l.gradient = n.gradient;
  if (direction) {
    Eigen::VectorXd product;
    n.Multiply(*direction, &product);
    l.curvature = direction->dot(product);
  }
  return l;
}

HeldOutComparison CompareOnFreshPixels(DifferentiablePathTracer& tracer,
                                       const std::vector<PosedImage>& targets,
                                       const RefineOptions& options, uint64_t seed,
                                       const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  const std::vector<PixelRef> pixels =
      SamplePixels(tracer, PathTracer(tracer.scene()), targets, options.pixels_per_view,
                   options.edge_margin, options.refined_pixels_only, seed);
  HeldOutComparison out;
  out.pixels = static_cast<int>(pixels.size());
  if (pixels.empty()) return out;
  const double rms = ReferenceRms(targets, pixels), channels = 3.0 * pixels.size();
  const auto rmse_at = [&](const Eigen::VectorXd& x) {
    tracer.SetPositions(x, false);
    return std::sqrt(Evaluate(tracer, targets, pixels, options, seed, 1.0, false).sum_squared /
                     channels) /
           rms;
  };
  out.rmse_a = rmse_at(a);
  out.rmse_b = rmse_at(b);
  return out;
}

RefineResult RefineVertices(DifferentiablePathTracer& tracer,
                            const std::vector<PosedImage>& targets, const RefineOptions& options,
                            uint64_t seed, const RefineProgress& progress) {
  options.Validate();
  if (targets.empty()) throw Error("vertex refinement: no reference images");
  for (size_t t = 0; t < targets.size(); ++t) {
    const auto& k = targets[t].view.intrinsics;
    const ImageRgb& image = targets[t].image;
    if (image.width() != k.width || image.height() != k.height) {
      throw Error(Format("vertex refinement: reference image ", t, " is ", image.width(), "x",
                         image.height(), " but its view is ", k.width, "x", k.height));
    }
    for (int v = 0; v < image.height(); ++v) {
      for (int u = 0; u < image.width(); ++u) {
        if (!image(u, v).allFinite()) {
          throw Error(Format("vertex refinement: reference image ", t, " pixel (", u, ", ", v,
                             ") is not finite"));
        }
      }
    }
  }
  if (tracer.VertexCount() == 0) throw Error("vertex refinement: no vertices to refine");

  const PathTracer plain(tracer.scene());  // built once for the pixel sample and the seen vertices
  const std::vector<PixelRef> pixels =
      SamplePixels(tracer, plain, targets, options.pixels_per_view, options.edge_margin,
                   options.refined_pixels_only, seed);
  const double rms = ReferenceRms(targets, pixels);
  const double scale = options.noise * rms;
  std::vector<Eigen::Matrix3d> prior = PriorBlocks(tracer, options);
  std::vector<bool> held(prior.size(), false);
  if (!options.refine_unseen) {
    const std::vector<bool> seen = SeenVertices(tracer, plain, targets, pixels);
    for (size_t v = 0; v < seen.size(); ++v) {
      if (!seen[v]) prior[v] *= kHeld, held[v] = true;
    }
  }
  const double channels = 3.0 * pixels.size();

  RefineResult result;
  result.initial = tracer.Positions();
  result.pixels = static_cast<int>(pixels.size());
  Eigen::VectorXd x = result.initial;
  // The prior's cost per vertex is Huber's loss of its Mahalanobis distance s = sqrt(d^T P d) from
  // the start (threshold prior_robust): quadratic for the small moves that noise makes, linear for
  // a large move that the images support, which a quadratic prior would pull back in proportion
  // (on the replica a 3 mm prior left the 40 mm spike 4-5 mm short). Held vertices stay quadratic
  // (threshold 0, as prior_robust 0).
  const auto threshold = [&](size_t v) { return held[v] ? 0.0 : options.prior_robust; };
  const auto distance = [&](const Eigen::VectorXd& at, size_t v) {
    const Eigen::Vector3d d = (at - result.initial).segment<3>(3 * v);
    return std::sqrt(d.dot(prior[v] * d));
  };
  const auto prior_weight = [&](const Eigen::VectorXd& at, size_t v) {
    return HuberWeight(distance(at, v), threshold(v));
  };
  // The relaxation term x^T Q x / 2 (Relaxation), Q from the normals at the start of each
  // iteration.
  const Relaxation relax(tracer, options.relax_sigma, options.smooth_sigma);
  Eigen::SparseMatrix<double> relaxation = relax.Matrix(x);
  const auto prior_gradient_at = [&](const Eigen::VectorXd& at) {
    Eigen::VectorXd g(at.size());
    for (size_t v = 0; v < prior.size(); ++v) {
      g.segment<3>(3 * v) =
          prior_weight(at, v) * (prior[v] * (at - result.initial).segment<3>(3 * v));
    }
    if (relaxation.nonZeros() > 0) g += relaxation * at;
    return g;
  };
  const auto prior_cost = [&](const Eigen::VectorXd& at) {
    double sum = 0.0;
    for (size_t v = 0; v < prior.size(); ++v) sum += HuberCost(distance(at, v), threshold(v));
    if (relaxation.nonZeros() > 0) sum += 0.5 * at.dot(relaxation * at);
    return sum;
  };
  // The prior's matrix at `at` for the step: P times the IRLS weight.
  const auto prior_blocks_at = [&](const Eigen::VectorXd& at) {
    std::vector<Eigen::Matrix3d> blocks(prior.size());
    for (size_t v = 0; v < prior.size(); ++v) blocks[v] = prior_weight(at, v) * prior[v];
    return blocks;
  };
  const auto now = [] { return std::chrono::steady_clock::now(); };
  const auto seconds = [](auto since) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
  };

  auto start = now();
  // With resampling every iteration traces its own linearisation: the start needs values only.
  Evaluation current = Evaluate(tracer, targets, pixels, options, seed, scale, !options.resample);
  RefineIteration first;
  first.cost = current.data_cost + prior_cost(x);
  first.data_rmse = std::sqrt(current.sum_squared / channels) / rms;
  first.damping = options.damping;
  first.accepted = true;
  first.seconds = seconds(start);
  first.rays = current.rays;
  result.history.push_back(first);
  if (progress) progress(first, tracer);

  const std::vector<Eigen::Vector3i> faces = ParameterFaces(tracer);
  double mu = options.damping;
  const double max_radius = options.max_step * MeanEdgeLength(tracer);
  double radius = max_radius;
  for (int it = 1; it <= options.iterations; ++it) {
    start = now();
    RefineIteration record;
    record.iteration = it;
    // Fresh random numbers each iteration (the same for its trials): a fixed sample would let
    // the vertices fit its noise.
    const uint64_t it_seed = options.resample ? seed + 7919 * static_cast<uint64_t>(it) : seed;
    if (options.resample) {
      tracer.SetPositions(x, true);
      current = Evaluate(tracer, targets, pixels, options, it_seed, scale, true);
      record.rays.intersect += current.rays.intersect;
      record.rays.occluded += current.rays.occluded;
    }
    relaxation = relax.Matrix(x);
    const NormalEquations equations = Assemble(current, tracer.VertexCount(), options.robust,
                                               tracer.VertexCount() <= options.direct_max_vertices);
    record.jacobian_nonzeros_per_pixel = equations.nonzeros / pixels.size();
    const Eigen::VectorXd prior_gradient = prior_gradient_at(x);
    const std::vector<Eigen::Matrix3d> prior_here = prior_blocks_at(x);
    const double cost = current.data_cost + prior_cost(x);
    record.cost = cost;
    for (int attempt = 0; attempt <= options.max_retries; ++attempt) {
      Eigen::VectorXd step = SolveStep(equations, prior_gradient, prior_here, relaxation, mu);
      // Trust region on the largest vertex move: the linear model holds over a fraction of an edge.
      double largest = 0.0;
      for (int v = 0; v < tracer.VertexCount(); ++v)
        largest = std::max(largest, step.segment<3>(3 * v).norm());
      if (largest > radius) step *= radius / largest;
      if (options.average_after > 0 && it > options.average_after)
        step /= it - options.average_after;
      record.held += HoldFoldingVertices(faces, result.initial, x, &step);
      const Eigen::VectorXd trial = x + step;
      const bool derivatives = it < options.iterations && !options.resample;
      tracer.SetPositions(trial, derivatives);
      // Most steps are kept: trace the trial with derivatives, they are the next iteration's
      // (unless the next iteration draws new random numbers).
      Evaluation evaluation =
          Evaluate(tracer, targets, pixels, options, it_seed, scale, derivatives);
      record.rays.intersect += evaluation.rays.intersect;
      record.rays.occluded += evaluation.rays.occluded;
      const double trial_cost = evaluation.data_cost + prior_cost(trial);
      if (trial_cost < cost) {
        x = trial;
        current = std::move(evaluation);
        record.accepted = true;
        record.cost = trial_cost;
        record.step_rms = std::sqrt(step.squaredNorm() / tracer.VertexCount());
        mu = std::max(mu / 3.0, 1e-9);
        radius = std::min(2.0 * radius, max_radius);
        break;
      }
      ++record.rejected;
      mu = std::max(mu * 4.0, 1e-6);
      radius *= 0.5;
    }
    if (!record.accepted) tracer.SetPositions(x);
    record.data_rmse = std::sqrt(current.sum_squared / channels) / rms;
    record.damping = mu;
    record.seconds = seconds(start);
    result.history.push_back(record);
    if (progress) progress(record, tracer);
    if (!record.accepted) break;
    if (cost - record.cost < options.tolerance * cost) break;
  }
  result.positions = x;
  return result;
}

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
