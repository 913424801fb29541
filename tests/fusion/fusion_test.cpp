// Fusion on analytic scenes (core/synthetic.h): exact depth, known poses, closed-form surfaces.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <tuple>

#include "core/parallel.h"
#include "core/rng.h"
#include "core/se3.h"
#include "core/synthetic.h"
#include "core/trajectory_metrics.h"
#include "fusion/keyframes.h"
#include "fusion/kinect_fusion.h"
#include "tests/test_util.h"

namespace genscene::fusion {
namespace {

CameraIntrinsics Camera(int width, int height) {
  return CameraIntrinsics::Centered(width, height, 0.9 * width);
}

// The Cornell-like room of core/synthetic.h, translated by `offset`.
SyntheticScene Room(const Eigen::Vector3d& offset = Eigen::Vector3d::Zero()) {
  SyntheticScene scene = MakeCornellScene();
  scene.room->bounds.translate(offset);
  for (auto& box : scene.boxes) box.bounds.translate(offset);
  for (auto& sphere : scene.spheres) sphere.center += offset;
  scene.light_position += offset;
  return scene;
}

Trajectory Orbit(int frames, const Eigen::Vector3d& offset = Eigen::Vector3d::Zero()) {
  const Trajectory t = MakeHandheldTrajectory(Eigen::Vector3d(0.0, 0.0, 0.6) + offset, 0.9,
                                              1.0 + offset.z(), 40.0, frames, 7);
  return t;
}

std::vector<RgbdFrame> Render(const SyntheticScene& scene, const Trajectory& trajectory,
                              const CameraIntrinsics& k) {
  std::vector<RgbdFrame> frames;
  for (const StampedPose& p : trajectory.poses()) {
    frames.push_back(RenderSyntheticFrame(scene, k, p.world_from_camera, p.timestamp));
  }
  return frames;
}

FusionOptions DefaultOptions() {
  FusionOptions o;
  o.voxel_size = 0.02;
  o.truncation = 0.08;
  return o;
}

struct FusionRun {
  std::unique_ptr<KinectFusion> fusion;
  std::map<FrameStatus, int> counts;
};

FusionRun Fuse(const std::vector<RgbdFrame>& frames, const FusionOptions& options) {
  FusionRun run;
  run.fusion = std::make_unique<KinectFusion>(options, frames.front().intrinsics);
  for (const RgbdFrame& f : frames) ++run.counts[run.fusion->ProcessFrame(f).status];
  run.fusion->Finish();
  return run;
}

Trajectory GroundTruth(const std::vector<RgbdFrame>& frames) {
  Trajectory t;
  for (const RgbdFrame& f : frames) t.Add(f.timestamp, *f.world_from_camera);
  return t;
}

// A tracked frame for the keyframe selector: a pose along x, a checkerboard whose contrast
// (sharpness) is `contrast`, its index in the time stamp.
RgbdFrame KeyframeCandidate(int index, double x, float contrast = 1.0f) {
  RgbdFrame f;
  f.timestamp = index;
  f.color = ImageRgb(16, 12);
  for (int v = 0; v < 12; ++v) {
    for (int u = 0; u < 16; ++u)
      f.color(u, v) = Eigen::Vector3f::Constant(0.5f + 0.5f * contrast * (((u + v) % 2) - 0.5f));
  }
  f.world_from_camera = Eigen::Isometry3d(Eigen::Translation3d(x, 0, 0));
  return f;
}

std::vector<double> KeyframeTimes(const KeyframeSelector& s) {
  std::vector<double> t;
  for (const RgbdFrame& f : s.keyframes()) t.push_back(f.timestamp);
  return t;
}

// Frames 0.5 m apart (a sparse multi-view recording): every one is a view of its own, not the
// sharpest of a window of five.
TEST(Keyframes, SparseRecordingKeepsEveryDistantView) {
  KeyframeSelector s(KeyframeOptions{});
  for (int i = 0; i < 5; ++i) s.Offer(KeyframeCandidate(i, 0.5 * i, i == 2 ? 0.5f : 1.0f));
  s.Finish();
  EXPECT_EQ(KeyframeTimes(s), (std::vector<double>{0, 1, 2, 3, 4}));
}

// Nine frames within 2 cm (a short recording): at least min_keyframes views, spread over it, in
// the recording's order.
TEST(Keyframes, ShortRecordingGetsMinKeyframesSpreadOverIt) {
  KeyframeSelector s(KeyframeOptions{});
  for (int i = 0; i < 9; ++i) s.Offer(KeyframeCandidate(i, 0.002 * i));
  s.Finish();
  const std::vector<double> t = KeyframeTimes(s);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
  EXPECT_EQ(t.front(), 0.0);  // the first window's sharpest (all alike: the first)
  EXPECT_EQ(t.back(), 8.0);   // the farthest from it
  EXPECT_NEAR(t[1], 4.0, 1.0);
  EXPECT_EQ(s.sharpness().size(), 3u);
}

// A long steady recording: a keyframe every 0.15 m, the sharpest of its window, and the held
// candidates never exceed their bound (the recording is 400 frames).
TEST(Keyframes, LongRecordingKeyframesFollowTheMotionAndSharpness) {
  KeyframeSelector s(KeyframeOptions{});
  for (int i = 0; i < 400; ++i) s.Offer(KeyframeCandidate(i, 0.01 * i, i % 5 == 2 ? 1.0f : 0.5f));
  s.Finish();
  const std::vector<double> t = KeyframeTimes(s);
  EXPECT_GE(t.size(), 20u);  // 4 m at 0.15 m, each window at most 5 frames
  EXPECT_LE(t.size(), 27u);
  // The sharp frames win every full window (the recording's end may cut the last one short).
  for (size_t k = 0; k < t.size(); ++k) {
    if (t[k] < 400 - 5) {
      EXPECT_EQ(static_cast<int>(t[k]) % 5, 2)
          << "keyframe " << k << " of " << t.size() << ": frame " << t[k];
    }
  }
}

// A close-range slide (a plane 0.25 m away, 0.8 cm a frame, 13.6 cm in all: never the 15 cm that
// makes a keyframe due by motion): a second keyframe once about a third of the view is surface the
// first did not see; without the new-surface rule, the first alone.
TEST(Keyframes, CloseRangeSlideGetsAKeyframeForTheNewSurface) {
  for (const double new_surface : {0.3, 0.0}) {
    KeyframeOptions o;
    o.new_surface = new_surface;
    o.window = 1;
    o.min_keyframes = 1;
    KeyframeSelector s(o);
    for (int i = 0; i < 18; ++i) {
      RgbdFrame f = KeyframeCandidate(i, 0.008 * i);
      f.intrinsics.width = 16, f.intrinsics.height = 12, f.intrinsics.fx = f.intrinsics.fy = 12.0;
      f.intrinsics.cx = 7.5, f.intrinsics.cy = 5.5;
      f.depth = ImageDepth(16, 12, 0.25f);
      s.Offer(f);
    }
    s.Finish();
    const std::vector<double> t = KeyframeTimes(s);
    if (new_surface == 0.0) {
      EXPECT_EQ(t, std::vector<double>{0.0});
      continue;
    }
    // The view is 0.33 m wide there: 30 % new after 10 cm, at frame 13.
    ASSERT_EQ(t.size(), 2u);
    EXPECT_EQ(t[0], 0.0);
    EXPECT_NEAR(t[1], 13.0, 1.0);
  }
}

// min_keyframes is validated against max_keyframes.
TEST(Keyframes, MinAboveMaxIsAClearError) {
  KeyframeOptions o;
  o.min_keyframes = 10;
  o.max_keyframes = 5;
  EXPECT_CONTAINS(test::ErrorOf([&] { o.Validate(); }),
                  "min_keyframes = 10 exceeds max_keyframes = 5");
}

TEST(Preprocess, MasksInvalidDepthAndKeepsEdgesSharp) {
  ImageDepth depth(8, 4, 1.0f);
  depth(0, 0) = std::numeric_limits<float>::quiet_NaN();
  depth(1, 0) = std::numeric_limits<float>::infinity();
  depth(2, 0) = -1.0f;
  depth(3, 0) = 50.0f;
  depth(4, 0) = 0.0f;
  for (int v = 0; v < 4; ++v) depth(7, v) = 2.0f;  // a step of 1 m
  MaskStats stats;
  const ImageDepth masked = MaskInvalidDepth(depth, 0.1, 6.0, &stats);
  EXPECT_EQ(stats.non_finite, 2u);
  EXPECT_EQ(stats.out_of_range, 2u);
  EXPECT_EQ(stats.zero, 1u);
  EXPECT_EQ(stats.valid, 27u);
  for (int u = 0; u < 5; ++u) EXPECT_EQ(masked(u, 0), 0.0f);
  const ImageDepth filtered = BilateralFilterDepth(masked, 2, 1.5, 0.03);
  EXPECT_FLOAT_EQ(filtered(6, 2), 1.0f);  // no blur across the 1 m step
  EXPECT_FLOAT_EQ(filtered(7, 2), 2.0f);
  EXPECT_EQ(filtered(0, 0), 0.0f);  // invalid stays invalid
}

// The window is clipped at the image's border. The same depth inside a frame of invalid pixels
// (which contribute nothing) puts every pixel's whole window inside the larger image: the filter
// must give the same values, bit for bit, with and without the clipping.
TEST(Preprocess, BilateralFilterAtTheBorderIsTheFilterOfTheImageFramedByInvalidPixels) {
  constexpr int kW = 23, kH = 17, kFrame = 3;
  CounterRng rng(11, 0);
  ImageDepth depth(kW, kH), framed(kW + 2 * kFrame, kH + 2 * kFrame);
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      // A slanted plane with noise, a step and holes.
      float z = 1.0f + 0.01f * u + 0.02f * static_cast<float>(rng.Uniform());
      if (u > 15) z += 0.5f;
      if (rng.Uniform() < 0.1) z = 0.0f;
      depth(u, v) = z;
      framed(u + kFrame, v + kFrame) = z;
    }
  }
  for (int radius : {1, 2, 3}) {
    const ImageDepth a = BilateralFilterDepth(depth, radius, 1.5, 0.03);
    const ImageDepth b = BilateralFilterDepth(framed, radius, 1.5, 0.03);
    int smoothed = 0;
    for (int v = 0; v < kH; ++v) {
      for (int u = 0; u < kW; ++u) {
        ASSERT_EQ(a(u, v), b(u + kFrame, v + kFrame))
            << "radius " << radius << " at " << u << ", " << v;
        smoothed += a(u, v) != depth(u, v);
      }
    }
    EXPECT_GT(smoothed, kW * kH / 2) << "radius " << radius;
  }
}

