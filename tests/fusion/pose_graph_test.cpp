// The pose graph: its edge error against closed forms, its Jacobians against central differences,
// and a loop of odometry with drift closed by one edge.
#include "fusion/pose_graph.h"

#include <cmath>

#include "core/parallel.h"
#include "core/rng.h"
#include "core/se3.h"
#include "tests/test_util.h"

namespace genscene::fusion {
namespace {

Eigen::Isometry3d Pose(const Eigen::Vector3d& rotation_vector, const Eigen::Vector3d& t) {
  Vector6d delta;
  delta << rotation_vector, Eigen::Vector3d::Zero();
  Eigen::Isometry3d pose = PerturbPose(Eigen::Isometry3d::Identity(), delta);
  pose.translation() = t;
  return pose;
}

Eigen::Isometry3d RandomPose(CounterRng& rng, double max_angle, double max_translation) {
  Eigen::Vector3d w, t;
  for (int i = 0; i < 3; ++i) {
    w[i] = max_angle * (2.0 * rng.UniformDouble() - 1.0);
    t[i] = max_translation * (2.0 * rng.UniformDouble() - 1.0);
  }
  return Pose(w, t);
}

TEST(PoseGraph, EdgeErrorIsZeroWhenThePosesAgreeAndTheRotationVectorAndTranslationOtherwise) {
  CounterRng rng(5, 1);
  const Eigen::Isometry3d a = RandomPose(rng, 1.0, 2.0), m = RandomPose(rng, 0.5, 1.0);
  const Eigen::Isometry3d b = a * m;
  EXPECT_LT(PoseGraphEdgeError(a, b, m).norm(), 1e-12);
  // b off by a rotation of 0.1 rad about z and 3 cm along x, both in the measurement's frame.
  const Eigen::Isometry3d off = Pose({0.0, 0.0, 0.1}, {0.03, 0.0, 0.0});
  const Vector6d e = PoseGraphEdgeError(a, a * m * off, m);
  Vector6d expected;
  expected << 0.0, 0.0, 0.1, 0.03, 0.0, 0.0;
  EXPECT_LT((e - expected).norm(), 1e-12) << e.transpose();
  // The whitened residual has |r|^2 = e^T Omega e.
  PoseGraphEdge edge;
  edge.measured = m;
  edge.information = Matrix6d::Identity();
  edge.information.diagonal() << 4.0, 4.0, 4.0, 100.0, 100.0, 100.0;
  edge.information(0, 3) = edge.information(3, 0) = 1.5;
  const EdgeLinearisation lin = LinearisePoseGraphEdge(a, a * m * off, edge);
  EXPECT_NEAR(lin.residual.squaredNorm(), e.dot(edge.information * e), 1e-12);
}

// Every Jacobian entry against central differences of the residual under the same perturbation
// (mean and max relative error), at random poses and information matrices.
TEST(PoseGraph, EdgeJacobiansMatchCentralDifferences) {
  CounterRng rng(17, 2);
  double max_rel = 0.0, sum_rel = 0.0;
  int entries = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Isometry3d a = RandomPose(rng, 2.5, 3.0);
    PoseGraphEdge edge;
    edge.measured = RandomPose(rng, 1.0, 1.0);
    const Eigen::Isometry3d b = a * edge.measured * RandomPose(rng, 0.3, 0.1);
    Matrix6d l = Matrix6d::Zero();
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j <= i; ++j)
        l(i, j) = (i == j ? 1.0 : 0.3) * (2.0 * rng.UniformDouble() - 1.0);
    l.diagonal() = l.diagonal().cwiseAbs().array() + 0.5;
    edge.information = l * l.transpose();
    const EdgeLinearisation lin = LinearisePoseGraphEdge(a, b, edge);
    constexpr double kH = 1e-6;
    for (int side = 0; side < 2; ++side) {
      const Matrix6d& analytic = side == 0 ? lin.d_from : lin.d_to;
      for (int k = 0; k < 6; ++k) {
        Vector6d delta = Vector6d::Zero();
        delta[k] = kH;
        const auto residual = [&](const Vector6d& d) {
          const Eigen::Isometry3d pa = side == 0 ? PerturbPose(a, d) : a;
          const Eigen::Isometry3d pb = side == 1 ? PerturbPose(b, d) : b;
          return LinearisePoseGraphEdge(pa, pb, edge).residual;
        };
        const Vector6d numeric = (residual(delta) - residual(-delta)) / (2.0 * kH);
        for (int r = 0; r < 6; ++r) {
          const double rel = std::abs(numeric[r] - analytic(r, k)) /
                             std::max(1e-3, std::abs(numeric[r]) + std::abs(analytic(r, k)));
          max_rel = std::max(max_rel, rel);
          sum_rel += rel;
          ++entries;
        }
      }
    }
  }
  std::printf("pose graph Jacobians: relative error mean %.3g, max %.3g over %d entries\n",
              sum_rel / entries, max_rel, entries);
  EXPECT_LT(max_rel, 1e-5);
  EXPECT_LT(sum_rel / entries, 1e-7);
}

