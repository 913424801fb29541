#include "core/tsdf_volume.h"

#include <algorithm>
#include <fstream>

#include "core/se3.h"
#include "core/trajectory_metrics.h"
#include "tests/test_util.h"

namespace genscene {
namespace {

using test::TempDir;

TsdfVolume MakeVolume() {
  TsdfVolumeParams p;
  p.voxel_size = 0.02;
  p.truncation = 0.06;
  p.origin = Eigen::Vector3d(1000.25, -3.5, 0.125);
  TsdfVolume volume(p);
  int n = 0;
  for (const Eigen::Vector3i& key :
       {Eigen::Vector3i(0, 0, 0), Eigen::Vector3i(-1, 2, -3), Eigen::Vector3i(5, -7, 1)}) {
    TsdfBlock& block = volume.block(volume.AllocateBlock(key));
    for (int i = 0; i < kTsdfBlockVoxels; ++i) {
      TsdfVoxel& v = block.voxels[i];
      v.sdf = 0.001f * static_cast<float>(n % 97) - 0.03f;
      v.weight = static_cast<float>(n % 5);
      block.colors[i] = Eigen::Vector3f(0.1f, 0.2f, 0.3f) * static_cast<float>(n % 7);
      ++n;
    }
  }
  return volume;
}

std::string Bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(TsdfVolume, FileRoundTripIsBitExact) {
  TempDir dir;
  const TsdfVolume volume = MakeVolume();
  WriteTsdfVolume(dir / "a.gsv", volume);
  const TsdfVolume back = ReadTsdfVolume(dir / "a.gsv");
  ASSERT_EQ(back.num_blocks(), volume.num_blocks());
  EXPECT_EQ(back.origin(), volume.origin());
  EXPECT_EQ(back.voxel_size(), volume.voxel_size());
  for (size_t b = 0; b < volume.num_blocks(); ++b) {
    EXPECT_EQ(back.block_key(b), volume.block_key(b));
    EXPECT_EQ(0, std::memcmp(&back.block(b), &volume.block(b), sizeof(TsdfBlock)));
  }
  WriteTsdfVolume(dir / "b.gsv", back);
  EXPECT_EQ(Bytes(dir / "a.gsv"), Bytes(dir / "b.gsv"));
}

TEST(TsdfVolume, FindsVoxelsAcrossNegativeBlocks) {
  TsdfVolume volume = MakeVolume();
  // Voxel (-1, 16, -24) is local (7, 0, 0) of block (-1, 2, -3).
  const TsdfVoxel* v = volume.FindVoxel(Eigen::Vector3i(-1, 16, -24));
  ASSERT_NE(v, nullptr);
  const auto index = volume.FindBlock(Eigen::Vector3i(-1, 2, -3));
  ASSERT_TRUE(index.has_value());
  EXPECT_EQ(v, &volume.block(*index).voxels[TsdfBlock::Index(7, 0, 0)]);
  EXPECT_EQ(volume.FindVoxel(Eigen::Vector3i(-9, 16, -24)), nullptr);
  EXPECT_EQ(TsdfVolume::BlockOf(Eigen::Vector3i(-8, -9, 7)), Eigen::Vector3i(-1, -2, 0));
  EXPECT_EQ(FloorToInt(-0.5f), -1);
  EXPECT_EQ(FloorToInt(-1.0f), -1);
  EXPECT_EQ(FloorToInt(2.75f), 2);
}

TEST(TsdfVolume, HashTableKeepsThousandsOfBlocks) {
  TsdfVolumeParams p;
  p.memory_cap_bytes = 0;
  TsdfVolume volume(p);
  for (int i = 0; i < 3000; ++i)
    volume.AllocateBlock(Eigen::Vector3i(i % 17 - 8, i / 17 - 90, (i * 7) % 13));
  for (int i = 0; i < 3000; ++i) {
    const auto found = volume.FindBlock(Eigen::Vector3i(i % 17 - 8, i / 17 - 90, (i * 7) % 13));
    ASSERT_TRUE(found.has_value());
    EXPECT_EQ(*found, i);
  }
  EXPECT_FALSE(volume.FindBlock(Eigen::Vector3i(100, 100, 100)).has_value());
}

// Every block is listed in exactly one chunk, the one of 8^3 blocks that holds it (floor
// division, negative keys included), in allocation order; a read-back volume has the same
// chunks and Clear() empties them.
TEST(TsdfVolume, ChunksListEveryBlockOnceInItsChunk) {
  TsdfVolumeParams p;
  p.memory_cap_bytes = 0;
  TsdfVolume volume(p);
  for (int i = 0; i < 2000; ++i)
    volume.AllocateBlock(Eigen::Vector3i(i % 23 - 11, (i / 23) % 19 - 9, (i * 7) % 29 - 14));
  std::vector<int> seen(volume.num_blocks(), 0);
  size_t listed = 0;
  for (size_t c = 0; c < volume.num_chunks(); ++c) {
    const std::vector<int32_t>& blocks = volume.chunk_blocks(c);
    ASSERT_FALSE(blocks.empty());
    EXPECT_TRUE(std::is_sorted(blocks.begin(), blocks.end()));
    for (const int32_t b : blocks) {
      const Eigen::Vector3i key = volume.block_key(static_cast<size_t>(b));
      for (int axis = 0; axis < 3; ++axis) {
        const int lo = 8 * volume.chunk_key(c)[axis];
        EXPECT_LE(lo, key[axis]);
        EXPECT_LT(key[axis], lo + 8);
      }
      ++seen[static_cast<size_t>(b)];
      ++listed;
    }
  }
  EXPECT_EQ(listed, volume.num_blocks());
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(seen.size()));
  EXPECT_EQ(TsdfVolume::ChunkOf(Eigen::Vector3i(-1, -8, -9)), Eigen::Vector3i(-1, -1, -2));
  EXPECT_EQ(TsdfVolume::ChunkOf(Eigen::Vector3i(7, 8, 0)), Eigen::Vector3i(0, 1, 0));
  EXPECT_GT(volume.num_chunks(), 8u);

