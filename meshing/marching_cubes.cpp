#include "meshing/marching_cubes.h"

#include <array>
#include <chrono>
#include <climits>
#include <memory>

#include "core/check.h"
#include "core/parallel.h"
#include "meshing/cube_cases.h"
#include "meshing/mesh_cleanup.h"

namespace genscene::meshing {

void MeshingOptions::Validate() const {
  RequireRange("iso_level", iso_level, -10.0, 10.0);
  RequireRange("min_weight", min_weight, 0.0, 1e9);
  RequireRange("min_component_triangles", min_component_triangles, 0, INT_MAX);
  RequireRange("denoise_iterations", denoise_iterations, 0, 1000);
  RequireRange("denoise_angle", denoise_angle, 1.0, 180.0);
  RequireRange("denoise_max_offset", denoise_max_offset, 0.0, 100.0);
  RequireRange("decimate_max_error", decimate_max_error, 0.0, 10.0);
}

Eigen::Vector3f EdgeNormal(const Eigen::Vector3f& gradient0, const Eigen::Vector3f& gradient1,
                           float t, int axis, bool start_inside) {
  const Eigen::Vector3f g = (1.0f - t) * gradient0 + t * gradient1;
  const float norm = g.norm();
  if (norm > 1e-12f && std::isfinite(norm)) return g / norm;
  // The sdf grows from the inside end to the outside end of a crossed edge.
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  n[axis] = start_inside ? 1.0f : -1.0f;
  return n;
}

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kSide = kTsdfBlockSide;
constexpr int kVoxels = kTsdfBlockVoxels;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

Eigen::Vector3i Unit(int axis) {
  return Eigen::Vector3i::Unit(axis);
}

// The voxels of a block and of its 26 neighbours, addressed by local coordinates in [-8, 16)
// relative to the block: one hash lookup per neighbour and block, none per voxel.
class Neighbourhood {
 public:
  explicit Neighbourhood(const TsdfVolume& volume)
      : volume_(volume), neighbours_(volume.num_blocks()) {
    ParallelFor(
        0, volume.num_blocks(),
        [&](size_t b) {
          for (int i = 0; i < 27; ++i) {
            const Eigen::Vector3i d(i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1);
            neighbours_[b][i] = volume.FindBlock(volume.block_key(b) + d).value_or(-1);
          }
        },
        64);
  }

  // Global id (block * 512 + voxel index) of the point at local coordinates `v` of block b, or -1
  // when its block is not allocated.
  int64_t PointId(size_t b, const Eigen::Vector3i& v) const {
    // Most lookups stay inside the block itself.
    if (static_cast<unsigned>(v.x()) < kSide && static_cast<unsigned>(v.y()) < kSide &&
        static_cast<unsigned>(v.z()) < kSide) {
      return static_cast<int64_t>(b) * kVoxels + TsdfBlock::Index(v.x(), v.y(), v.z());
    }
    const Eigen::Vector3i d = (v.array() + kSide) / kSide - 1;  // -1, 0 or 1 per axis
    const int32_t block = neighbours_[b][(d.x() + 1) + 3 * (d.y() + 1) + 9 * (d.z() + 1)];
    if (block < 0) return -1;
    const Eigen::Vector3i local = v - kSide * d;
    return int64_t{block} * kVoxels + TsdfBlock::Index(local.x(), local.y(), local.z());
  }

  // The voxel at local coordinates v of block b when it exists and is observed.
  const TsdfVoxel* Observed(size_t b, const Eigen::Vector3i& v, float min_weight) const {
    const int64_t id = PointId(b, v);
    if (id < 0) return nullptr;
    const TsdfVoxel& voxel = volume_.block(id / kVoxels).voxels[id % kVoxels];
    return IsObserved(voxel, min_weight) ? &voxel : nullptr;
  }