struct Loop {
  std::vector<Eigen::Isometry3d> truth, odometry;  // world_from_camera
  std::vector<Eigen::Isometry3d> steps;            // measured relative poses i -> i+1
};

// A camera that circles a room (radius 1.5 m, looking outwards), 48 steps and back to its start;
// each step's measurement turns 0.25 degrees too far and carries noise, so chained odometry ends
// tens of centimetres off.
Loop MakeLoop(uint64_t seed) {
  constexpr int kSteps = 48;
  Loop loop;
  for (int i = 0; i <= kSteps; ++i) {
    const double angle = 2.0 * M_PI * (i % kSteps) / kSteps;
    loop.truth.push_back(Pose({0.0, angle, 0.0}, {1.5 * std::sin(angle), 0.1 * std::sin(3 * angle),
                                                  1.5 * std::cos(angle)}));
  }
  CounterRng rng(seed, 3);
  loop.odometry.push_back(loop.truth.front());
  for (int i = 0; i < kSteps; ++i) {
    const Eigen::Isometry3d step = loop.truth[i].inverse() * loop.truth[i + 1];
    Vector6d noise;
    for (int k = 0; k < 6; ++k)
      noise[k] = (k < 3 ? 1e-3 : 2e-3) * (2.0 * rng.UniformDouble() - 1.0);
    noise[1] += 0.25 * M_PI / 180.0;
    loop.steps.push_back(PerturbPose(step, noise));
    loop.odometry.push_back(loop.odometry.back() * loop.steps.back());
  }
  return loop;
}

double PositionRmse(const std::vector<Eigen::Isometry3d>& poses,
                    const std::vector<Eigen::Isometry3d>& truth) {
  double sum = 0.0;
  for (size_t i = 0; i < poses.size(); ++i)
    sum += (poses[i].translation() - truth[i].translation()).squaredNorm();
  return std::sqrt(sum / poses.size());
}

PoseGraph LoopGraph(const Loop& loop) {
  PoseGraph graph;
  const size_t n = loop.steps.size();
  for (size_t i = 0; i < n; ++i) graph.AddNode(loop.odometry[i]);
  for (size_t i = 0; i + 1 < n; ++i) {
    PoseGraphEdge edge;
    edge.from = static_cast<int>(i), edge.to = static_cast<int>(i + 1);
    edge.measured = loop.steps[i];
    graph.AddEdge(edge);
  }
  // The loop closure: the last step measured back to the first node (the revisit), as a
  // relocalisation would measure it.
  PoseGraphEdge closure;
  closure.from = static_cast<int>(n - 1), closure.to = 0;
  closure.measured = loop.steps[n - 1];
  graph.AddEdge(closure);
  return graph;
}

TEST(PoseGraph, ALoopClosureTakesOutMostOfTheOdometrysDrift) {
  const Loop loop = MakeLoop(7);
  const size_t n = loop.steps.size();
  const std::vector<Eigen::Isometry3d> truth(loop.truth.begin(), loop.truth.begin() + n);
  const std::vector<Eigen::Isometry3d> odometry(loop.odometry.begin(), loop.odometry.begin() + n);
  const double before = PositionRmse(odometry, truth);
  PoseGraph graph = LoopGraph(loop);
  const double cost_before = graph.Cost();
  const PoseGraphReport report = graph.Optimize();
  const double after = PositionRmse(graph.poses(), truth);
  std::printf(
      "loop of %zu poses: odometry %.2f cm RMS, after the closure %.2f cm; cost %.4g -> %.4g in %d "
      "iterations (%s)\n",
      n, 100 * before, 100 * after, report.initial_cost, report.final_cost, report.iterations,
      report.message.c_str());
  EXPECT_GT(before, 0.03);
  EXPECT_LT(after, before / 3.0);
  EXPECT_TRUE(report.converged) << report.message;
  EXPECT_NEAR(report.initial_cost, cost_before, 1e-9 * cost_before);
  EXPECT_LT(report.final_cost, 0.01 * report.initial_cost);
  EXPECT_NEAR(report.final_cost, graph.Cost(), 1e-9 + 1e-9 * report.final_cost);
  // The first node is the gauge: it does not move.
  EXPECT_TRUE(graph.poses()[0].isApprox(loop.odometry[0], 1e-15));
}

