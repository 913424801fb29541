// Loop-closure verification against PCL's registration: the job LoopClosure::MatchNodes does
// (fusion/loop_closure.cpp) with our ICP, done by PCL's GICP and point-to-plane ICP on the same
// pairs of frames. Built only where PCL is installed (bench/CMakeLists.txt); run by hand:
//   build/bench/bench_pcl_registration [--pairs 5] [--width 0] [--views both] [--threads 0]
//     [--methods ours,pcl] [--exact] [--pcl-raw] [--levels 4] [--verbose]
//
// Pairs: the textured analytic living room (core/synthetic.h, 0.15 m tiles), the first frame of a
// pair at one of two sets of views (--views): `loop`, poses of the room's loop
// (MakeRoomLoopTrajectory: a 0.4 m circle looking out at the walls and 25 degrees down, as the
// loop-closure tests and bench_fusion --scale walk it: mostly a wall and the floor), and `centre`,
// cameras 1.6 m high on an ellipse of 2 x 1.5 m looking at the table (table, sofa, cabinet and
// walls in view: geometry that constrains every direction); the second frame moved from the first
// by 10-40 cm in a random direction and turned 5-20 degrees about a random axis; both rendered
// exactly, then given Kinect-v1 noise (AddKinectDepthNoise), masked and kept in a FrameStore
// (16-bit depth, 8-bit sRGB colour) as loop closure keeps them. Every method starts from the true
// relative pose perturbed by a PnP-like error (3 cm and 2 degrees, random directions) and is
// scored on the relative pose it recovers: translation and rotation error against the truth,
// success = both under 1 cm and 1 degree, and its wall time per pair (everything a method does
// from the two stored frames: pyramids or clouds, filters, normals, alignment); for ours also
// whether MatchNodes' test accepts the pose (and how many accepted poses are wrong). All random
// numbers come from fixed seeds. Results and the decision they made: fusion/README.md, PCL.
//
// Methods:
//   ours          TrackFrameToModel with the default IcpOptions, called as MatchNodes calls it:
//                 the live frame's pyramid against ModelFromDepth of the old frame's, with both
//                 frames' brightness pyramids (the photometric term)
//   ours depth    the same with color_weight 0 (geometry only, as the PCL methods are)
//   pcl gicp L    pcl::GeneralizedIterativeClosestPoint (covariances of 20 neighbours) on both
//                 frames' back-projected clouds after pcl::VoxelGrid at leaf L (1 and 2 cm); the
//                 clouds come from the depth after the bilateral filter our pyramid applies
//                 (BuildPyramid's level 0), as ours does (--pcl-raw: from the stored depth)
//   pcl p2pl L    pcl::IterativeClosestPointWithNormals (point-to-plane) on the same clouds with
//                 normals from pcl::NormalEstimation (20 nearest neighbours)
// Both PCL methods reject correspondences farther than 0.1 m (our ICP's max_distance).
#include <pcl/common/io.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "core/parallel.h"
#include "core/rng.h"
#include "core/se3.h"
#include "core/synthetic.h"
#include "fusion/icp.h"
#include "fusion/loop_closure.h"
#include "fusion/preprocess.h"

using namespace genscene;
using namespace genscene::fusion;

