// A pose graph over camera poses (keyframes): nodes are world_from_camera poses, edges relative
// poses measured between two nodes (odometry from tracking, loop closures from relocalisation),
// each with the information matrix of its 6-vector error. Optimised with Ceres (Levenberg-Marquardt
// on the quaternion manifold); Ceres stays inside pose_graph.cpp.
//
// The error of an edge from node a to node b with measurement M (the pose of b in a's frame,
// a_from_b) at the poses A = world_from_a, B = world_from_b:
//
//   E = M^-1 A^-1 B                         (identity when the poses agree with the measurement)
//   e = [ log(R_E) ; t_E ]                  (rotation vector in rad, translation in m: in M's
//   frame) cost = 1/2 e^T Omega e                  (Omega: the edge's information, 6x6 symmetric >=
//   0)
//
// The graph has a gauge freedom (a rigid motion of all poses); the nodes marked fixed (by default
// the first) keep their pose.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "core/se3.h"

namespace genscene::fusion {

using Matrix6d = Eigen::Matrix<double, 6, 6>;  // Vector6d: core/se3.h

struct PoseGraphEdge {
  int from = 0;
  int to = 0;
  Eigen::Isometry3d measured = Eigen::Isometry3d::Identity();  // from_T_to
  Matrix6d information = Matrix6d::Identity();  // of e = [rotation (rad); translation (m)]
};

struct PoseGraphOptions {
  int max_iterations = 100;           // Levenberg-Marquardt iterations at most
  double function_tolerance = 1e-12;  // relative decrease of the cost that ends the solve
  double parameter_tolerance = 1e-12;
  void Validate() const;
};

struct PoseGraphReport {
  double initial_cost = 0.0;  // 1/2 sum of e^T Omega e over the edges
  double final_cost = 0.0;
  int iterations = 0;
  bool converged = false;  // Ceres stopped on a tolerance (not on the iteration limit or a failure)
  std::string message;     // Ceres' reason for stopping
};

// The 6-vector error e of an edge (above) at the given poses.
Vector6d PoseGraphEdgeError(const Eigen::Isometry3d& world_from_from,
                            const Eigen::Isometry3d& world_from_to,
                            const Eigen::Isometry3d& measured);

// The edge's whitened residual r = L^T e (Omega = L L^T) and its Jacobians with respect to each
// pose's 6-vector tangent perturbation: the pose exp([w; v]) applied on the right,
// R <- R exp(w), t <- t + R v (the derivative the solver uses, from Ceres' automatic
// differentiation through its quaternion manifold). For tests and diagnostics.
struct EdgeLinearisation {
  Vector6d residual;
  Matrix6d d_from;  // d r / d (perturbation of the `from` pose)
  Matrix6d d_to;
};
EdgeLinearisation LinearisePoseGraphEdge(const Eigen::Isometry3d& world_from_from,
                                         const Eigen::Isometry3d& world_from_to,
                                         const PoseGraphEdge& edge);

// The pose applied with a tangent perturbation as above (R exp(w), t + R v).
Eigen::Isometry3d PerturbPose(const Eigen::Isometry3d& pose, const Vector6d& delta);

class PoseGraph {
 public:
  // Adds a node at `world_from_node`; returns its index (0, 1, ...).
  int AddNode(const Eigen::Isometry3d& world_from_node);
  // Throws when a node index is out of range, from == to, the measurement is not rigid, or the
  // information is not symmetric positive semi-definite and finite.
  void AddEdge(const PoseGraphEdge& edge);
  // Takes the last edge added out again.
  void RemoveLastEdge();
  // Sets every node's pose (as many as there are nodes, each rigid); throws otherwise.
  void SetPoses(const std::vector<Eigen::Isometry3d>& poses);
  // Holds a node's pose during Optimize. Node 0 is fixed unless Unfix(0) is called.
  void Fix(int node);
  void Unfix(int node);

  // 1/2 sum of e^T Omega e at the current poses.
  double Cost() const;
  // Moves the free nodes to minimise Cost(). Deterministic: one thread, the same result for the
  // same graph whatever the thread count of the rest of the program.
  PoseGraphReport Optimize(const PoseGraphOptions& options = PoseGraphOptions());

  int NodeCount() const { return static_cast<int>(poses_.size()); }
  const std::vector<Eigen::Isometry3d>& poses() const { return poses_; }
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  bool fixed(int node) const { return fixed_.at(static_cast<size_t>(node)); }

 private:
  std::vector<Eigen::Isometry3d> poses_;
  std::vector<bool> fixed_;
  std::vector<PoseGraphEdge> edges_;
};

}  // namespace genscene::fusion
