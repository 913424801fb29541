#include "core/tsdf_volume.h"

#include <cmath>
#include <cstring>
#include <fstream>

#include "core/binary_io.h"
#include "core/check.h"
#include "core/file_util.h"
#include "core/options.h"

namespace genscene {

void TsdfVolumeParams::Validate() const {
  RequireRange("voxel_size", voxel_size, 1e-4, 1.0);
  RequireRange("truncation", truncation, voxel_size, 100.0 * voxel_size);
  RequireRange("max_weight", max_weight, 1.0f, 1e6f);
  RequireRange("memory_cap_bytes", memory_cap_bytes, 0.0, 1e15);
  if (!origin.allFinite()) throw Error("option origin is not finite");
}

// ---------------------------------------------------------------------------------------------
// BlockHashTable

BlockHashTable::BlockHashTable() {
  slots_.resize(1024);
}

size_t BlockHashTable::HashOf(const Eigen::Vector3i& key) {
  // The spatial hash of Teschner et al. 2003 (three large primes, xor), on unsigned values.
  const uint64_t x = static_cast<uint32_t>(key.x());
  const uint64_t y = static_cast<uint32_t>(key.y());
  const uint64_t z = static_cast<uint32_t>(key.z());
  uint64_t h = (x * 73856093ull) ^ (y * 19349669ull) ^ (z * 83492791ull);
  h ^= h >> 29;
  h *= 0xbf58476d1ce4e5b9ull;
  h ^= h >> 32;
  return static_cast<size_t>(h);
}

std::optional<int32_t> BlockHashTable::Find(const Eigen::Vector3i& key) const {
  const size_t mask = slots_.size() - 1;
  for (size_t i = HashOf(key) & mask;; i = (i + 1) & mask) {
    const Slot& slot = slots_[i];
    if (slot.value < 0) return std::nullopt;
    if (slot.key == key) return slot.value;
  }
}

void BlockHashTable::Insert(const Eigen::Vector3i& key, int32_t value) {
  GS_CHECK_GE(value, 0);
  if (2 * (size_ + 1) > slots_.size()) Grow();
  const size_t mask = slots_.size() - 1;
  for (size_t i = HashOf(key) & mask;; i = (i + 1) & mask) {
    Slot& slot = slots_[i];
    if (slot.value < 0) {
      slot.key = key;
      slot.value = value;
      ++size_;
      return;
    }
    GS_CHECK(slot.key != key);
  }
}

void BlockHashTable::Grow() {
  std::vector<Slot> old;
  old.swap(slots_);
  slots_.assign(old.size() * 2, Slot{});
  size_ = 0;
  for (const Slot& slot : old) {
    if (slot.value >= 0) Insert(slot.key, slot.value);
  }
}

void BlockHashTable::Clear() {
  slots_.assign(1024, Slot{});
  size_ = 0;
}

// ---------------------------------------------------------------------------------------------
// TsdfVolume

TsdfVolume::TsdfVolume(const TsdfVolumeParams& params) : params_(params) {
  params_.Validate();
}

int32_t TsdfVolume::AllocateBlock(const Eigen::Vector3i& key) {
  if (auto found = table_.Find(key)) return *found;
  if (params_.memory_cap_bytes > 0 &&
      allocated_bytes() + sizeof(TsdfBlock) > params_.memory_cap_bytes) {
    throw Error(Format("TSDF volume: memory cap of ", params_.memory_cap_bytes / 1e6,
                       " MB reached with ", blocks_.size(), " blocks of ", kTsdfBlockSide,
                       "^3 voxels (", sizeof(TsdfBlock), " bytes each) at voxel size ",
                       params_.voxel_size, " m; use a larger voxel size or raise the memory cap"));
  }
  if (blocks_.size() >= static_cast<size_t>(INT32_MAX)) throw Error("TSDF volume: too many blocks");
  const auto index = static_cast<int32_t>(blocks_.size());
  blocks_.emplace_back();
  keys_.push_back(key);
  table_.Insert(key, index);
  const Eigen::Vector3i chunk = ChunkOf(key);
  if (const auto c = chunk_table_.Find(chunk)) {
    chunk_blocks_[static_cast<size_t>(*c)].push_back(index);
  } else {
    chunk_table_.Insert(chunk, static_cast<int32_t>(chunk_keys_.size()));
    chunk_keys_.push_back(chunk);
    chunk_blocks_.push_back({index});
  }
  return index;
}

namespace {

// A voxel's place: its block and its index in the block's arrays (voxels and colors).
struct Corner {
  const TsdfBlock* block;
  int index;
};

// The place of lattice point v; nullopt when its block is not allocated.
std::optional<Corner> Locate(const TsdfVolume& volume, const Eigen::Vector3i& v) {
  const Eigen::Vector3i b = TsdfVolume::BlockOf(v);
  const auto index = volume.FindBlock(b);
  if (!index) return std::nullopt;
  const Eigen::Vector3i local = v - kTsdfBlockSide * b;
  return Corner{&volume.block(static_cast<size_t>(*index)),
                TsdfBlock::Index(local.x(), local.y(), local.z())};
}

}  // namespace

const TsdfVoxel* TsdfVolume::FindVoxel(const Eigen::Vector3i& v) const {
  const auto place = Locate(*this, v);
  return place ? &place->block->voxels[place->index] : nullptr;
}

TsdfVoxel* TsdfVolume::FindVoxel(const Eigen::Vector3i& v) {
  return const_cast<TsdfVoxel*>(static_cast<const TsdfVolume*>(this)->FindVoxel(v));
}

namespace {

// Gathers the 8 voxels around a continuous lattice point; false when one is missing or unobserved.
bool GatherCorners(const TsdfVolume& volume, const Eigen::Vector3f& lattice, Corner corners[8],
                   Eigen::Vector3f* frac) {
  const Eigen::Vector3f floor = lattice.array().floor();
  if (!floor.allFinite() || floor.cwiseAbs().maxCoeff() > 1e9f) return false;
  const Eigen::Vector3i base = floor.cast<int>();
  *frac = lattice - floor;
  for (int c = 0; c < 8; ++c) {
    const auto place = Locate(volume, base + Eigen::Vector3i(c & 1, (c >> 1) & 1, (c >> 2) & 1));
    if (!place || place->block->voxels[place->index].weight <= 0.0f) return false;
    corners[c] = *place;
  }
  return true;
}

template <typename T, typename Get>
T Trilinear(const Corner corners[8], const Eigen::Vector3f& f, const Get& get) {
  const T x00 = get(corners[0]) * (1 - f.x()) + get(corners[1]) * f.x();
  const T x10 = get(corners[2]) * (1 - f.x()) + get(corners[3]) * f.x();
  const T x01 = get(corners[4]) * (1 - f.x()) + get(corners[5]) * f.x();
  const T x11 = get(corners[6]) * (1 - f.x()) + get(corners[7]) * f.x();
  const T y0 = x00 * (1 - f.y()) + x10 * f.y();
  const T y1 = x01 * (1 - f.y()) + x11 * f.y();
  return y0 * (1 - f.z()) + y1 * f.z();
}

}  // namespace

std::optional<float> TsdfVolume::InterpolateSdf(const Eigen::Vector3f& lattice) const {
  Corner corners[8];
  Eigen::Vector3f f;
  if (!GatherCorners(*this, lattice, corners, &f)) return std::nullopt;
  return Trilinear<float>(corners, f, [](const Corner& c) { return c.block->voxels[c.index].sdf; });
}

std::optional<Eigen::Vector3f> TsdfVolume::InterpolateColor(const Eigen::Vector3f& lattice) const {
  Corner corners[8];
  Eigen::Vector3f f;
  if (!GatherCorners(*this, lattice, corners, &f)) return std::nullopt;
  return Trilinear<Eigen::Vector3f>(
      corners, f, [](const Corner& c) -> Eigen::Vector3f { return c.block->colors[c.index]; });
}

std::optional<Eigen::Vector3f> TsdfVolume::SdfGradient(const Eigen::Vector3f& lattice) const {
  Eigen::Vector3f gradient;
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::Vector3f step = Eigen::Vector3f::Zero();
    step[axis] = 0.5f;
    const auto plus = InterpolateSdf(lattice + step);
    const auto minus = InterpolateSdf(lattice - step);
    if (!plus || !minus) return std::nullopt;
    gradient[axis] = *plus - *minus;  // central difference over one lattice unit
  }
  return gradient;
}