namespace {

bool g_exact = false;  // --exact

// A pair of stored frames: `old` and `live` as loop closure keeps them, and the truth.
struct Pair {
  ImageDepth old_depth, live_depth;
  ImageRgb old_color, live_color;
  Eigen::Isometry3d truth;  // old_from_live
  Eigen::Isometry3d start;  // the truth perturbed (the PnP-like start)
};

Eigen::Vector3d RandomUnitVector(CounterRng& rng) {
  const double z = 2.0 * rng.UniformDouble() - 1.0, phi = 2.0 * M_PI * rng.UniformDouble();
  const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// A motion of `translation` metres and `degrees` about random directions.
Eigen::Isometry3d RandomMotion(CounterRng& rng, double translation, double degrees) {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = Eigen::AngleAxisd(degrees * M_PI / 180.0, RandomUnitVector(rng)).toRotationMatrix();
  m.translation() = translation * RandomUnitVector(rng);
  return m;
}

// The first frame of pair i of `count` (see the top of the file).
Eigen::Isometry3d OldPose(const std::string& views, int i, int count) {
  if (views == "loop") {
    return MakeRoomLoopTrajectory(Eigen::Vector3d::Zero(), 0.4, 1.5, 1.0, count + 1, 11)
        .poses()[static_cast<size_t>(i)]
        .world_from_camera;
  }
  const double angle = 0.3 + 2.0 * M_PI * i / count;
  return LookAt(Eigen::Vector3d(2.0 * std::cos(angle), 1.5 * std::sin(angle), 1.6),
                Eigen::Vector3d(0.0, 0.0, 0.5));
}

std::vector<Pair> MakePairs(int count, int width, const std::string& views) {
  SyntheticScene room = MakeLivingRoomScene();
  room.texture_tile = 0.15;
  const int height = width * 3 / 4;
  const CameraIntrinsics k = CameraIntrinsics::Centered(width, height, 525.0 * width / 640.0);
  const PreprocessOptions preprocess;
  FrameStore store(preprocess.max_depth);
  std::vector<Pair> pairs;
  for (int i = 0; i < count; ++i) {
    // The same motions at every width; other ones for the other views.
    CounterRng rng(7, static_cast<uint64_t>(i), views == "loop" ? 1 : 2);
    const Eigen::Isometry3d old_pose = OldPose(views, i, count);
    const double translation = 0.10 + 0.30 * rng.UniformDouble();
    const double degrees = 5.0 + 15.0 * rng.UniformDouble();
    const Eigen::Isometry3d motion = RandomMotion(rng, translation, degrees);
    const Eigen::Isometry3d live_pose = old_pose * motion;
    Pair pair;
    pair.truth = motion;  // old_from_live
    pair.start = pair.truth * RandomMotion(rng, 0.03, 2.0);
    for (int f = 0; f < 2; ++f) {
      RgbdFrame frame = RenderSyntheticFrame(room, k, f == 0 ? old_pose : live_pose, 0.0);
      if (!g_exact) AddKinectDepthNoise(frame.depth, 5, static_cast<uint64_t>(2 * i + f));
      store.Add(0.0, MaskInvalidDepth(frame.depth, preprocess.min_depth, preprocess.max_depth),
                frame.color);
      (f == 0 ? pair.old_depth : pair.live_depth) = store.Depth(store.size() - 1);
      (f == 0 ? pair.old_color : pair.live_color) = store.Color(store.size() - 1);
    }
    pairs.push_back(std::move(pair));
  }
  return pairs;
}

// ---- ours ----

// What a method returns: the relative pose, and for ours whether MatchNodes would accept it.
struct Result {
  Eigen::Isometry3d old_from_live;
  int accepted = -1;  // 1 / 0; -1 = the method has no acceptance test here
};

int g_levels = PreprocessOptions().levels + kLoopVerifyExtraLevels;  // --levels

Result AlignOurs(const Pair& pair, const CameraIntrinsics& k, const IcpOptions& icp) {
  PreprocessOptions preprocess;
  preprocess.levels = g_levels;
  const std::vector<PyramidLevel> old_pyramid = BuildPyramid(pair.old_depth, k, preprocess);
  const std::vector<PyramidLevel> live_pyramid = BuildPyramid(pair.live_depth, k, preprocess);
  const std::vector<IntensityLevel> old_intensity =
      BuildIntensityPyramid(pair.old_color, preprocess.levels);
  const std::vector<IntensityLevel> live_intensity =
      BuildIntensityPyramid(pair.live_color, preprocess.levels);
  Result result{pair.start};
  const IcpReport report =
      TrackFrameToModel(live_pyramid, ModelFromDepth(old_pyramid[0]), k, icp, &result.old_from_live,
                        &live_intensity, &old_intensity);
  // MatchNodes' test: converged on most of the frame and near the start.
  constexpr double kMaxCorrection = 0.15, kMaxCorrectionDeg = 5.0;  // m, degrees
  const Eigen::Isometry3d correction = pair.start.inverse() * result.old_from_live;
  result.accepted =
      !(report.inlier_ratio < icp.min_inlier_ratio || report.rms_residual > icp.max_rms_residual ||
        report.degenerate || correction.translation().norm() > kMaxCorrection ||
        RotationAngle(correction) * 180.0 / M_PI > kMaxCorrectionDeg);
  return result;
}

// ---- PCL ----

using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using NormalCloud = pcl::PointCloud<pcl::PointNormal>;
constexpr double kPclMaxDistance = 0.1;  // m, as IcpOptions::max_distance
bool g_pcl_raw = false;                  // --pcl-raw

// The camera-frame points of the valid pixels, then a voxel grid of `leaf` metres.
Cloud::Ptr BackProject(const ImageDepth& stored, const CameraIntrinsics& k, double leaf) {
  PreprocessOptions preprocess;
  preprocess.levels = 1;
  const ImageDepth depth = g_pcl_raw ? stored : BuildPyramid(stored, k, preprocess)[0].depth;
  Cloud::Ptr all(new Cloud);
  all->reserve(depth.size());
  for (int v = 0; v < depth.height(); ++v) {
    for (int u = 0; u < depth.width(); ++u) {
      const float z = depth(u, v);
      if (!(z > 0.0f)) continue;
      all->push_back(pcl::PointXYZ(static_cast<float>((u - k.cx) / k.fx * z),
                                   static_cast<float>((v - k.cy) / k.fy * z), z));
    }
  }
  Cloud::Ptr out(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(all);
  const float l = static_cast<float>(leaf);
  grid.setLeafSize(l, l, l);
  grid.filter(*out);
  return out;
}

Eigen::Isometry3d ToIsometry(const Eigen::Matrix4f& m) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::Quaterniond(m.topLeftCorner<3, 3>().cast<double>()).normalized().matrix();
  out.translation() = m.topRightCorner<3, 1>().cast<double>();
  return out;
}

Result AlignGicp(const Pair& pair, const CameraIntrinsics& k, double leaf) {
  const Cloud::Ptr old_cloud = BackProject(pair.old_depth, k, leaf);
  const Cloud::Ptr live_cloud = BackProject(pair.live_depth, k, leaf);
  pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> gicp;
  gicp.setInputSource(live_cloud);
  gicp.setInputTarget(old_cloud);
  gicp.setMaxCorrespondenceDistance(kPclMaxDistance);
  // Stop when a step changes the translation by < 1 um and the rotation matrix by < 1e-5 (the
  // defaults, 5e-4 m and 2e-3, stop early: raw depth, 3 centre pairs at 320x240, median error
  // 8.6 mm against 7.1).
  gicp.setTransformationEpsilon(1e-6);
  gicp.setRotationEpsilon(1e-5);
  Cloud aligned;
  gicp.align(aligned, pair.start.matrix().cast<float>());
  return {ToIsometry(gicp.getFinalTransformation())};
}

NormalCloud::Ptr WithNormals(const Cloud::Ptr& cloud) {
  pcl::PointCloud<pcl::Normal> normals;
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setInputCloud(cloud);
  estimation.setSearchMethod(
      pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  estimation.setKSearch(20);
  estimation.setViewPoint(0.0f, 0.0f, 0.0f);  // the camera: normals face it
  estimation.compute(normals);
  NormalCloud::Ptr out(new NormalCloud);
  pcl::concatenateFields(*cloud, normals, *out);
  NormalCloud::Ptr finite(new NormalCloud);
  finite->reserve(out->size());
  for (const pcl::PointNormal& p : *out) {
    if (std::isfinite(p.normal_x) && std::isfinite(p.normal_y) && std::isfinite(p.normal_z))
      finite->push_back(p);
  }
  return finite;
}

Result AlignPointToPlane(const Pair& pair, const CameraIntrinsics& k, double leaf) {
  const NormalCloud::Ptr old_cloud = WithNormals(BackProject(pair.old_depth, k, leaf));
  const NormalCloud::Ptr live_cloud = WithNormals(BackProject(pair.live_depth, k, leaf));
  pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal> icp;
  icp.setInputSource(live_cloud);
  icp.setInputTarget(old_cloud);
  icp.setMaxCorrespondenceDistance(kPclMaxDistance);
  icp.setMaximumIterations(50);
  icp.setTransformationEpsilon(1e-10);  // squared translation of a step: 10 um
  NormalCloud aligned;
  icp.align(aligned, pair.start.matrix().cast<float>());
  return {ToIsometry(icp.getFinalTransformation())};
}

// ---- scoring ----

struct Method {
  std::string name;
  std::function<Result(const Pair&, const CameraIntrinsics&)> align;
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void Run(int width, const std::string& views, int pair_count, const std::vector<std::string>& only,
         bool verbose) {
  const CameraIntrinsics k =
      CameraIntrinsics::Centered(width, width * 3 / 4, 525.0 * width / 640.0);
  const std::vector<Pair> pairs = MakePairs(pair_count, width, views);
  IcpOptions depth_only;
  depth_only.color_weight = 0.0;
  std::vector<Method> methods = {
      {"ours", [](const Pair& p, const CameraIntrinsics& k) { return AlignOurs(p, k, {}); }},
      {"ours depth",
       [&](const Pair& p, const CameraIntrinsics& k) { return AlignOurs(p, k, depth_only); }},
      {"pcl gicp 1cm",
       [](const Pair& p, const CameraIntrinsics& k) { return AlignGicp(p, k, 0.01); }},
      {"pcl gicp 2cm",
       [](const Pair& p, const CameraIntrinsics& k) { return AlignGicp(p, k, 0.02); }},
      {"pcl p2pl 1cm",
       [](const Pair& p, const CameraIntrinsics& k) { return AlignPointToPlane(p, k, 0.01); }},
      {"pcl p2pl 2cm",
       [](const Pair& p, const CameraIntrinsics& k) { return AlignPointToPlane(p, k, 0.02); }},
  };
  // --methods: a method's whole name, or else the start of names (pcl, pcl gicp).
  auto chosen = [&](const std::string& name) {
    if (only.empty()) return true;
    for (const std::string& o : only) {
      const bool whole_name =
          std::any_of(methods.begin(), methods.end(), [&](const Method& m) { return m.name == o; });
      if (whole_name ? name == o : name.rfind(o + " ", 0) == 0) return true;
    }
    return false;
  };
  methods.erase(std::remove_if(methods.begin(), methods.end(),
                               [&](const Method& m) { return !chosen(m.name); }),
                methods.end());
  const std::string resolution = std::to_string(width) + "x" + std::to_string(width * 3 / 4);
  for (const Method& method : methods) {
    std::vector<double> mm, degrees, ms;
    int success = 0, accepted = 0, wrong = 0;
    bool has_test = false;
    for (size_t i = 0; i < pairs.size(); ++i) {
      const auto start = std::chrono::steady_clock::now();
      const Result result = method.align(pairs[i], k);
      ms.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count());
      const Eigen::Isometry3d error = pairs[i].truth.inverse() * result.old_from_live;
      mm.push_back(1e3 * error.translation().norm());
      degrees.push_back(RotationAngle(error) * 180.0 / M_PI);
      const bool good = mm.back() < 10.0 && degrees.back() < 1.0;
      success += good;
      has_test = result.accepted >= 0;
      accepted += result.accepted == 1;
      wrong += result.accepted == 1 && !good;
      if (verbose) {
        std::printf("  %s %s %s pair %zu: %.2f mm %.3f deg %.0f ms%s\n", method.name.c_str(),
                    resolution.c_str(), views.c_str(), i, mm.back(), degrees.back(), ms.back(),
                    result.accepted == 0 ? " (rejected)" : "");
      }
    }
    const std::string accepts =
        has_test ? std::to_string(accepted) + " (" + std::to_string(wrong) + " wrong)" : "-";
    std::printf(
        "%-13s | %-10s | %-6s | %5zu | %4d/%-4zu | %9.2f | %8.2f | %10.3f | %9.3f | %8.0f | %s\n",
        method.name.c_str(), resolution.c_str(), views.c_str(), pairs.size(), success, pairs.size(),
        Median(mm), *std::max_element(mm.begin(), mm.end()), Median(degrees),
        *std::max_element(degrees.begin(), degrees.end()), Median(ms), accepts.c_str());
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_pcl_registration: loop-closure verification, our ICP against PCL's"};
  int pairs = 5, width = 0, threads = 0;
  std::string views = "both";
  bool verbose = false;
  app.add_option("--pairs", pairs, "pairs of frames per resolution and set of views")
      ->check(CLI::Range(1, 1000));
  app.add_option("--width", width, "image width (4:3); 0 = 640 and 320");
  app.add_option("--views", views, "loop (out at the walls), centre (at the table) or both")
      ->check(CLI::IsMember({"loop", "centre", "both"}));
  app.add_option("--threads", threads, "threads of our code (0 = the default)");
  std::vector<std::string> only;
  app.add_option("--methods", only,
                 "methods to run: names (ours, \"ours depth\", \"pcl gicp 2cm\", ...) or the start "
                 "of names (pcl, \"pcl gicp\"); default: all")
      ->delimiter(',');
  app.add_option("--levels", g_levels,
                 "pyramid levels of our ICP (MatchNodes: tracking's + kLoopVerifyExtraLevels)")
      ->check(CLI::Range(1, 6));
  app.add_flag("--verbose", verbose, "a line per pair and method");
  app.add_flag("--exact", g_exact, "exact depth (no Kinect noise)");
  app.add_flag("--pcl-raw", g_pcl_raw,
               "PCL's clouds from the stored depth as it is (default: bilateral-filtered as our "
               "ICP's pyramid, BuildPyramid level 0)");
  CLI11_PARSE(app, argc, argv);
  if (threads > 0) SetThreadCount(threads);
  std::printf(
      "loop verification on the textured living room: %d pairs a set 10-40 cm / 5-20 deg apart, "
      "%s depth, PCL's clouds from %s depth, start 3 cm / 2 deg from the truth; success = < 10 mm "
      "and < 1 deg; threads %d (PCL: 1); accepted = passes MatchNodes' test\n",
      pairs, g_exact ? "exact" : "Kinect-noise", g_pcl_raw ? "the stored" : "bilateral-filtered",
      ThreadCount());
  std::printf("%-13s | %-10s | %-6s | %5s | %9s | %9s | %8s | %10s | %9s | %8s | %s\n", "method",
              "resolution", "views", "pairs", "success", "median mm", "worst mm", "median deg",
              "worst deg", "ms/pair", "accepted");
  const std::vector<int> widths = width > 0 ? std::vector<int>{width} : std::vector<int>{640, 320};
  const std::vector<std::string> view_sets = views == "both"
                                                 ? std::vector<std::string>{"loop", "centre"}
                                                 : std::vector<std::string>{views};
  for (const std::string& v : view_sets) {
    for (int w : widths) Run(w, v, pairs, only, verbose);
  }
  return 0;
}