  TempDir dir;
  WriteTsdfVolume(dir / "c.gsv", volume);
  const TsdfVolume back = ReadTsdfVolume(dir / "c.gsv", 0);
  ASSERT_EQ(back.num_chunks(), volume.num_chunks());
  for (size_t c = 0; c < volume.num_chunks(); ++c) {
    EXPECT_EQ(back.chunk_key(c), volume.chunk_key(c));
    EXPECT_EQ(back.chunk_blocks(c), volume.chunk_blocks(c));
  }
  volume.Clear();
  EXPECT_EQ(volume.num_chunks(), 0u);
  volume.AllocateBlock(Eigen::Vector3i(3, 3, 3));
  ASSERT_EQ(volume.num_chunks(), 1u);
  EXPECT_EQ(volume.chunk_blocks(0), std::vector<int32_t>{0});
}

TEST(TsdfVolume, TrilinearInterpolationIsExactForLinearFields) {
  TsdfVolumeParams p;
  TsdfVolume volume(p);
  for (int i = 0; i < 8; ++i)
    volume.AllocateBlock(Eigen::Vector3i(i & 1, (i >> 1) & 1, (i >> 2) & 1));
  for (size_t b = 0; b < volume.num_blocks(); ++b) {
    for (int z = 0; z < 8; ++z)
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
          const Eigen::Vector3i v = 8 * volume.block_key(b) + Eigen::Vector3i(x, y, z);
          TsdfVoxel& voxel = volume.block(b).voxels[TsdfBlock::Index(x, y, z)];
          voxel.sdf = 0.5f * v.x() - 0.25f * v.y() + 0.125f * v.z();
          voxel.weight = 1.0f;
        }
  }
  const Eigen::Vector3f p0(7.3f, 8.6f, 3.9f);  // crosses block boundaries in x and y
  const auto sdf = volume.InterpolateSdf(p0);
  ASSERT_TRUE(sdf.has_value());
  EXPECT_NEAR(*sdf, 0.5f * p0.x() - 0.25f * p0.y() + 0.125f * p0.z(), 1e-5);
  const auto g = volume.SdfGradient(p0);
  ASSERT_TRUE(g.has_value());
  EXPECT_NEAR((*g - Eigen::Vector3f(0.5f, -0.25f, 0.125f)).norm(), 0.0f, 1e-5);
  EXPECT_FALSE(
      volume.InterpolateSdf(Eigen::Vector3f(15.5f, 1.0f, 1.0f)).has_value());  // unallocated
}

TEST(TsdfVolume, MemoryCapIsAClearError) {
  TsdfVolumeParams p;
  p.memory_cap_bytes = 3.5 * sizeof(TsdfBlock);
  TsdfVolume volume(p);
  for (int i = 0; i < 3; ++i) volume.AllocateBlock(Eigen::Vector3i(i, 0, 0));
  EXPECT_CONTAINS(test::ErrorOf([&] { volume.AllocateBlock(Eigen::Vector3i(9, 0, 0)); }),
                  "memory cap");
  EXPECT_EQ(volume.num_blocks(), 3u);
}