 private:
  const TsdfVolume& volume_;
  std::vector<std::array<int32_t, 27>> neighbours_;
};

Eigen::Vector3i LocalOf(int i) {
  return Eigen::Vector3i(i % kSide, (i / kSide) % kSide, i / (kSide * kSide));
}

// The corners of a block's cells are its 8^3 voxels plus the far faces taken from its +x, +y and
// +z neighbours: 9^3 lattice points.
constexpr int kPad = kSide + 1;
constexpr int kPadPoints = kPad * kPad * kPad;

// Cube indices of block b's 512 cells into `cube` (0 where a corner is unobserved). Returns false,
// leaving `cube` untouched, when no cell of the block can have triangles: its observed corners all
// lie on one side of the iso level (most blocks of a fused volume: the truncation band is wider
// than the surface). One neighbour lookup per corner point, not per cell corner.
bool ClassifyBlock(const Neighbourhood& hood, const TsdfVolume& volume, size_t b, float iso,
                   float min_weight, uint8_t* cube) {
  std::array<float, kPadPoints> sdf;
  std::array<bool, kPadPoints> observed;
  bool any_inside = false, any_outside = false;
  for (int z = 0, p = 0; z < kPad; ++z) {
    for (int y = 0; y < kPad; ++y) {
      for (int x = 0; x < kPad; ++x, ++p) {
        const int64_t id = hood.PointId(b, Eigen::Vector3i(x, y, z));
        const TsdfVoxel* voxel =
            id >= 0 ? &volume.block(id / kVoxels).voxels[id % kVoxels] : nullptr;
        observed[p] = voxel != nullptr && IsObserved(*voxel, min_weight);
        if (!observed[p]) continue;
        sdf[p] = voxel->sdf;
        any_inside |= sdf[p] < iso;
        any_outside |= !(sdf[p] < iso);
      }
    }
  }
  if (!any_inside || !any_outside) return false;
  std::array<int, 8> corner_offset;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3i o = CornerOffset(c);
    corner_offset[c] = o.x() + kPad * (o.y() + kPad * o.z());
  }
  for (int i = 0; i < kVoxels; ++i) {
    const int x = i % kSide, y = (i / kSide) % kSide, z = i / (kSide * kSide);
    const int base = x + kPad * (y + kPad * z);
    float corners[8];
    bool all_observed = true;
    for (int c = 0; c < 8 && all_observed; ++c) {
      const int point = base + corner_offset[c];
      all_observed = observed[point];
      if (all_observed) corners[c] = sdf[point];
    }
    cube[i] = all_observed ? CubeIndex(corners, iso) : 0;
  }
  return true;
}

// Per cube index, bit e set when cell edge e is crossed: its two corners lie on opposite sides.
// In a cell with triangles every crossed edge carries a vertex (the face rule of cube_cases.h
// joins every crossed edge of a face), so these are the edges the cell's triangles use.
const std::array<uint16_t, 256>& CrossedEdges() {
  static const std::array<uint16_t, 256> table = [] {
    std::array<uint16_t, 256> crossed{};
    for (int index = 0; index < 256; ++index) {
      for (int e = 0; e < 12; ++e) {
        const int c0 = CornerIndex(EdgeStart(e)), c1 = c0 + (1 << EdgeAxis(e));
        if (((index >> c0) & 1) != ((index >> c1) & 1))
          crossed[index] |= static_cast<uint16_t>(1u << e);
      }
    }
    return crossed;
  }();
  return table;
}

// Sdf gradient (per lattice unit) at lattice point v by central differences over observed
// neighbours, one-sided where one neighbour is missing, 0 along an axis where both are.
Eigen::Vector3f LatticeGradient(const Neighbourhood& hood, size_t b, const Eigen::Vector3i& v,
                                float centre, float min_weight) {
  Eigen::Vector3f g = Eigen::Vector3f::Zero();
  for (int axis = 0; axis < 3; ++axis) {
    const TsdfVoxel* plus = hood.Observed(b, v + Unit(axis), min_weight);
    const TsdfVoxel* minus = hood.Observed(b, v - Unit(axis), min_weight);
    if (plus && minus)
      g[axis] = 0.5f * (plus->sdf - minus->sdf);
    else if (plus)
      g[axis] = plus->sdf - centre;
    else if (minus)
      g[axis] = centre - minus->sdf;
  }
  return g;
}

// Exclusive scan of per-block counts; returns the total.
uint64_t ExclusiveScan(const std::vector<uint32_t>& counts, std::vector<uint64_t>* offsets) {
  offsets->resize(counts.size());
  uint64_t sum = 0;
  for (size_t i = 0; i < counts.size(); ++i) {
    (*offsets)[i] = sum;
    sum += counts[i];
  }
  return sum;
}

void CheckIndexRange(uint64_t count, const char* what) {
  if (count > static_cast<uint64_t>(INT_MAX)) {
    throw Error(Format("marching cubes: ", count, " ", what,
                       " exceed the 2^31 - 1 a TriangleMesh can index"));
  }
}

}  // namespace