TEST(Preprocess, NormalsOfAPlaneFaceTheCamera) {
  const CameraIntrinsics k = Camera(80, 60);
  ImageDepth depth(80, 60);
  // Plane z = 1 + 0.5 x seen by the camera: planar depth solves z = 1 + 0.5 z (u - cx) / fx.
  for (int v = 0; v < 60; ++v)
    for (int u = 0; u < 80; ++u)
      depth(u, v) = static_cast<float>(1.0 / (1.0 - 0.5 * (u - k.cx) / k.fx));
  const auto pyramid = BuildPyramid(depth, k, PreprocessOptions());
  ASSERT_EQ(pyramid.size(), 3u);
  EXPECT_EQ(pyramid[2].depth.width(), 20);
  const Eigen::Vector3f expected = Eigen::Vector3f(0.5f, 0.0f, -1.0f).normalized();
  for (const auto& level : pyramid) {
    const Eigen::Vector3f n = level.normals(level.normals.width() / 2, level.normals.height() / 2);
    EXPECT_GT(n.dot(expected), 0.9999f) << n.transpose();
  }
}

// A TSDF fused from exact depth maps of an analytic sphere and box; the raycast
// surface lies within 0.5 voxel of the truth. Within a truncation distance of the box's edges the
// projective TSDF bulges (a known limit of projective distances, KinectFusion's too): those pixels
// are counted and bounded separately.
TEST(Fusion, RaycastOfSphereAndBoxIsWithinHalfAVoxel) {
  SyntheticScene scene;
  scene.spheres.push_back({Eigen::Vector3d(0.0, 0.0, 0.5), 0.3, Eigen::Vector3f(0.8f, 0.2f, 0.2f)});
  scene.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(0.4, -0.3, 0.0), Eigen::Vector3d(0.8, 0.1, 0.35)),
       Eigen::Vector3f(0.2f, 0.8f, 0.2f)});
  const CameraIntrinsics k = Camera(160, 120);
  const Trajectory trajectory =
      MakeOrbitTrajectory(Eigen::Vector3d(0.2, 0.0, 0.3), 1.4, 1.0, 300.0, 24);
  FusionOptions options = DefaultOptions();
  options.voxel_size = 0.01;
  options.truncation = 0.04;
  options.tracking = "known";
  const FusionRun run = Fuse(Render(scene, trajectory, k), options);
  EXPECT_EQ(run.counts.at(FrameStatus::kKnownPose), 24);
  double worst = 0.0, worst_near_edges = 0.0;
  size_t hits = 0, near_edges = 0;
  const Eigen::AlignedBox3d& box = scene.boxes[0].bounds;
  for (const StampedPose& pose : {trajectory.poses()[3], trajectory.poses()[15]}) {
    const RaycastResult r = RaycastVolume(run.fusion->volume(), k, pose.world_from_camera);
    for (int v = 0; v < k.height; ++v) {
      for (int u = 0; u < k.width; ++u) {
        if (r.depth(u, v) <= 0.0f) continue;
        const Eigen::Vector3d p = pose.world_from_camera * r.points(u, v).cast<double>();
        const double d_sphere = std::abs((p - scene.spheres[0].center).norm() - 0.3);
        const Eigen::Vector3d q = (p - box.center()).cwiseAbs() - 0.5 * box.sizes();
        const double d_box = std::abs(q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0));
        const double error = std::min(d_sphere, d_box);
        // Near an edge: within a truncation of two of the box's face planes.
        const int close_faces = (q.array().abs() < options.truncation).count();
        if (d_box < d_sphere && close_faces >= 2) {
          worst_near_edges = std::max(worst_near_edges, error);
          ++near_edges;
        } else {
          worst = std::max(worst, error);
        }
        ++hits;
      }
    }
  }
  std::cout << "raycast: " << hits << " surface pixels, worst distance to the true surface "
            << worst / options.voxel_size << " voxel; " << near_edges
            << " pixels near box edges, worst " << worst_near_edges / options.voxel_size
            << " voxel\n";
  EXPECT_GT(hits, 5000u);
  EXPECT_LT(near_edges, hits / 5);
  EXPECT_LT(worst, 0.5 * options.voxel_size);
  EXPECT_LT(worst_near_edges, options.truncation);
}