TEST(TsdfVolume, CorruptFilesAreClearErrors) {
  TempDir dir;
  WriteTsdfVolume(dir / "good.gsv", MakeVolume());
  const std::string good = Bytes(dir / "good.gsv");
  test::WriteFile(dir / "magic.gsv", "PLY nonsense");
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadTsdfVolume(dir / "magic.gsv"); }),
                  "magic.gsv: not a genscene TSDF volume");
  test::WriteFile(dir / "short.gsv", good.substr(0, good.size() - 7));
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadTsdfVolume(dir / "short.gsv"); }), "short.gsv");
  // A header declaring 10^12 blocks must be refused before allocating anything.
  std::string huge = good;
  const uint64_t count = 1000000000000ull;
  std::memcpy(&huge[8 + 8 + 8 + 4 + 24], &count, sizeof(count));
  test::WriteFile(dir / "huge.gsv", huge);
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadTsdfVolume(dir / "huge.gsv"); }),
                  "declares 1000000000000 blocks");
  std::string nan = good;
  const float bad = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&nan[nan.size() - 4], &bad, sizeof(bad));
  test::WriteFile(dir / "nan.gsv", nan);
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadTsdfVolume(dir / "nan.gsv"); }), "non-finite");
  EXPECT_CONTAINS(test::ErrorOf([&] { ReadTsdfVolume(dir / "missing.gsv"); }),
                  "missing.gsv: cannot open");
}

TEST(TrajectoryMetrics, AteIsZeroForARigidlyMovedTrajectoryAndSeesNoise) {
  Trajectory gt, moved, noisy;
  const Eigen::Isometry3d offset =
      ExpSE3((Vector6d() << 3.0, -2.0, 1000.0, 0.3, -0.2, 1.1).finished());
  for (int i = 0; i < 50; ++i) {
    const Eigen::Isometry3d pose = ExpSE3(
        (Vector6d() << 0.05 * i, std::sin(0.2 * i), 0.01 * i * i, 0.02 * i, 0.0, 0.1).finished());
    gt.Add(i / 30.0, pose);
    moved.Add(i / 30.0 + 0.004, offset * pose);  // within the 20 ms association window
    Eigen::Isometry3d shifted = pose;
    shifted.translation().x() += (i % 2 ? 0.01 : -0.01);
    noisy.Add(i / 30.0, shifted);
  }
  // The copy is 4 ms late: paired with the nearest ground truth, as TUM's evaluate_ate.py does.
  const AteResult exact = ComputeAte(moved, gt, 0.02, AteAssociation::kNearest);
  EXPECT_EQ(exact.pairs, 50u);
  EXPECT_LT(exact.rmse, 1e-6);
  const AteResult n = ComputeAte(noisy, gt);
  EXPECT_NEAR(n.rmse, 0.01, 1e-3);
  std::cout << "ATE of a 1 km offset copy: " << exact.rmse << " m; of +-1 cm noise: " << n.rmse
            << " m\n";
  Trajectory far;
  far.Add(100.0, Eigen::Isometry3d::Identity());
  EXPECT_CONTAINS(test::ErrorOf([&] { ComputeAte(far, gt); }), "only 0 of 1");
}

// A camera on a circle of 1 m radius at 0.5 m/s, the ground truth sampled at 100 Hz, the
// estimate exact at 30 Hz time stamps between the samples: interpolated, the ground truth agrees
// with the estimate to the chord's sagitta (v^2 dt^2 / 8 r, 3 micrometres); the nearest sample is
// up to 5 ms (2.5 mm) away.
TEST(TrajectoryMetrics, InterpolatedGroundTruthPairsAFrameBetweenItsSamples) {
  const auto pose = [](double t) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.linear() = Eigen::AngleAxisd(0.5 * t, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    p.translation() = Eigen::Vector3d(std::cos(0.5 * t), std::sin(0.5 * t), 0.1 * t);
    return p;
  };
  Trajectory gt, estimate;
  for (int i = 0; i <= 300; ++i) gt.Add(0.01 * i, pose(0.01 * i));
  for (int i = 0; i < 80; ++i) estimate.Add(0.0037 + i / 30.0, pose(0.0037 + i / 30.0));
  const AteResult interpolated = ComputeAte(estimate, gt);
  const AteResult nearest = ComputeAte(estimate, gt, 0.02, AteAssociation::kNearest);
  EXPECT_EQ(interpolated.pairs, 80u);
  EXPECT_LT(interpolated.rmse, 1e-5);
  EXPECT_GT(nearest.rmse, 5e-4);
  // An estimate beyond the ground truth's end pairs with its last pose when it is near enough.
  Trajectory past;
  for (int i = 0; i < 3; ++i) past.Add(3.005 + 0.001 * i, pose(3.0));
  EXPECT_LT(ComputeAte(past, gt).rmse, 1e-9);
}

}  // namespace
}  // namespace genscene