TEST(PoseGraph, SameResultWithOneAndTwoThreads) {
  const Loop loop = MakeLoop(11);
  std::vector<std::vector<Eigen::Isometry3d>> results;
  for (int threads : {1, 2}) {
    SetThreadCount(threads);
    PoseGraph graph = LoopGraph(loop);
    graph.Optimize();
    results.push_back(graph.poses());
  }
  SetThreadCount(0);
  for (size_t i = 0; i < results[0].size(); ++i)
    EXPECT_TRUE(results[0][i].matrix() == results[1][i].matrix()) << "node " << i;
}

TEST(PoseGraph, BadEdgesAreRefusedWithTheirNodes) {
  PoseGraph graph;
  graph.AddNode(Eigen::Isometry3d::Identity());
  graph.AddNode(Eigen::Isometry3d::Identity());
  PoseGraphEdge edge;
  edge.from = 0, edge.to = 2;
  EXPECT_CONTAINS(test::ErrorOf([&] { graph.AddEdge(edge); }), "edge 0 -> 2");
  edge.to = 0;
  EXPECT_CONTAINS(test::ErrorOf([&] { graph.AddEdge(edge); }), "must be distinct");
  edge.to = 1;
  edge.measured.linear() *= 2.0;
  EXPECT_CONTAINS(test::ErrorOf([&] { graph.AddEdge(edge); }), "not a rigid motion");
  edge.measured = Eigen::Isometry3d::Identity();
  edge.information(2, 2) = -1.0;
  EXPECT_CONTAINS(test::ErrorOf([&] { graph.AddEdge(edge); }), "negative eigenvalue");
  edge.information(2, 2) = std::nan("");
  EXPECT_CONTAINS(test::ErrorOf([&] { graph.AddEdge(edge); }), "not finite and symmetric");
  EXPECT_TRUE(graph.edges().empty());
  // Nothing free to move: nothing to do.
  edge.information = Matrix6d::Identity();
  graph.AddEdge(edge);
  graph.Fix(1);
  EXPECT_EQ(graph.Optimize().message, "nothing to optimise");
}

// Undoing a solve (loop closure undoes one that raised the cost): the last edge comes out, the
// poses are set back; wrong counts and non-rigid poses are refused.
TEST(PoseGraph, TheLastEdgeComesOutAndThePosesAreSetBack) {
  PoseGraph graph;
  graph.AddNode(Eigen::Isometry3d::Identity());
  graph.AddNode(Eigen::Isometry3d(Eigen::Translation3d(1.0, 0.0, 0.0)));
  PoseGraphEdge edge;
  edge.from = 0, edge.to = 1;
  edge.measured = Eigen::Translation3d(1.0, 0.0, 0.0);
  graph.AddEdge(edge);
  edge.measured = Eigen::Translation3d(1.2, 0.0, 0.0);
  graph.AddEdge(edge);
  const std::vector<Eigen::Isometry3d> before = graph.poses();
  graph.Optimize();
  EXPECT_NEAR(graph.poses()[1].translation().x(), 1.1, 1e-6);  // between the two measurements
  graph.RemoveLastEdge();
  graph.SetPoses(before);
  ASSERT_EQ(graph.edges().size(), 1u);
  EXPECT_EQ(graph.poses()[1].translation().x(), 1.0);
  EXPECT_EQ(graph.Cost(), 0.0);
  EXPECT_CONTAINS(test::ErrorOf([&] { graph.SetPoses({before[0]}); }), "1 poses for 2 nodes");
  Eigen::Isometry3d scaled = before[1];
  scaled.linear() *= 2.0;
  EXPECT_CONTAINS(test::ErrorOf([&] {
                    graph.SetPoses({before[0], scaled});
                  }),
                  "node 1: the pose is not a rigid motion");
}

}  // namespace
}  // namespace genscene::fusion
