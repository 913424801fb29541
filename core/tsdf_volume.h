// Sparse TSDF volume storage (DESIGN.md §3: core holds the TSDF volume storage and its file I/O;
// fusion/ writes it, meshing/ reads it).
//
// The volume is a lattice of voxels with spacing `voxel_size`; voxel v = (i, j, k) sits at the
// world point origin + voxel_size * v (lattice points, not cell centres). Voxels are grouped in
// blocks of 8x8x8 that are allocated only where a depth measurement's truncation band passed
// (voxel-block hashing, Niessner et al. 2013), so memory follows the observed surface area,
// not the bounding volume. Block b holds voxels 8*b + [0, 8)^3.
//
// Each voxel stores the truncated signed distance in metres (positive in front of the surface,
// i.e. on the camera's side; clamped to [-truncation, truncation]), the accumulated weight
// (0 = never observed) and a weighted running average of the linear RGB colour. A block keeps the
// geometry (sdf, weight: 8 bytes a voxel) apart from the colours: the raycast for tracking and
// marching cubes' classification read only the geometry, and an x-row of eight voxels is then one
// 64-byte cache line (a trilinear sample reads four lines, and a block's geometry is 4 KB).
//
// The world origin of the lattice is a double-precision offset, so that a scene 1 km from the
// world origin keeps millimetre precision in the float voxel arithmetic.
//
// Block order is the allocation order; the allocating code (fusion) allocates in a
// deterministic order, so block indices are identical with any thread count.
//
// Blocks are also grouped into chunks of 8x8x8 blocks (64^3 voxels: 64 cm at 1 cm voxels), each
// with the list of its allocated blocks, so that a per-frame pass (the raycast's depth ranges)
// tests a chunk against the camera's frustum and visits only the blocks of the chunks it
// touches: its cost follows what the camera sees, not the size of the scanned room.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <optional>
#include <vector>

namespace genscene {

// floor() as an int without a libm call (x86-64 without SSE4.1 has no inline floor instruction,
// and the lattice arithmetic of fusion and meshing calls this per voxel and per ray step).
inline int FloorToInt(float x) {
  const int i = static_cast<int>(x);
  return i - (x < static_cast<float>(i));
}

// The geometry of one voxel; its colour is TsdfBlock::colors at the same index.
struct TsdfVoxel {
  float sdf = 0.0f;     // truncated signed distance, metres, in [-truncation, truncation]
  float weight = 0.0f;  // accumulated integration weight; 0 = unobserved
};

constexpr int kTsdfBlockSide = 8;
constexpr int kTsdfBlockVoxels = kTsdfBlockSide * kTsdfBlockSide * kTsdfBlockSide;
constexpr int kTsdfChunkShift = 3;  // a chunk is 2^3 = 8 blocks per side
constexpr int kTsdfChunkSide = kTsdfBlockSide << kTsdfChunkShift;  // voxels per side of a chunk

struct alignas(64) TsdfBlock {
  TsdfBlock() {
    for (Eigen::Vector3f& c : colors) c.setZero();
  }
  std::array<TsdfVoxel, kTsdfBlockVoxels> voxels;
  std::array<Eigen::Vector3f, kTsdfBlockVoxels> colors;  // weighted mean linear RGB
  // Index of the local voxel (x, y, z), each in [0, 8).
  static int Index(int x, int y, int z) { return x + kTsdfBlockSide * (y + kTsdfBlockSide * z); }
};

struct TsdfVolumeParams {
  double voxel_size = 0.01;   // metres between lattice points
  double truncation = 0.04;   // metres; the band |sdf| < truncation around surfaces
  float max_weight = 128.0f;  // the running average's weight saturates here (adapts to change)
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // world position of voxel (0, 0, 0)
  double memory_cap_bytes = 4e9;  // allocating beyond this throws Error (0 = no cap)

  // Throws Error naming the field and value when out of range.
  void Validate() const;
};

// Hash of block coordinates to block index: open addressing with linear probing. Lookups are
// safe from many threads as long as nobody inserts at the same time.
class BlockHashTable {
 public:
  BlockHashTable();
  std::optional<int32_t> Find(const Eigen::Vector3i& key) const;
  // Inserts key -> value; the key must not be present.
  void Insert(const Eigen::Vector3i& key, int32_t value);
  void Clear();
  size_t size() const { return size_; }

 private:
  struct Slot {
    Eigen::Vector3i key;
    int32_t value = -1;  // -1 = empty
  };
  static size_t HashOf(const Eigen::Vector3i& key);
  void Grow();
  std::vector<Slot> slots_;
  size_t size_ = 0;
};

class TsdfVolume {
 public:
  explicit TsdfVolume(const TsdfVolumeParams& params);

  const TsdfVolumeParams& params() const { return params_; }
  double voxel_size() const { return params_.voxel_size; }
  double truncation() const { return params_.truncation; }
  const Eigen::Vector3d& origin() const { return params_.origin; }

