#include "fusion/pose_graph.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>
#include <ceres/solver.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>

#include "core/check.h"

namespace genscene::fusion {

namespace {

// W with W^T W = Omega (W = sqrt(D) V^T from Omega = V D V^T), so that |W e|^2 = e^T Omega e. A
// singular information (an edge that does not constrain some direction) gives zero rows.
Matrix6d Whitening(const Matrix6d& information) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(information);
  const Vector6d d = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return d.asDiagonal() * eigen.eigenvectors().transpose();
}

// One edge's residual r = W e, with e = [log(R_E); t_E] and E = M^-1 A^-1 B (pose_graph.h). The
// poses are a unit quaternion (Eigen's x, y, z, w order) and a translation each.
class EdgeCost {
 public:
  EdgeCost(const Eigen::Isometry3d& measured, const Matrix6d& information)
      : measured_inverse_rotation_(Eigen::Quaterniond(measured.rotation()).conjugate()),
        measured_translation_(measured.translation()),
        whitening_(Whitening(information)) {}

  template <typename T>
  bool operator()(const T* q_from, const T* t_from, const T* q_to, const T* t_to,
                  T* residual) const {
    using Quaternion = Eigen::Quaternion<T>;
    using Vector3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Quaternion> qa(q_from), qb(q_to);
    const Eigen::Map<const Vector3> ta(t_from), tb(t_to);
    // A^-1 B: the pose of `to` in the frame of `from`.
    const Quaternion qa_inverse = qa.conjugate();
    const Quaternion q_ab = qa_inverse * qb;
    const Vector3 t_ab = qa_inverse * (tb - ta);
    // E = M^-1 (A^-1 B).
    const Quaternion m_inverse = measured_inverse_rotation_.cast<T>();
    const Quaternion q_e = m_inverse * q_ab;
    const Vector3 t_e = m_inverse * (t_ab - measured_translation_.cast<T>());
    const T wxyz[4] = {q_e.w(), q_e.x(), q_e.y(), q_e.z()};
    Eigen::Matrix<T, 6, 1> e;
    ceres::QuaternionToAngleAxis(wxyz, e.data());
    e.template tail<3>() = t_e;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r = whitening_.cast<T>() * e;
    return true;
  }

  static ceres::CostFunction* Create(const PoseGraphEdge& edge) {
    return new ceres::AutoDiffCostFunction<EdgeCost, 6, 4, 3, 4, 3>(
        new EdgeCost(edge.measured, edge.information));
  }

 private:
  Eigen::Quaterniond measured_inverse_rotation_;
  Eigen::Vector3d measured_translation_;
  Matrix6d whitening_;
};

// A pose as the solver's parameters: quaternion (x, y, z, w) then translation.
std::array<double, 7> ToParameters(const Eigen::Isometry3d& pose) {
  const Eigen::Quaterniond q(pose.rotation());
  return {q.x(),
          q.y(),
          q.z(),
          q.w(),
          pose.translation().x(),
          pose.translation().y(),
          pose.translation().z()};
}

Eigen::Isometry3d FromParameters(const std::array<double, 7>& p) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Quaterniond(p[3], p[0], p[1], p[2]).normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(p[4], p[5], p[6]);
  return pose;
}

bool IsRigid(const Eigen::Isometry3d& pose) {
  return IsValidRigidTransform(pose.matrix(), 1e-6);
}

}  // namespace

void PoseGraphOptions::Validate() const {
  if (max_iterations < 1)
    throw Error(Format("pose graph max_iterations = ", max_iterations, " must be >= 1"));
  if (!(function_tolerance >= 0.0) || !(parameter_tolerance >= 0.0)) {
    throw Error(Format("pose graph tolerances (", function_tolerance, ", ", parameter_tolerance,
                       ") must be >= 0"));
  }
}