TEST(Fusion, TracksTheRoomWithExactDepth) {
  const std::vector<RgbdFrame> frames = Render(Room(), Orbit(40), Camera(160, 120));
  const FusionRun run = Fuse(frames, DefaultOptions());
  EXPECT_EQ(run.counts.at(FrameStatus::kTracked), 39);
  const AteResult ate = ComputeAte(run.fusion->trajectory(), GroundTruth(frames));
  std::cout << "room, 40 frames 160x120, exact depth: ATE " << 100 * ate.rmse << " cm\n";
  EXPECT_LT(ate.rmse, 0.01);
  EXPECT_GE(run.fusion->keyframes().size(), 2u);
  // Memory follows the surface: the room's walls, not its 2 x 2 x 2 m bounding volume.
  const double bounding_blocks = std::pow(2.0 / (8 * 0.02), 3);
  std::cout << "allocated " << run.fusion->volume().num_blocks()
            << " blocks; the bounding volume holds " << bounding_blocks << "\n";
  EXPECT_LT(run.fusion->volume().num_blocks(), bounding_blocks);
}

// The model raycast at half resolution (model_subsample 0 picks 2 up to 320 pixels wide: a
// quarter of the rays) and at full resolution both track every frame of the room; the raycast
// has the size asked for.
TEST(Fusion, TracksTheRoomWithTheModelAtHalfAndFullResolution) {
  const std::vector<RgbdFrame> frames = Render(Room(), Orbit(40), Camera(160, 120));
  FusionOptions o = DefaultOptions();
  EXPECT_EQ(o.model_subsample, 0);
  EXPECT_EQ(o.ModelSubsample(160), 2);
  EXPECT_EQ(o.ModelSubsample(320), 2);
  EXPECT_EQ(o.ModelSubsample(640), 4);
  EXPECT_EQ(o.ModelSubsample(1280), 8);
  for (int subsample : {2, 1}) {
    o.model_subsample = subsample;
    const FusionRun run = Fuse(frames, o);
    EXPECT_EQ(run.counts.at(FrameStatus::kTracked), 39);
    EXPECT_EQ(run.fusion->model().depth.width(), 160 / subsample);
    EXPECT_EQ(run.fusion->model().depth.height(), 120 / subsample);
    const AteResult ate = ComputeAte(run.fusion->trajectory(), GroundTruth(frames));
    std::cout << "room, 40 frames 160x120, model 1/" << subsample << ": ATE " << 100 * ate.rmse
              << " cm\n";
    EXPECT_LT(ate.rmse, 0.01);
  }
  o.model_subsample = 9;
  EXPECT_CONTAINS(test::ErrorOf([&] { o.Validate(); }), "model_subsample");
}

