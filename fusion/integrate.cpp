#include "fusion/integrate.h"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <iterator>

#include "core/check.h"
#include "core/parallel.h"

namespace genscene::fusion {
namespace {

// Four floats and their comparison masks (lanes all ones or zero) as GCC vector types, which
// GCC and clang compile to one SSE or NEON register.
typedef float Row4 __attribute__((vector_size(16)));
typedef int Mask4 __attribute__((vector_size(16)));
static_assert(sizeof(TsdfVoxel) == 2 * sizeof(float), "two voxels are one Row4");

struct KeyLess {
  bool operator()(const Eigen::Vector3i& a, const Eigen::Vector3i& b) const {
    if (a.z() != b.z()) return a.z() < b.z();
    if (a.y() != b.y()) return a.y() < b.y();
    return a.x() < b.x();
  }
};

}  // namespace

std::vector<Eigen::Vector3i> BlocksInTruncationBand(const TsdfVolume& volume,
                                                    const ImageDepth& depth,
                                                    const CameraIntrinsics& k,
                                                    const Eigen::Isometry3d& world_from_camera,
                                                    int pixel_stride) {
  GS_CHECK_GE(pixel_stride, 1);
  const int w = depth.width(), h = depth.height();
  const double vs = volume.voxel_size();
  // Lattice coordinates of camera-frame points: L(p) = R' p + c, with R' = R / voxel_size and
  // c = (t - origin) / voxel_size in double, then float for the per-pixel work (the origin sits
  // near the cameras, so these numbers stay small even 1 km from the world origin).
  const Eigen::Matrix3f rotation = (world_from_camera.linear() / vs).cast<float>();
  const Eigen::Vector3f centre =
      volume.WorldToLattice(world_from_camera.translation()).cast<float>();
  const float trunc = static_cast<float>(volume.truncation());
  const float block_metres = static_cast<float>(kTsdfBlockSide * vs);
  const float inv_side = 1.0f / kTsdfBlockSide;

  // Per pixel, samples half a block apart along the ray over the band, a truncation either side
  // of the surface along the ray: planar depths [d - trunc / lambda, d + trunc / lambda], lambda =
  // |(x, y, 1)|. The count does not depend on lambda.
  const int samples = static_cast<int>(std::ceil(4.0f * trunc / block_metres)) + 1;
  std::vector<float> ray_x(static_cast<size_t>(w));
  for (int u = 0; u < w; ++u) ray_x[static_cast<size_t>(u)] = static_cast<float>((u - k.cx) / k.fx);

  const int rows = (h + pixel_stride - 1) / pixel_stride;
  std::vector<std::vector<Eigen::Vector3i>> per_row(static_cast<size_t>(rows));
  ParallelFor(
      0, static_cast<size_t>(rows),
      [&](size_t r) {
        const int v = static_cast<int>(r) * pixel_stride;
        const float ray_y = static_cast<float>((v - k.cy) / k.fy);
        std::vector<Eigen::Vector3i>& keys = per_row[r];
        // Neighbouring pixels' bands pass through the same few blocks: a key already pushed for
        // this row is remembered in one of 64 slots (by its coordinates modulo 4), so the row's
        // list holds few repeats (on the synthetic room 320x240: 91 keys a row, none repeated).
        std::array<Eigen::Vector3i, 64> recent;
        for (Eigen::Vector3i& key : recent) key.setConstant(INT_MIN);
        for (int u = 0; u < w; u += pixel_stride) {
          const float d = depth(u, v);
          if (d <= 0.0f) continue;
          const Eigen::Vector3f ray(ray_x[static_cast<size_t>(u)], ray_y, 1.0f);
          const Eigen::Vector3f dir = rotation * ray;  // lattice units per metre of planar depth
          const float inv_lambda = 1.0f / ray.norm();
          const float band = trunc * inv_lambda;
          const float step = 0.5f * block_metres * inv_lambda;
          for (int s = 0; s < samples; ++s) {
            const float z = std::min(d + band, d - band + step * static_cast<float>(s));
            if (z <= 0.0f) continue;
            const Eigen::Vector3f lattice = centre + z * dir;
            const Eigen::Vector3i key(FloorToInt(lattice.x() * inv_side),
                                      FloorToInt(lattice.y() * inv_side),
                                      FloorToInt(lattice.z() * inv_side));
            Eigen::Vector3i& slot =
                recent[(key.x() & 3) | ((key.y() & 3) << 2) | ((key.z() & 3) << 4)];
            if (slot != key) {
              slot = key;
              keys.push_back(key);
            }
          }
        }
        std::sort(keys.begin(), keys.end(), KeyLess());
        keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
      },
      4);
  // Pairwise merges of the rows' sorted lists, each level's pairs in parallel (a fixed tree, so
  // the same result with any thread count): 0.3 ms a frame against 1.2 ms for one sort of all.
  while (per_row.size() > 1) {
    std::vector<std::vector<Eigen::Vector3i>> merged((per_row.size() + 1) / 2);
    ParallelFor(
        0, merged.size(),
        [&](size_t i) {
          if (2 * i + 1 == per_row.size()) {
            merged[i] = std::move(per_row[2 * i]);
            return;
          }
          const auto& a = per_row[2 * i];
          const auto& b = per_row[2 * i + 1];
          merged[i].reserve(a.size() + b.size());
          std::set_union(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(merged[i]),
                         KeyLess());
        },
        1);
    per_row = std::move(merged);
  }
  return per_row.empty() ? std::vector<Eigen::Vector3i>() : std::move(per_row.front());
}

IntegrationStats IntegrateFrame(TsdfVolume& volume, const ImageDepth& depth, const ImageRgb& color,
                                const CameraIntrinsics& k,
                                const Eigen::Isometry3d& world_from_camera,
                                const IntegrationOptions& options) {
  if (!depth.SameSize(k.width, k.height)) {
    throw Error(Format("IntegrateFrame: depth ", depth.width(), "x", depth.height(),
                       " but intrinsics say ", k.width, "x", k.height));
  }
  const bool with_color = !color.empty();
  if (with_color && !color.SameSize(depth)) {
    throw Error(Format("IntegrateFrame: colour ", color.width(), "x", color.height(), " but depth ",
                       depth.width(), "x", depth.height()));
  }
  IntegrationStats stats;
  const std::vector<Eigen::Vector3i> keys =
      BlocksInTruncationBand(volume, depth, k, world_from_camera, options.allocation_stride);
  stats.blocks_touched = keys.size();
  // One look-up per key: found blocks keep their index, the missing ones are counted (for the
  // memory cap, checked before anything is allocated) and allocated after.
  std::vector<int32_t> indices(keys.size(), -1);
  ParallelFor(
      0, keys.size(),
      [&](size_t i) {
        if (const auto found = volume.FindBlock(keys[i])) indices[i] = *found;
      },
      256);
  const size_t missing = static_cast<size_t>(std::count(indices.begin(), indices.end(), -1));
  const double cap = volume.params().memory_cap_bytes;
  if (cap > 0 &&
      volume.allocated_bytes() + static_cast<double>(missing) * sizeof(TsdfBlock) > cap) {
    throw Error(Format("TSDF volume: memory cap of ", cap / 1e6, " MB exceeded: this frame needs ",
                       missing, " more blocks on top of ", volume.num_blocks(), " (",
                       sizeof(TsdfBlock), " bytes each) at voxel size ", volume.voxel_size(),
                       " m; use a larger voxel size or raise the memory cap"));
  }
  for (size_t i = 0; i < keys.size(); ++i) {
    if (indices[i] < 0) indices[i] = volume.AllocateBlock(keys[i]);
  }
  stats.blocks_allocated = missing;

  // Camera-frame point of lattice point v: R^T (origin + vs v - t) = A v + b.
  const Eigen::Isometry3d camera_from_world = world_from_camera.inverse();
  const Eigen::Matrix3d a = camera_from_world.linear() * volume.voxel_size();
  const Eigen::Vector3d b = camera_from_world * volume.origin();
  const Eigen::Matrix3f a_f = a.cast<float>();
  const float fx = static_cast<float>(k.fx), fy = static_cast<float>(k.fy);
  const float cx = static_cast<float>(k.cx), cy = static_cast<float>(k.cy);
  const float trunc = static_cast<float>(volume.truncation());
  const float max_weight = volume.params().max_weight;
  const float wf = static_cast<float>(depth.width()), hf = static_cast<float>(depth.height());

  const float* depth_pixels = depth.pixels().data();
  const Eigen::Vector3f* color_pixels = with_color ? color.pixels().data() : nullptr;
  const int w = depth.width();
  std::vector<size_t> updated(keys.size(), 0);
  ParallelFor(
      0, keys.size(),
      [&](size_t i) {
        // Local copies of the frame's constants: the closure's references would be reloaded after
        // every float store (a store to a voxel may alias them as far as the compiler knows).
        const float* const depth_at = depth_pixels;
        const Eigen::Vector3f* const color_at = color_pixels;
        const int width = w;
        const float fx_l = fx, fy_l = fy, cx_l = cx, cy_l = cy, wf_l = wf, hf_l = hf;
        const float trunc_l = trunc, max_weight_l = max_weight;
        const bool noise_weights = options.noise_weights;
        const Eigen::Matrix3f a_l = a_f;
        TsdfBlock& block = volume.block(static_cast<size_t>(indices[i]));
        const char* next_block =
            i + 1 < keys.size()
                ? reinterpret_cast<const char*>(&volume.block(static_cast<size_t>(indices[i + 1])))
                : nullptr;
        const Eigen::Vector3f base =
            (a * (kTsdfBlockSide * keys[i]).cast<double>() + b).cast<float>();
        const Eigen::Vector3f dx = a_l.col(0);  // camera-frame step of one voxel along x
        size_t count = 0;
        for (int z = 0; z < kTsdfBlockSide; ++z) {
          for (int y = 0; y < kTsdfBlockSide; ++y) {
            // A row of eight voxels: the projection as plain arrays, which the compiler turns into
            // SIMD (divisions and square roots four at a time), then the pixels' depths (one by
            // one), then integrate.h's kernel four voxels at a time, then the colours.
            const Eigen::Vector3f row = base + a_l * Eigen::Vector3f(0.0f, y, z);
            // The blocks lie scattered in memory, and the hardware prefetcher starts over on each
            // (4 KB of distances and weights, 6 KB of colours): every row fetches ahead the same
            // row of the next block. Synthetic room 320x240, 1 thread, integration 54-62 -> 63-65
            // fps.
            if (next_block) {
              const int r = y + kTsdfBlockSide * z;
              __builtin_prefetch(next_block + offsetof(TsdfBlock, voxels) + 64 * r, 1);
              __builtin_prefetch(next_block + offsetof(TsdfBlock, colors) + 96 * r, 1);
              __builtin_prefetch(next_block + offsetof(TsdfBlock, colors) + 96 * r + 64, 1);
            }
            float pz[kTsdfBlockSide], uf[kTsdfBlockSide], vf[kTsdfBlockSide],
                lambda[kTsdfBlockSide];
            for (int x = 0; x < kTsdfBlockSide; ++x) {
              const float px = row.x() + x * dx.x(), py = row.y() + x * dx.y();
              pz[x] = row.z() + x * dx.z();
              const float inv_z = 1.0f / pz[x];
              const float rx = px * inv_z, ry = py * inv_z;  // the voxel's ray, (rx, ry, 1)
              uf[x] = fx_l * rx + cx_l + 0.5f;
              vf[x] = fy_l * ry + cy_l + 0.5f;
              lambda[x] = std::sqrt(1.0f + rx * rx + ry * ry);
            }
            float d[kTsdfBlockSide];
            int pixel[kTsdfBlockSide];
            for (int x = 0; x < kTsdfBlockSide; ++x) {
              d[x] = 0.0f;
              pixel[x] =
                  0;  // a valid index for the colour pass, which leaves such voxels unchanged
              // Nearest pixel: footprints are [u - 0.5, u + 0.5); the range test comes before the
              // integer conversion (which truncates, equal to floor for non-negative values).
              if (!(pz[x] > 0.0f && uf[x] >= 0.0f && vf[x] >= 0.0f && uf[x] < wf_l &&
                    vf[x] < hf_l)) {
                continue;
              }
              pixel[x] = static_cast<int>(vf[x]) * width + static_cast<int>(uf[x]);
              d[x] = depth_at[pixel[x]];
            }
            // The update, four voxels at a time as GCC vector types: two voxels (sdf, weight, sdf,
            // weight) per 16-byte load, split into distances and weights by shuffles, and merged
            // back the same way; kept voxels are written back unchanged. As scalar code the
            // compiler kept a division per voxel (two with noise weights) and a branch per voxel
            // store.
            TsdfVoxel* voxels = &block.voxels[TsdfBlock::Index(0, y, z)];
            // The colour's running average as keep * c + take * observed, times scale: for the
            // voxels it leaves alone (outside the band, hidden, unobserved) 1, 0 and 1 with black
            // for the observed colour (not their pixel's, which may be NaN in an EXR), which gives
            // c exactly, so the colour pass has no branch per voxel (branches on whether a voxel is
            // in the band were mispredicted; 1 thread 74-80 -> 84-86 fps).
            alignas(16) float keep[kTsdfBlockSide], take[kTsdfBlockSide], scale[kTsdfBlockSide];
            alignas(16) int coloured[kTsdfBlockSide];
            Mask4 any_colour = Mask4{};
            for (int h = 0; h < kTsdfBlockSide; h += 4) {
              Row4 lo, hi;
              std::memcpy(&lo, &voxels[h], sizeof(lo));
              std::memcpy(&hi, &voxels[h + 2], sizeof(hi));
              const Row4 sdf_old = __builtin_shufflevector(lo, hi, 0, 2, 4, 6);
              const Row4 weight_old = __builtin_shufflevector(lo, hi, 1, 3, 5, 7);
              const Row4 dv = {d[h], d[h + 1], d[h + 2], d[h + 3]};
              Row4 pzv, lambdav;
              std::memcpy(&pzv, &pz[h], sizeof(pzv));
              std::memcpy(&lambdav, &lambda[h], sizeof(lambdav));
              Row4 w = Row4{} + 1.0f;
              if (noise_weights) w = ObservationWeight(dv);
              const Row4 e = (dv - pzv) * lambdav;
              const Mask4 upd = (dv > 0.0f) & (e >= -trunc_l);  // not hidden behind the surface
              const Row4 sdf_obs = e < trunc_l ? e : Row4{} + trunc_l;
              const Row4 w_new = weight_old + w;
              const Row4 inv = 1.0f / w_new;
              const Row4 sdf = (weight_old * sdf_old + w * sdf_obs) * inv;
              const Row4 sdf_out = upd ? sdf : sdf_old;
              const Row4 weight_out =
                  upd ? (w_new < max_weight_l ? w_new : Row4{} + max_weight_l) : weight_old;
              lo = __builtin_shufflevector(sdf_out, weight_out, 0, 4, 1, 5);
              hi = __builtin_shufflevector(sdf_out, weight_out, 2, 6, 3, 7);
              std::memcpy(static_cast<void*>(&voxels[h]), &lo, sizeof(lo));
              std::memcpy(static_cast<void*>(&voxels[h + 2]), &hi, sizeof(hi));
              // Colour only inside the band: the colour of free space in front of a surface is not
              // its colour.
              const Mask4 colour = upd & (e < trunc_l);
              const Row4 keep_v = colour ? weight_old : Row4{} + 1.0f;
              const Row4 take_v = colour ? w : Row4{};
              const Row4 scale_v = colour ? inv : Row4{} + 1.0f;
              std::memcpy(&keep[h], &keep_v, sizeof(keep_v));
              std::memcpy(&take[h], &take_v, sizeof(take_v));
              std::memcpy(&scale[h], &scale_v, sizeof(scale_v));
              std::memcpy(&coloured[h], &colour, sizeof(colour));
              count +=
                  static_cast<size_t>(-(upd[0] + upd[1] + upd[2] + upd[3]));  // true lanes are -1
              any_colour |= colour;
            }
            if (!color_at || !(any_colour[0] | any_colour[1] | any_colour[2] | any_colour[3]))
              continue;
            Eigen::Vector3f* colours =
                &block.colors[static_cast<size_t>(TsdfBlock::Index(0, y, z))];
            for (int x = 0; x < kTsdfBlockSide; ++x) {
              // The observed colour's bits and the lane's mask (all ones or zero): black without a
              // branch (a select here cost 8 %).
              const float* pixel_colour = color_at[pixel[x]].data();
              Eigen::Vector3f observed;
              for (int c = 0; c < 3; ++c) {
                uint32_t bits;
                std::memcpy(&bits, &pixel_colour[c], sizeof(bits));
                bits &= static_cast<uint32_t>(coloured[x]);
                std::memcpy(&observed[c], &bits, sizeof(bits));
              }
              colours[x] = (keep[x] * colours[x] + take[x] * observed) * scale[x];
            }
          }
        }
        updated[i] = count;
      },
      8);
  for (size_t c : updated) stats.voxels_updated += c;
  return stats;
}

}  // namespace genscene::fusion