size_t TsdfVolume::CountObservedVoxels() const {
  size_t count = 0;
  for (const TsdfBlock& block : blocks_) {
    for (const TsdfVoxel& voxel : block.voxels) count += voxel.weight > 0.0f;
  }
  return count;
}

void TsdfVolume::Clear() {
  blocks_.clear();
  keys_.clear();
  table_.Clear();
  chunk_keys_.clear();
  chunk_blocks_.clear();
  chunk_table_.Clear();
}

// ---------------------------------------------------------------------------------------------
// File I/O

namespace {

constexpr char kMagic[8] = {'G', 'S', 'T', 'S', 'D', 'F', '0', '1'};
constexpr size_t kVoxelBytes = 5 * sizeof(float);
constexpr size_t kBlockBytes = 3 * sizeof(int32_t) + kTsdfBlockVoxels * kVoxelBytes;

}  // namespace

void WriteTsdfVolume(const std::filesystem::path& path, const TsdfVolume& volume) {
  std::string out;
  out.reserve(64 + volume.num_blocks() * kBlockBytes);
  out.append(kMagic, sizeof(kMagic));
  const TsdfVolumeParams& p = volume.params();
  PutBinary(out, p.voxel_size);
  PutBinary(out, p.truncation);
  PutBinary(out, p.max_weight);
  for (int i = 0; i < 3; ++i) PutBinary(out, p.origin[i]);
  PutBinary(out, static_cast<uint64_t>(volume.num_blocks()));
  for (size_t b = 0; b < volume.num_blocks(); ++b) {
    const Eigen::Vector3i& key = volume.block_key(b);
    for (int i = 0; i < 3; ++i) PutBinary(out, static_cast<int32_t>(key[i]));
    const TsdfBlock& block = volume.block(b);
    for (int i = 0; i < kTsdfBlockVoxels; ++i) {
      PutBinary(out, block.voxels[i].sdf);
      PutBinary(out, block.voxels[i].weight);
      for (int c = 0; c < 3; ++c) PutBinary(out, block.colors[i][c]);
    }
  }
  WriteFileAtomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream file(tmp, std::ios::binary);
    file.write(out.data(), static_cast<std::streamsize>(out.size()));
    file.close();
    if (!file) throw Error(Format(path.string(), ": cannot write TSDF volume"));
  });
}