MeshingResult ExtractMesh(const TsdfVolume& volume, const MeshingOptions& options) {
  options.Validate();
  const auto start = Clock::now();
  const float iso = static_cast<float>(options.iso_level);
  const float min_weight = static_cast<float>(options.min_weight);
  const size_t num_blocks = volume.num_blocks();
  MeshingResult result;
  MeshingStats& stats = result.stats;
  const CubeCase* cases =
      &CubeCaseOf(0);  // the table, indexed by cube index (no init guard per call)
  stats.blocks = num_blocks;
  stats.cells = num_blocks * kVoxels;

  // Phase 1: classify every cell; count active cells and triangles per block.
  auto t0 = Clock::now();
  const Neighbourhood hood(volume);
  std::vector<uint8_t> cube(num_blocks * kVoxels);
  std::vector<uint32_t> block_cells(num_blocks), block_triangles(num_blocks);
  ParallelFor(
      0, num_blocks,
      [&](size_t b) {
        uint8_t* block_cube = cube.data() + b * kVoxels;
        if (!ClassifyBlock(hood, volume, b, iso, min_weight, block_cube)) return;  // stays 0
        for (int i = 0; i < kVoxels; ++i) {
          const int triangles = cases[block_cube[i]].num_triangles;
          block_cells[b] += triangles > 0;
          block_triangles[b] += triangles;
        }
      },
      4);
  stats.seconds_classify = SecondsSince(t0);

  // Phase 2: exclusive scans over blocks, then compaction of the active cells.
  t0 = Clock::now();
  std::vector<uint64_t> cell_offset, triangle_offset;
  const uint64_t num_active = ExclusiveScan(block_cells, &cell_offset);
  const uint64_t num_triangles = ExclusiveScan(block_triangles, &triangle_offset);
  CheckIndexRange(num_triangles, "triangles");
  std::vector<int64_t> active_cell(num_active);
  std::vector<uint64_t> first_triangle(num_active);
  ParallelFor(
      0, num_blocks,
      [&](size_t b) {
        uint64_t slot = cell_offset[b], triangle = triangle_offset[b];
        for (int i = 0; i < kVoxels; ++i) {
          const int triangles = cases[cube[b * kVoxels + i]].num_triangles;
          if (triangles == 0) continue;
          active_cell[slot] = static_cast<int64_t>(b * kVoxels + i);
          first_triangle[slot++] = triangle;
          triangle += triangles;
        }
      },
      16);
  stats.active_cells = num_active;
  stats.seconds_scan = SecondsSince(t0);

  // Phase 3: active edges per lattice point, scanned into each point's first vertex. Each active
  // cell marks its crossed edges in the edge's lower end point, bit = axis. The marks are ORed
  // atomically: OR commutes, so the masks do not depend on the order or the thread count. An edge
  // gets a vertex exactly when it is crossed, its ends are observed and one of its four cells
  // has triangles (such a cell has all eight corners observed).
  t0 = Clock::now();
  std::vector<uint8_t> edge_mask(num_blocks * kVoxels);
  const std::array<uint16_t, 256>& crossed_edges = CrossedEdges();
  ParallelFor(
      0, num_active,
      [&](size_t a) {
        const int64_t cell = active_cell[a];
        const size_t b = static_cast<size_t>(cell / kVoxels);
        const Eigen::Vector3i v = LocalOf(static_cast<int>(cell % kVoxels));
        const uint16_t crossed = crossed_edges[cube[cell]];
        for (int e = 0; e < 12; ++e) {
          if (!(crossed & (1u << e))) continue;
          const int64_t point = hood.PointId(b, v + EdgeStart(e));
          GS_CHECK_GE(point, 0);
          __atomic_fetch_or(&edge_mask[point], static_cast<uint8_t>(1u << EdgeAxis(e)),
                            __ATOMIC_RELAXED);
        }
      },
      256);
  std::vector<uint32_t> block_vertices(num_blocks);
  ParallelFor(
      0, num_blocks,
      [&](size_t b) {
        const uint8_t* mask = edge_mask.data() + b * kVoxels;
        uint32_t count = 0;
        for (int i = 0; i < kVoxels; ++i) count += __builtin_popcount(mask[i]);
        block_vertices[b] = count;
      },
      64);
  std::vector<uint64_t> vertex_offset;
  const uint64_t num_vertices = ExclusiveScan(block_vertices, &vertex_offset);
  CheckIndexRange(num_vertices, "vertices");

  // Phase 4: one vertex per active edge: position, normal, colour.
  TriangleMesh& mesh = result.mesh;
  mesh.vertices.resize(num_vertices);
  mesh.normals.resize(num_vertices);
  mesh.vertex_colors.resize(num_vertices);
  // Read only where edge_mask has a bit set, which is where it is written: left uninitialised.
  const std::unique_ptr<int32_t[]> first_vertex(new int32_t[num_blocks * kVoxels]);
  ParallelFor(
      0, num_blocks,
      [&](size_t b) {
        if (block_vertices[b] == 0) return;
        auto next = static_cast<int32_t>(vertex_offset[b]);
        const Eigen::Vector3i block_origin = kSide * volume.block_key(b);
        for (int i = 0; i < kVoxels; ++i) {
          const uint8_t mask = edge_mask[b * kVoxels + i];
          if (mask == 0) continue;
          first_vertex[b * kVoxels + i] = next;
          const Eigen::Vector3i v = LocalOf(i);
          const TsdfVoxel& p = volume.block(b).voxels[i];
          const Eigen::Vector3f& p_color = volume.block(b).colors[i];
          const Eigen::Vector3f gradient_p = LatticeGradient(hood, b, v, p.sdf, min_weight);
          for (int axis = 0; axis < 3; ++axis) {
            if (!(mask & (1u << axis))) continue;
            // The edge's other end: observed (the edge mask says so), so it exists.
            const int64_t q_id = hood.PointId(b, v + Unit(axis));
            const TsdfBlock& q_block = volume.block(q_id / kVoxels);
            const TsdfVoxel& q = q_block.voxels[q_id % kVoxels];
            const Eigen::Vector3f& q_color = q_block.colors[q_id % kVoxels];
            const float t = EdgeCrossing(p.sdf, q.sdf, iso);
            Eigen::Vector3d lattice = (block_origin + v).cast<double>();
            lattice[axis] += t;
            mesh.vertices[next] = (volume.origin() + volume.voxel_size() * lattice).cast<float>();
            const Eigen::Vector3f gradient_q =
                LatticeGradient(hood, b, v + Unit(axis), q.sdf, min_weight);
            mesh.normals[next] = EdgeNormal(gradient_p, gradient_q, t, axis, p.sdf < iso);
            mesh.vertex_colors[next] = (1.0f - t) * p_color + t * q_color;
            ++next;
          }
        }
      },
      4);
  stats.seconds_vertices = SecondsSince(t0);

  // Phase 5: triangles of the active cells, through the owning points' vertex indices.
  t0 = Clock::now();
  mesh.faces.resize(num_triangles);
  ParallelFor(
      0, num_active,
      [&](size_t a) {
        const size_t b = static_cast<size_t>(active_cell[a] / kVoxels);
        const Eigen::Vector3i v = LocalOf(static_cast<int>(active_cell[a] % kVoxels));
        const CubeCase& cell_case = cases[cube[active_cell[a]]];
        for (int k = 0; k < cell_case.num_triangles; ++k) {
          Eigen::Vector3i face;
          for (int j = 0; j < 3; ++j) {
            const int e = cell_case.triangles[k][j];
            const int axis = EdgeAxis(e);
            const int64_t point = hood.PointId(b, v + EdgeStart(e));
            GS_CHECK_GE(point, 0);
            const uint8_t mask = edge_mask[point];
            GS_CHECK_NE(mask & (1u << axis), 0u);
            // Vertices of a point are stored in axis order: skip those of the lower axes.
            const int rank = ((mask & 1) && axis > 0) + ((mask & 2) && axis > 1);
            face[j] = first_vertex[point] + rank;
          }
          mesh.faces[first_triangle[a] + k] = face;
        }
      },
      256);
  stats.seconds_triangles = SecondsSince(t0);

  // Optional clean-up (serial; deterministic).
  t0 = Clock::now();
  if (options.min_component_triangles > 0) {
    const ComponentRemoval removal = RemoveSmallComponents(&mesh, options.min_component_triangles);
    stats.removed_components = removal.components;
    stats.removed_component_triangles = removal.triangles;
  }
  stats.seconds_cleanup = SecondsSince(t0);
  t0 = Clock::now();
  if (options.denoise_iterations > 0) {
    const DenoiseStats denoised = Denoise(&mesh, options.denoise_iterations, options.denoise_angle,
                                          options.denoise_max_offset * volume.voxel_size());
    stats.denoise_mean_offset = denoised.mean_offset;
  }
  stats.seconds_denoise = SecondsSince(t0);
  t0 = Clock::now();
  if (options.decimate_max_error > 0.0) {
    const size_t before = mesh.faces.size();
    Decimate(&mesh, options.decimate_max_error);
    stats.decimated_triangles = before - mesh.faces.size();
  }
  stats.seconds_decimate = SecondsSince(t0);
  stats.vertices = mesh.vertices.size();
  stats.triangles = mesh.faces.size();
  stats.seconds_total = SecondsSince(start);
  return result;
}

}  // namespace genscene::meshing