Vector6d PoseGraphEdgeError(const Eigen::Isometry3d& world_from_from,
                            const Eigen::Isometry3d& world_from_to,
                            const Eigen::Isometry3d& measured) {
  const Eigen::Isometry3d e = measured.inverse() * world_from_from.inverse() * world_from_to;
  const Eigen::AngleAxisd rotation(e.rotation());
  Vector6d error;
  error.head<3>() = rotation.angle() * rotation.axis();
  error.tail<3>() = e.translation();
  return error;
}

Eigen::Isometry3d PerturbPose(const Eigen::Isometry3d& pose, const Vector6d& delta) {
  Eigen::Isometry3d out = pose;
  const Eigen::Vector3d w = delta.head<3>();
  const double angle = w.norm();
  const Eigen::Matrix3d exp_w = angle > 0.0 ? Eigen::AngleAxisd(angle, w / angle).toRotationMatrix()
                                            : Eigen::Matrix3d::Identity();
  out.linear() = pose.rotation() * exp_w;
  out.translation() = pose.translation() + pose.rotation() * delta.tail<3>();
  return out;
}

EdgeLinearisation LinearisePoseGraphEdge(const Eigen::Isometry3d& world_from_from,
                                         const Eigen::Isometry3d& world_from_to,
                                         const PoseGraphEdge& edge) {
  std::unique_ptr<ceres::CostFunction> cost(EdgeCost::Create(edge));
  std::array<double, 7> a = ToParameters(world_from_from), b = ToParameters(world_from_to);
  const double* parameters[4] = {a.data(), a.data() + 4, b.data(), b.data() + 4};
  Eigen::Matrix<double, 6, 4, Eigen::RowMajor> dqa, dqb;
  Eigen::Matrix<double, 6, 3, Eigen::RowMajor> dta, dtb;
  double* jacobians[4] = {dqa.data(), dta.data(), dqb.data(), dtb.data()};
  EdgeLinearisation out;
  GS_CHECK(cost->Evaluate(parameters, out.residual.data(), jacobians));
  // The right perturbation in the solver's parameters: q exp(w) gives dq/dw = 1/2 [q]_L's
  // vector columns (in x, y, z, w order); t + R v gives dt/dv = R, and t does not move with w.
  const auto tangent = [](const std::array<double, 7>& p) {
    const double x = p[0], y = p[1], z = p[2], w = p[3];
    Eigen::Matrix<double, 4, 3> dq;
    // q * (0, e_i) for the unit vectors e_i, in (x, y, z, w) rows.
    dq << w, -z, y,  //
        z, w, -x,    //
        -y, x, w,    //
        -x, -y, -z;
    return Eigen::Matrix<double, 4, 3>(0.5 * dq);
  };
  const Eigen::Matrix3d ra = world_from_from.rotation(), rb = world_from_to.rotation();
  out.d_from.leftCols<3>() = dqa * tangent(a);
  out.d_from.rightCols<3>() = dta * ra;
  out.d_to.leftCols<3>() = dqb * tangent(b);
  out.d_to.rightCols<3>() = dtb * rb;
  return out;
}

int PoseGraph::AddNode(const Eigen::Isometry3d& world_from_node) {
  if (!IsRigid(world_from_node)) {
    throw Error(Format("pose graph node ", poses_.size(), ": the pose is not a rigid motion"));
  }
  poses_.push_back(world_from_node);
  fixed_.push_back(poses_.size() == 1);
  return NodeCount() - 1;
}

void PoseGraph::RemoveLastEdge() {
  if (!edges_.empty()) edges_.pop_back();
}

void PoseGraph::SetPoses(const std::vector<Eigen::Isometry3d>& poses) {
  if (poses.size() != poses_.size()) {
    throw Error(Format("pose graph: ", poses.size(), " poses for ", poses_.size(), " nodes"));
  }
  for (size_t i = 0; i < poses.size(); ++i) {
    if (!IsRigid(poses[i]))
      throw Error(Format("pose graph node ", i, ": the pose is not a rigid motion"));
  }
  poses_ = poses;
}