TsdfVolume ReadTsdfVolume(const std::filesystem::path& path, double memory_cap_bytes) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw Error(Format(path.string(), ": cannot open TSDF volume file"));
  const std::string data((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  const std::string where = path.string();
  if (data.size() < sizeof(kMagic) || std::memcmp(data.data(), kMagic, sizeof(kMagic)) != 0) {
    throw Error(Format(where, ": not a genscene TSDF volume (expected magic GSTSDF01)"));
  }
  const std::string body = data.substr(sizeof(kMagic));
  BinaryReader reader(body, path, "TSDF volume");
  TsdfVolumeParams params;
  params.voxel_size = reader.Get<double>("voxel_size");
  params.truncation = reader.Get<double>("truncation");
  params.max_weight = reader.Get<float>("max_weight");
  for (int i = 0; i < 3; ++i) params.origin[i] = reader.Get<double>("origin");
  params.memory_cap_bytes = memory_cap_bytes;
  try {
    params.Validate();
  } catch (const Error& e) {
    throw Error(Format(where, ": bad TSDF volume header: ", e.what()));
  }
  const auto count = reader.Get<uint64_t>("block count");
  if (count > reader.remaining() / kBlockBytes || count * kBlockBytes != reader.remaining()) {
    throw Error(Format(where, ": TSDF volume declares ", count, " blocks (",
                       count * 1.0 * kBlockBytes, " bytes) but holds ", reader.remaining(),
                       " bytes of blocks"));
  }
  TsdfVolume volume(params);
  for (uint64_t b = 0; b < count; ++b) {
    Eigen::Vector3i key;
    for (int i = 0; i < 3; ++i) key[i] = reader.Get<int32_t>("block key");
    if (key.cwiseAbs().maxCoeff() > (1 << 27)) {
      throw Error(Format(where, ": block ", b, " has an out-of-range key ", key.transpose()));
    }
    if (volume.FindBlock(key)) {
      throw Error(Format(where, ": block ", b, " repeats key ", key.transpose()));
    }
    TsdfBlock& block = volume.block(volume.AllocateBlock(key));
    for (int i = 0; i < kTsdfBlockVoxels; ++i) {
      TsdfVoxel& v = block.voxels[i];
      Eigen::Vector3f& color = block.colors[i];
      v.sdf = reader.Get<float>("voxel");
      v.weight = reader.Get<float>("voxel");
      for (int c = 0; c < 3; ++c) color[c] = reader.Get<float>("voxel");
      if (!std::isfinite(v.sdf) || !std::isfinite(v.weight) || !color.allFinite() ||
          v.weight < 0.0f) {
        throw Error(Format(where, ": block ", b, " holds a non-finite or negative-weight voxel"));
      }
    }
  }
  return volume;
}

}  // namespace genscene