// Tracking on a pyramid that starts at 1/2 or 1/4 of the depth's resolution (tracking_subsample,
// by default the largest that keeps the finest level >= 320 pixels wide): the depth pyramid's
// first level is the masked depth reduced by DownsampleDepth, unfiltered, with intrinsics to
// match; the brightness pyramid's levels are the full pyramid's from the same level on, bit for
// bit (noise included); and the room is tracked as well from the reduced levels.
TEST(Fusion, TracksOnAPyramidThatStartsBelowFullResolution) {
  FusionOptions o = DefaultOptions();
  EXPECT_EQ(o.tracking_subsample, 0);
  EXPECT_EQ(o.TrackingSubsample(160), 1);
  EXPECT_EQ(o.TrackingSubsample(320), 1);
  EXPECT_EQ(o.TrackingSubsample(639), 1);
  EXPECT_EQ(o.TrackingSubsample(640), 2);
  EXPECT_EQ(o.TrackingSubsample(1280), 4);
  EXPECT_EQ(o.TrackingSubsample(4096), 4);

  const std::vector<RgbdFrame> frames = Render(Room(), Orbit(40), Camera(160, 120));
  const RgbdFrame& f = frames[5];
  const ImageDepth masked = MaskInvalidDepth(f.depth, 0.1, 6.0);
  const std::vector<PyramidLevel> half = BuildPyramid(masked, f.intrinsics, o.preprocess, 2);
  ASSERT_EQ(half.size(), 3u);
  const ImageDepth reduced = DownsampleDepth(masked, o.preprocess.bilateral_sigma_depth);
  ASSERT_TRUE(half[0].depth.SameSize(80, 60));
  EXPECT_EQ(half[0].depth.pixels(), reduced.pixels());
  EXPECT_DOUBLE_EQ(half[0].intrinsics.fx, f.intrinsics.Scaled(0.5).fx);
  EXPECT_DOUBLE_EQ(half[0].intrinsics.cx, f.intrinsics.Scaled(0.5).cx);
  EXPECT_TRUE(half[2].depth.SameSize(20, 15));
  const std::vector<IntensityLevel> full = BuildIntensityPyramid(f.color, 4);
  for (int subsample : {2, 4}) {
    const std::vector<IntensityLevel> part = BuildIntensityPyramid(f.color, 2, subsample);
    ASSERT_EQ(part.size(), 2u);
    const size_t skip = subsample == 2 ? 1 : 2;
    for (size_t l = 0; l < part.size(); ++l) {
      EXPECT_EQ(part[l].intensity.pixels(), full[l + skip].intensity.pixels());
      EXPECT_EQ(part[l].grad_u.pixels(), full[l + skip].grad_u.pixels());
      EXPECT_EQ(part[l].grad_v.pixels(), full[l + skip].grad_v.pixels());
      EXPECT_EQ(part[l].noise, full[l + skip].noise);
    }
  }
  o.tracking_subsample = 2;
  const FusionRun run = Fuse(frames, o);
  EXPECT_EQ(run.counts.at(FrameStatus::kTracked), 39);
  const AteResult ate = ComputeAte(run.fusion->trajectory(), GroundTruth(frames));
  std::cout << "room, 40 frames 160x120 tracked at 80x60: ATE " << 100 * ate.rmse << " cm\n";
  EXPECT_LT(ate.rmse, 0.01);
  o.tracking_subsample = 3;
  EXPECT_CONTAINS(test::ErrorOf([&] { o.Validate(); }), "tracking_subsample");
}

// Blocks allocated along the band of every second pixel (allocation_stride 2) are a subset of those
// every pixel's band gives, fewer, and the model seen from the cameras loses almost nothing: every
// pixel still updates the voxels of allocated blocks. The default (0) picks the stride by width.
TEST(Fusion, SparserAllocationKeepsASubsetOfTheBlocksAndTheSurface) {
  const std::vector<RgbdFrame> frames = Render(Room(), Orbit(20), Camera(160, 120));
  FusionOptions o = DefaultOptions();
  EXPECT_EQ(o.allocation_stride, 0);
  EXPECT_EQ(o.AllocationStride(160), 1);
  EXPECT_EQ(o.AllocationStride(320), 2);
  EXPECT_EQ(o.AllocationStride(640), 4);
  EXPECT_EQ(o.AllocationStride(64), 1);
  o.tracking = "known";
  o.allocation_stride = 1;
  const FusionRun every = Fuse(frames, o);
  o.allocation_stride = 2;
  const FusionRun sparse = Fuse(frames, o);
  const TsdfVolume& all = every.fusion->volume();
  const TsdfVolume& some = sparse.fusion->volume();
  for (size_t b = 0; b < some.num_blocks(); ++b) {
    ASSERT_TRUE(all.FindBlock(some.block_key(b)).has_value()) << some.block_key(b).transpose();
  }
  EXPECT_LT(some.num_blocks(), all.num_blocks());
  EXPECT_TRUE(sparse.fusion->model().depth.empty());  // known poses: no model raycast for ICP
  size_t hits_every = 0, hits_sparse = 0;
  const Eigen::Isometry3d pose = *frames[10].world_from_camera;
  const RaycastResult a = RaycastVolume(all, frames[10].intrinsics, pose);
  const RaycastResult b = RaycastVolume(some, frames[10].intrinsics, pose);
  size_t both = 0, differ = 0;
  for (size_t i = 0; i < a.depth.size(); ++i) {
    const float da = a.depth.pixels()[i], db = b.depth.pixels()[i];
    hits_every += da > 0.0f;
    hits_sparse += db > 0.0f;
    if (da > 0.0f && db > 0.0f) {
      ++both;
      differ += std::abs(da - db) > 0.5 * o.voxel_size;
    }
  }
  std::cout << "blocks " << all.num_blocks() << " (every pixel) / " << some.num_blocks()
            << " (every second); raycast hits " << hits_every << " / " << hits_sparse << "; of "
            << both << " pixels both hit, " << differ << " differ by more than half a voxel\n";
  EXPECT_GT(hits_sparse, 0.99 * hits_every);
  EXPECT_LT(differ, both / 100);
  EXPECT_EQ(o.AllocationStride(640), 2);  // a set stride is kept at every width
  o.allocation_stride = -1;
  EXPECT_CONTAINS(test::ErrorOf([&] { o.Validate(); }), "allocation_stride");
}