void PoseGraph::AddEdge(const PoseGraphEdge& edge) {
  const auto in_range = [&](int n) { return n >= 0 && n < NodeCount(); };
  if (!in_range(edge.from) || !in_range(edge.to) || edge.from == edge.to) {
    throw Error(Format("pose graph edge ", edge.from, " -> ", edge.to,
                       ": nodes must be distinct, in [0, ", NodeCount(), ")"));
  }
  if (!IsRigid(edge.measured)) {
    throw Error(Format("pose graph edge ", edge.from, " -> ", edge.to,
                       ": the measurement is not a rigid motion"));
  }
  const Matrix6d& info = edge.information;
  const double scale = std::max(1.0, info.cwiseAbs().maxCoeff());
  if (!info.allFinite() || (info - info.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    throw Error(Format("pose graph edge ", edge.from, " -> ", edge.to,
                       ": the information matrix is not finite and symmetric"));
  }
  const double smallest = Eigen::SelfAdjointEigenSolver<Matrix6d>(info).eigenvalues().minCoeff();
  if (smallest < -1e-9 * scale) {
    throw Error(Format("pose graph edge ", edge.from, " -> ", edge.to,
                       ": the information matrix has a negative eigenvalue (", smallest, ")"));
  }
  edges_.push_back(edge);
}

void PoseGraph::Fix(int node) {
  fixed_.at(static_cast<size_t>(node)) = true;
}
void PoseGraph::Unfix(int node) {
  fixed_.at(static_cast<size_t>(node)) = false;
}

double PoseGraph::Cost() const {
  double cost = 0.0;
  for (const PoseGraphEdge& edge : edges_) {
    const Vector6d e = PoseGraphEdgeError(poses_[static_cast<size_t>(edge.from)],
                                          poses_[static_cast<size_t>(edge.to)], edge.measured);
    cost += 0.5 * e.dot(edge.information * e);
  }
  return cost;
}

PoseGraphReport PoseGraph::Optimize(const PoseGraphOptions& options) {
  options.Validate();
  PoseGraphReport report;
  report.initial_cost = report.final_cost = Cost();
  bool any_free = false;
  for (bool f : fixed_) any_free |= !f;
  if (edges_.empty() || !any_free) {
    report.converged = true;
    report.message = "nothing to optimise";
    return report;
  }
  // Build: two parameter blocks a node (the quaternion on its manifold, the translation).
  std::vector<std::array<double, 7>> parameters;
  parameters.reserve(poses_.size());
  for (const Eigen::Isometry3d& pose : poses_) parameters.push_back(ToParameters(pose));
  ceres::Problem problem;
  for (size_t i = 0; i < parameters.size(); ++i) {
    problem.AddParameterBlock(parameters[i].data(), 4, new ceres::EigenQuaternionManifold());
    problem.AddParameterBlock(parameters[i].data() + 4, 3);
    if (fixed_[i]) {
      problem.SetParameterBlockConstant(parameters[i].data());
      problem.SetParameterBlockConstant(parameters[i].data() + 4);
    }
  }
  for (const PoseGraphEdge& edge : edges_) {
    std::array<double, 7>& a = parameters[static_cast<size_t>(edge.from)];
    std::array<double, 7>& b = parameters[static_cast<size_t>(edge.to)];
    problem.AddResidualBlock(EdgeCost::Create(edge), nullptr, a.data(), a.data() + 4, b.data(),
                             b.data() + 4);
  }
  // Solve: Levenberg-Marquardt, sparse normal equations, one thread (deterministic).
  ceres::Solver::Options solver;
  solver.minimizer_type = ceres::TRUST_REGION;
  solver.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  solver.function_tolerance = options.function_tolerance;
  solver.parameter_tolerance = options.parameter_tolerance;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  solver.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  // Report.
  for (size_t i = 0; i < parameters.size(); ++i) {
    if (!fixed_[i]) poses_[i] = FromParameters(parameters[i]);
  }
  report.final_cost = Cost();
  report.iterations = static_cast<int>(summary.iterations.size()) - 1;
  report.converged = summary.termination_type == ceres::CONVERGENCE;
  report.message = summary.message;
  return report;
}

}  // namespace genscene::fusion