  size_t num_blocks() const { return keys_.size(); }
  const Eigen::Vector3i& block_key(size_t i) const { return keys_[i]; }
  const TsdfBlock& block(size_t i) const { return blocks_[i]; }
  TsdfBlock& block(size_t i) { return blocks_[i]; }
  // Bytes held by voxel blocks (what the memory cap limits).
  double allocated_bytes() const { return static_cast<double>(blocks_.size()) * sizeof(TsdfBlock); }

  std::optional<int32_t> FindBlock(const Eigen::Vector3i& key) const { return table_.Find(key); }

  // Chunks (8^3 blocks) that hold at least one allocated block, in the order of their first
  // block's allocation; chunk c covers blocks 8 * chunk_key(c) + [0, 8)^3 and lists the indices of
  // its allocated blocks in allocation order.
  size_t num_chunks() const { return chunk_keys_.size(); }
  const Eigen::Vector3i& chunk_key(size_t c) const { return chunk_keys_[c]; }
  const std::vector<int32_t>& chunk_blocks(size_t c) const { return chunk_blocks_[c]; }
  static Eigen::Vector3i ChunkOf(const Eigen::Vector3i& block_key) {
    return Eigen::Vector3i(block_key.x() >> kTsdfChunkShift, block_key.y() >> kTsdfChunkShift,
                           block_key.z() >> kTsdfChunkShift);  // arithmetic shift: floor
  }
  // Returns the block's index, allocating an unobserved block when missing. Throws Error when
  // the allocation would exceed params().memory_cap_bytes. Not thread-safe.
  int32_t AllocateBlock(const Eigen::Vector3i& key);

  // The voxel at lattice index v, or nullptr when its block is not allocated.
  const TsdfVoxel* FindVoxel(const Eigen::Vector3i& v) const;
  TsdfVoxel* FindVoxel(const Eigen::Vector3i& v);

  // Lattice <-> world.
  Eigen::Vector3d VoxelToWorld(const Eigen::Vector3i& v) const {
    return params_.origin + params_.voxel_size * v.cast<double>();
  }
  // Continuous lattice coordinates of a world point (voxel (i,j,k) at integer coordinates).
  Eigen::Vector3d WorldToLattice(const Eigen::Vector3d& p) const {
    return (p - params_.origin) / params_.voxel_size;
  }
  static Eigen::Vector3i BlockOf(const Eigen::Vector3i& v) {
    return Eigen::Vector3i(FloorDiv(v.x()), FloorDiv(v.y()), FloorDiv(v.z()));
  }
  static int FloorDiv(int a) {
    return a >= 0 ? a / kTsdfBlockSide : -((-a + kTsdfBlockSide - 1) / kTsdfBlockSide);
  }

  // Trilinear interpolation of the sdf at continuous lattice coordinates; nullopt when one of the
  // eight surrounding voxels is unallocated or unobserved (weight 0).
  std::optional<float> InterpolateSdf(const Eigen::Vector3f& lattice) const;
  // Same for the colour.
  std::optional<Eigen::Vector3f> InterpolateColor(const Eigen::Vector3f& lattice) const;
  // Gradient of the sdf by central differences of trilinear samples (per lattice unit), at
  // continuous lattice coordinates; nullopt where a sample is missing.
  std::optional<Eigen::Vector3f> SdfGradient(const Eigen::Vector3f& lattice) const;

  // Number of observed voxels (weight > 0).
  size_t CountObservedVoxels() const;

  // Removes every block.
  void Clear();

 private:
  TsdfVolumeParams params_;
  std::vector<Eigen::Vector3i> keys_;
  std::deque<TsdfBlock> blocks_;  // a deque: growing never moves (copies) the existing blocks
  BlockHashTable table_;
  std::vector<Eigen::Vector3i> chunk_keys_;
  std::vector<std::vector<int32_t>> chunk_blocks_;
  BlockHashTable chunk_table_;  // chunk key -> chunk index
};

// The .gsv file ("genscene volume"), little-endian binary:
//   magic "GSTSDF01" (8 bytes)
//   f64 voxel_size, f64 truncation, f32 max_weight, f64 origin[3]
//   u64 block count
//   per block, in the volume's block order: i32 key[3], then 512 voxels in TsdfBlock::Index
//   order, each f32 sdf, f32 weight, f32 r, g, b.
// Reading it back gives a volume equal voxel for voxel and bit for bit.
void WriteTsdfVolume(const std::filesystem::path& path, const TsdfVolume& volume);
// Throws Error naming the file on a bad magic, a truncated file, an absurd header, or non-finite
// values. `memory_cap_bytes` limits the blocks the file may declare.
TsdfVolume ReadTsdfVolume(const std::filesystem::path& path, double memory_cap_bytes = 4e9);

}  // namespace genscene