// The raycast's per-frame pass visits the blocks of the chunks in the frustum only: the same
// room beside a volume four times as large (blocks 30 m away, outside every frustum) gives the
// same images bit for bit and projects the same blocks, and a view that sees part of the room
// projects fewer blocks than the room holds.
TEST(Fusion, RaycastVisitsOnlyTheBlocksOfChunksInTheFrustum) {
  const std::vector<RgbdFrame> frames = Render(Room(), Orbit(12), Camera(160, 120));
  FusionOptions o = DefaultOptions();
  o.voxel_size = 0.01;
  o.truncation = 0.04;
  o.tracking = "known";
  const FusionRun run = Fuse(frames, o);
  const TsdfVolume& room = run.fusion->volume();
  TsdfVolume large = room;
  const size_t room_blocks = room.num_blocks();
  const int side = static_cast<int>(std::ceil(std::cbrt(3.0 * static_cast<double>(room_blocks))));
  for (int x = 0; x < side; ++x) {
    for (int y = 0; y < side; ++y) {
      for (int z = 0; z < side; ++z) {
        TsdfBlock& block = large.block(large.AllocateBlock(Eigen::Vector3i(375 + x, y, z)));
        for (TsdfVoxel& v : block.voxels) v = TsdfVoxel{0.0f, 1.0f};  // observed surface
      }
    }
  }
  ASSERT_GE(large.num_blocks(), 4 * room_blocks);
  const CameraIntrinsics& k = frames.front().intrinsics;
  for (const size_t f : {size_t{2}, size_t{9}}) {
    const Eigen::Isometry3d pose = *frames[f].world_from_camera;
    const RaycastResult a = RaycastVolume(room, k, pose);
    const RaycastResult b = RaycastVolume(large, k, pose);
    std::cout << "frame " << f << ": room " << room_blocks << " blocks in " << room.num_chunks()
              << " chunks, " << a.blocks_projected << " projected; large " << large.num_blocks()
              << " blocks in " << large.num_chunks() << " chunks, " << b.blocks_projected
              << " projected\n";
    EXPECT_EQ(a.chunks_tested, room.num_chunks());
    EXPECT_EQ(b.chunks_tested, large.num_chunks());
    EXPECT_EQ(a.blocks_projected, b.blocks_projected);
    EXPECT_GT(a.blocks_projected, 0u);
    ASSERT_EQ(a.depth.size(), b.depth.size());
    size_t hits = 0;
    for (size_t i = 0; i < a.depth.size(); ++i) {
      ASSERT_EQ(a.depth.pixels()[i], b.depth.pixels()[i]) << "pixel " << i;
      ASSERT_EQ(a.color.pixels()[i], b.color.pixels()[i]) << "pixel " << i;
      hits += a.depth.pixels()[i] > 0.0f;
    }
    EXPECT_GT(hits, a.depth.size() / 2);
  }
  // Looking at a corner from close by: most of the room's chunks are outside the frustum.
  const Eigen::Vector3d eye(0.0, 0.0, 0.6), target = eye + Eigen::Vector3d(0.0, 1.0, -0.3);
  const Eigen::Isometry3d close = LookAt(eye, target);
  const RaycastResult c = RaycastVolume(large, k, close);
  std::cout << "one wall: " << c.blocks_projected << " of " << large.num_blocks()
            << " blocks projected\n";
  EXPECT_LT(c.blocks_projected, room_blocks);
}

// Noise weights: a wall measured once from 0.8 m (exactly) and once from 3 m (2 cm too far, a
// typical error there) ends where the near measurement put it; uniform weights split the
// difference.
TEST(Fusion, NoiseWeightsTrustTheNearMeasurement) {
  EXPECT_NEAR(ObservationWeight(1.0f), 1.0f, 1e-6f);
  EXPECT_GT(ObservationWeight(0.5f), 2.0f);
  EXPECT_LT(ObservationWeight(3.0f), 0.02f);
  const CameraIntrinsics k = Camera(64, 48);
  for (const bool noise : {true, false}) {
    TsdfVolumeParams params;
    params.voxel_size = 0.01;
    params.truncation = 0.04;
    params.origin = Eigen::Vector3d(0.0, 0.0, 0.003);  // the wall between lattice planes
    TsdfVolume volume(params);
    IntegrationOptions options;
    options.noise_weights = noise;
    // The wall is the plane z = 0.8 m; cameras on the z axis look along +z.
    for (const double distance : {0.8, 3.0}) {
      const Eigen::Isometry3d pose(Eigen::Translation3d(0.0, 0.0, 0.8 - distance));
      ImageDepth depth(k.width, k.height);
      for (float& d : depth.pixels())
        d = static_cast<float>(distance + (distance > 1.0 ? 0.02 : 0.0));
      IntegrateFrame(volume, depth, ImageRgb(), k, pose, options);
    }
    // The fused wall's position on the optical axis: where the sdf crosses zero along z.
    const Eigen::Vector3d lattice = volume.WorldToLattice(Eigen::Vector3d(0.0, 0.0, 0.8));
    const auto before =
        volume.InterpolateSdf(Eigen::Vector3f(lattice.x(), lattice.y(), std::floor(lattice.z())));
    const auto after = volume.InterpolateSdf(
        Eigen::Vector3f(lattice.x(), lattice.y(), std::floor(lattice.z()) + 1));
    ASSERT_TRUE(before && after);
    const double t = *before / (*before - *after);
    const double wall =
        volume.VoxelToWorld(Eigen::Vector3i(0, 0, static_cast<int>(std::floor(lattice.z())))).z() +
        t * params.voxel_size;
    std::cout << (noise ? "noise" : "uniform") << " weights: wall at " << wall
              << " m (truth 0.8)\n";
    if (noise) {
      EXPECT_NEAR(wall, 0.8, 0.001);
    } else {
      EXPECT_NEAR(wall, 0.81, 0.001);
    }
  }
}

// IntegrateFrame runs its update four voxels at a time; every voxel must still follow
// integrate.h's kernel, recomputed here one voxel at a time in double precision from the volume
// before the frame (a second frame over a first one, so old weights, sdfs and colours all count).
// With `nan_colour` the second frame's colours are all NaN (an EXR may hold them): the voxels it
// colours become NaN, every other voxel keeps its colour bit for bit.
void CheckEveryVoxelFollowsTheKernel(bool nan_colour) {
  const CameraIntrinsics k = Camera(64, 48);
  std::vector<RgbdFrame> frames = Render(Room(), Orbit(8), k);
  if (nan_colour) {
    for (Eigen::Vector3f& c : frames[5].color.pixels())
      c.setConstant(std::numeric_limits<float>::quiet_NaN());
  }
  TsdfVolumeParams params;
  params.voxel_size = 0.02;
  params.truncation = 0.08;
  params.max_weight = 1.5f;  // the second measurement of near voxels saturates
  TsdfVolume volume(params);
  IntegrationOptions options;
  IntegrateFrame(volume, frames[0].depth, frames[0].color, k, *frames[0].world_from_camera,
                 options);
  // Blocks keep their index when more are allocated: block i of the volume after the second
  // frame was block i before it, or new (i >= before.size()).
  std::vector<TsdfBlock> before;
  for (size_t i = 0; i < volume.num_blocks(); ++i) before.push_back(volume.block(i));
  const RgbdFrame& frame = frames[5];
  IntegrateFrame(volume, frame.depth, frame.color, k, *frame.world_from_camera, options);
  // Only the blocks of this frame's band are updated, the others keep their voxels.
  std::set<std::tuple<int, int, int>> band;
  for (const Eigen::Vector3i& key : BlocksInTruncationBand(
           volume, frame.depth, k, *frame.world_from_camera, options.allocation_stride)) {
    band.insert({key.x(), key.y(), key.z()});
  }

  const Eigen::Isometry3d camera_from_world = frame.world_from_camera->inverse();
  const double trunc = params.truncation;
  const TsdfBlock empty;
  size_t updated = 0, coloured = 0, saturated = 0, kept = 0, borderline = 0;
  for (size_t i = 0; i < volume.num_blocks(); ++i) {
    const Eigen::Vector3i& key = volume.block_key(i);
    const TsdfBlock& was = i < before.size() ? before[i] : empty;
    const TsdfBlock& now = volume.block(i);
    for (int z = 0; z < kTsdfBlockSide; ++z) {
      for (int y = 0; y < kTsdfBlockSide; ++y) {
        for (int x = 0; x < kTsdfBlockSide; ++x) {
          const int index = TsdfBlock::Index(x, y, z);
          const TsdfVoxel& v0 = was.voxels[index];
          const TsdfVoxel& v1 = now.voxels[index];
          const Eigen::Vector3f& c0 = was.colors[index];
          const Eigen::Vector3f& c1 = now.colors[index];
          const Eigen::Vector3d p =
              camera_from_world *
              volume.VoxelToWorld(kTsdfBlockSide * key + Eigen::Vector3i(x, y, z));
          const double u = k.fx * p.x() / p.z() + k.cx + 0.5, v = k.fy * p.y() / p.z() + k.cy + 0.5;
          // Voxels on a pixel footprint's edge may fall either side in float: not checked.
          const auto near_edge = [](double t) { return std::abs(t - std::round(t)) < 1e-3; };
          if (p.z() > 0.0 && (near_edge(u) || near_edge(v))) {
            ++borderline;
            continue;
          }
          double depth = 0.0;
          if (p.z() > 0.0 && u >= 0.0 && v >= 0.0 && u < k.width && v < k.height) {
            depth = frame.depth(static_cast<int>(u), static_cast<int>(v));
          }
          const double lambda = (p / p.z()).norm();
          const double eta = (depth - p.z()) * lambda;
          if (band.count({key.x(), key.y(), key.z()}) && depth > 0.0 &&
              (std::abs(eta + trunc) < 1e-5 || std::abs(eta - trunc) < 1e-5)) {
            ++borderline;
            continue;
          }
          if (!band.count({key.x(), key.y(), key.z()}) || depth <= 0.0 || eta < -trunc) {
            // No update: bit for bit the old voxel.
            ASSERT_EQ(v1.sdf, v0.sdf) << "block " << i << " voxel " << index;
            ASSERT_EQ(v1.weight, v0.weight) << "block " << i << " voxel " << index;
            ASSERT_EQ(c1, c0) << "block " << i << " voxel " << index;
            ++kept;
            continue;
          }
          const double w_obs = ObservationWeight(static_cast<float>(depth));
          const double w_new = v0.weight + w_obs;
          const double sdf = (v0.weight * v0.sdf + w_obs * std::min(eta, trunc)) / w_new;
          ASSERT_NEAR(v1.sdf, sdf, 1e-5) << "block " << i << " voxel " << index;
          ASSERT_NEAR(v1.weight, std::min(w_new, double{params.max_weight}), 1e-5 * w_new)
              << "block " << i << " voxel " << index;
          saturated += w_new > params.max_weight;
          ++updated;
          if (eta < trunc) {
            const Eigen::Vector3d observed =
                frame.color(static_cast<int>(u), static_cast<int>(v)).cast<double>();
            const Eigen::Vector3d colour =
                (v0.weight * c0.cast<double>() + w_obs * observed) / w_new;
            if (nan_colour) {
              ASSERT_TRUE(c1.array().isNaN().all()) << "block " << i << " voxel " << index;
            } else {
              ASSERT_LT((c1.cast<double>() - colour).cwiseAbs().maxCoeff(), 1e-5)
                  << "block " << i << " voxel " << index;
            }
            ++coloured;
          } else {
            ASSERT_EQ(c1, c0) << "free space keeps its colour: block " << i << " voxel " << index;
          }
        }
      }
    }
  }
  std::cout << volume.num_blocks() << " blocks: " << updated << " voxels updated (" << coloured
            << " coloured, " << saturated << " saturated), " << kept << " kept, " << borderline
            << " on an edge\n";
  EXPECT_GT(updated, 10000u);
  EXPECT_GT(coloured, 2000u);
  EXPECT_GT(saturated, 1000u);
  EXPECT_GT(kept, 10000u);
  EXPECT_LT(borderline, (updated + kept) / 50);
}

TEST(Fusion, EveryVoxelFollowsTheKernel) {
  CheckEveryVoxelFollowsTheKernel(false);
}

TEST(Fusion, NanColourStaysInTheVoxelsItColours) {
  CheckEveryVoxelFollowsTheKernel(true);
}

// Hard case: a pure plane leaves three pose directions unconstrained.
TEST(FusionHardCases, PurePlaneIsDetectedAsDegenerateNotAWildPose) {
  SyntheticScene scene;
  scene.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(-20, -20, -1), Eigen::Vector3d(20, 20, 0)),
       Eigen::Vector3f::Constant(0.5f)});
  Trajectory trajectory;
  for (int i = 0; i < 10; ++i) {  // sliding sideways 1 cm per frame, 1.2 m above the plane
    const Eigen::Vector3d eye(0.01 * i, 0.0, 1.2);
    trajectory.Add(i / 30.0, LookAt(eye, eye + Eigen::Vector3d(0.3, 0.2, -1.0)));
  }
  const std::vector<RgbdFrame> frames = Render(scene, trajectory, Camera(160, 120));
  const FusionRun run = Fuse(frames, DefaultOptions());
  EXPECT_EQ(run.counts.at(FrameStatus::kDegenerate), 9);
  for (const FrameReport& r : run.fusion->reports()) {
    if (r.status != FrameStatus::kDegenerate) continue;
    EXPECT_EQ(r.icp.constrained_directions, 3) << r.reason;
    EXPECT_FALSE(r.fused);
    // Along the plane the estimate stays put (no wild slide); off the plane it is exact.
    const Eigen::Isometry3d& truth = *frames[r.index].world_from_camera;
    const Eigen::Vector3d error = r.world_from_camera->translation() - truth.translation();
    EXPECT_LT(error.head<2>().norm(), 0.1 + 1e-9);
    EXPECT_LT(std::abs(error.z()), 1e-3);
  }
}

// The same slide over a plane with texture (tiles of random brightness): the photometric term
// fixes the directions the geometry leaves free, and the frames are tracked and fused.
TEST(FusionHardCases, TexturedPlaneIsTrackedByItsColour) {
  SyntheticScene scene;
  scene.boxes.push_back(
      {Eigen::AlignedBox3d(Eigen::Vector3d(-20, -20, -1), Eigen::Vector3d(20, 20, 0)),
       Eigen::Vector3f::Constant(0.5f)});
  scene.texture_tile = 0.2;
  Trajectory trajectory;
  for (int i = 0; i < 10; ++i) {
    const Eigen::Vector3d eye(0.01 * i, 0.0, 1.2);
    trajectory.Add(i / 30.0, LookAt(eye, eye + Eigen::Vector3d(0.3, 0.2, -1.0)));
  }
  const std::vector<RgbdFrame> frames = Render(scene, trajectory, Camera(320, 240));
  const FusionRun run = Fuse(frames, DefaultOptions());
  EXPECT_EQ(run.counts.at(FrameStatus::kTracked), 9);
  for (const FrameReport& r : run.fusion->reports()) {
    if (r.index == 0) continue;
    EXPECT_EQ(r.icp.constrained_directions, 6) << r.index;
    EXPECT_GT(r.icp.color_pixels, 1000u) << r.index;
    const Eigen::Isometry3d& truth = *frames[r.index].world_from_camera;
    ASSERT_TRUE(r.world_from_camera.has_value());
    EXPECT_LT((r.world_from_camera->translation() - truth.translation()).norm(), 2e-3) << r.index;
    EXPECT_LT(RotationAngle(r.world_from_camera->inverse() * truth), 2e-3) << r.index;
  }
  // Geometry alone (no photometric term, no feature start): the slide is unconstrained and the
  // frames are not fused.
  FusionOptions geometry = DefaultOptions();
  geometry.icp.color_weight = 0.0;
  geometry.feature_tracking = false;
  EXPECT_EQ(Fuse(frames, geometry).counts.at(FrameStatus::kDegenerate), 9);
}

TEST(FusionHardCases, AllInvalidFrameIsSkippedAndTrackingGoesOn) {
  std::vector<RgbdFrame> frames = Render(Room(), Orbit(12), Camera(160, 120));
  frames[5].depth = ImageDepth(160, 120);
  const FusionRun run = Fuse(frames, DefaultOptions());
  EXPECT_EQ(run.fusion->reports()[5].status, FrameStatus::kBlank);
  EXPECT_EQ(run.counts.at(FrameStatus::kTracked), 10);
  EXPECT_LT(ComputeAte(run.fusion->trajectory(), GroundTruth(frames)).rmse, 0.01);
}

TEST(FusionHardCases, FarAwayFrameIsLostAndTrackingRecovers) {
  std::vector<RgbdFrame> frames = Render(Room(), Orbit(16), Camera(160, 120));
  // Frame 8 is seen from the opposite corner, looking elsewhere: a jump no ICP can follow.
  frames[8] = RenderSyntheticFrame(Room(), Camera(160, 120),
                                   LookAt({0.7, 0.7, 1.5}, {-0.8, 0.5, 0.2}), frames[8].timestamp);
  FusionOptions options = DefaultOptions();
  const FusionRun run = Fuse(frames, options);
  EXPECT_EQ(run.fusion->reports()[8].status, FrameStatus::kLost) << run.fusion->reports()[8].reason;
  EXPECT_FALSE(run.fusion->reports()[8].fused);
  for (size_t i = 9; i < frames.size(); ++i) {
    EXPECT_EQ(run.fusion->reports()[i].status, FrameStatus::kTracked) << "frame " << i;
  }
  std::vector<RgbdFrame> good = frames;
  good.erase(good.begin() + 8);
  const AteResult ate = ComputeAte(run.fusion->trajectory(), GroundTruth(good));
  EXPECT_EQ(ate.pairs, 15u);
  EXPECT_LT(ate.rmse, 0.01);
}

TEST(FusionHardCases, NanAndInfDepthAreMasked) {
  std::vector<RgbdFrame> frames = Render(Room(), Orbit(12), Camera(160, 120));
  for (RgbdFrame& f : frames) {
    for (int i = 0; i < 400; ++i) {
      f.depth.pixels()[(i * 7919) % f.depth.size()] =
          i % 2 ? std::numeric_limits<float>::quiet_NaN() : -std::numeric_limits<float>::infinity();
    }
  }
  const FusionRun run = Fuse(frames, DefaultOptions());
  EXPECT_EQ(run.counts.at(FrameStatus::kTracked), 11);
  EXPECT_GE(run.fusion->reports()[3].mask.non_finite, 390u);
  EXPECT_LT(ComputeAte(run.fusion->trajectory(), GroundTruth(frames)).rmse, 0.01);
  for (size_t b = 0; b < run.fusion->volume().num_blocks(); ++b) {
    const TsdfBlock& block = run.fusion->volume().block(b);
    for (int i = 0; i < kTsdfBlockVoxels; ++i) {
      const TsdfVoxel& v = block.voxels[i];
      ASSERT_TRUE(std::isfinite(v.sdf) && std::isfinite(v.weight) && block.colors[i].allFinite());
    }
  }
}

TEST(FusionHardCases, CameraOneKilometreFromTheOriginKeepsItsPrecision) {
  const Eigen::Vector3d offset(1000.0, -1000.0, 300.0);
  const std::vector<RgbdFrame> frames = Render(Room(offset), Orbit(20, offset), Camera(160, 120));
  const std::vector<RgbdFrame> near_frames = Render(Room(), Orbit(20), Camera(160, 120));
  const FusionRun far = Fuse(frames, DefaultOptions());
  const FusionRun near = Fuse(near_frames, DefaultOptions());
  EXPECT_EQ(far.counts.at(FrameStatus::kTracked), 19);
  const double far_ate = ComputeAte(far.fusion->trajectory(), GroundTruth(frames)).rmse;
  const double near_ate = ComputeAte(near.fusion->trajectory(), GroundTruth(near_frames)).rmse;
  std::cout << "ATE 1 km away " << far_ate << " m, at the origin " << near_ate << " m\n";
  EXPECT_LT(far_ate, 0.01);
  EXPECT_LT(std::abs(far_ate - near_ate), 1e-3);
  // The model sits where the scene is: 1 km away (the first frame's known pose defines the world).
  EXPECT_LT((far.fusion->volume().origin() - offset).norm(), 3.0);
}

TEST(FusionHardCases, VoxelSizeBeyondTheMemoryCapIsAClearError) {
  const std::vector<RgbdFrame> frames = Render(Room(), Orbit(2), Camera(160, 120));
  FusionOptions options = DefaultOptions();
  options.voxel_size = 0.002;
  options.truncation = 0.008;
  options.memory_cap = 20.0;  // MB
  KinectFusion fusion(options, frames[0].intrinsics);
  const std::string error = test::ErrorOf([&] { fusion.ProcessFrame(frames[0]); });
  EXPECT_CONTAINS(error, "memory cap of 20 MB exceeded");
  EXPECT_CONTAINS(error, "voxel size 0.002 m");
  EXPECT_EQ(fusion.volume().num_blocks(), 0u);  // nothing half-allocated
}

TEST(Fusion, SameOutputWithOneAndTwoThreads) {
  const std::vector<RgbdFrame> frames = Render(Room(), Orbit(8), Camera(160, 120));
  test::TempDir dir;
  std::string bytes[2], trajectories[2];
  for (int threads : {1, 2}) {
    SetThreadCount(threads);
    const FusionRun run = Fuse(frames, DefaultOptions());
    const Workspace ws(dir / ("ws" + std::to_string(threads)));
    SaveFusionOutputs(*run.fusion, ws);
    std::ifstream tsdf(ws.Tsdf(), std::ios::binary), traj(ws.Trajectory());
    bytes[threads - 1] =
        std::string((std::istreambuf_iterator<char>(tsdf)), std::istreambuf_iterator<char>());
    trajectories[threads - 1] =
        std::string((std::istreambuf_iterator<char>(traj)), std::istreambuf_iterator<char>());
  }
  SetThreadCount(0);
  EXPECT_GT(bytes[0].size(), 1000u);
  EXPECT_TRUE(bytes[0] == bytes[1]) << "tsdf.gsv differs between 1 and 2 threads";
  EXPECT_EQ(trajectories[0], trajectories[1]);
}

}  // namespace
}  // namespace genscene::fusion
