#include "core/se3.h"

#include <cmath>

#include "core/check.h"

namespace genscene {

Eigen::Isometry3d PoseFromTranslationQuaternion(const Eigen::Vector3d& t,
                                                const Eigen::Quaterniond& q) {
  const double norm = q.norm();
  if (!std::isfinite(norm) || norm < 1e-9 || !t.allFinite()) {
    throw Error(Format("invalid pose: translation (", t.transpose(), "), quaternion (", q.x(), " ",
                       q.y(), " ", q.z(), " ", q.w(), ")"));
  }
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = t;
  return pose;
}

void ToTranslationQuaternion(const Eigen::Isometry3d& pose, Eigen::Vector3d* t,
                             Eigen::Quaterniond* q) {
  *t = pose.translation();
  *q = Eigen::Quaterniond(pose.rotation()).normalized();
  if (q->w() < 0.0) q->coeffs() *= -1.0;
}

Eigen::Isometry3d InterpolatePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                                  double alpha) {
  const Eigen::Quaterniond qa(a.rotation());
  const Eigen::Quaterniond qb(b.rotation());
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = qa.slerp(alpha, qb).toRotationMatrix();
  out.translation() = (1.0 - alpha) * a.translation() + alpha * b.translation();
  return out;
}

double RotationAngle(const Eigen::Isometry3d& pose) {
  return Eigen::AngleAxisd(pose.rotation()).angle();
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

namespace {

// Left Jacobian of SO(3): V = I + (1 - cos t)/t^2 [phi]x + (t - sin t)/t^3 [phi]x^2.
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d k = Skew(phi);
  if (theta < 1e-8) return Eigen::Matrix3d::Identity() + 0.5 * k;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * k +
         (theta - std::sin(theta)) / (t2 * theta) * k * k;
}

}  // namespace

Eigen::Isometry3d ExpSE3(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  const double theta = phi.norm();
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = theta < 1e-12 ? Eigen::Matrix3d::Identity()
                               : Eigen::AngleAxisd(theta, phi / theta).toRotationMatrix();
  out.translation() = LeftJacobianSO3(phi) * rho;
  return out;
}

Vector6d LogSE3(const Eigen::Isometry3d& pose) {
  const Eigen::AngleAxisd aa(pose.rotation());
  const Eigen::Vector3d phi = aa.axis() * aa.angle();
  Vector6d xi;
  xi.head<3>() = LeftJacobianSO3(phi).inverse() * pose.translation();
  xi.tail<3>() = phi;
  return xi;
}

bool IsValidRigidTransform(const Eigen::Matrix4d& m, double tolerance) {
  if (!m.allFinite()) return false;
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if (!(r * r.transpose()).isApprox(Eigen::Matrix3d::Identity(), tolerance)) return false;
  if (std::abs(r.determinant() - 1.0) > tolerance) return false;
  return m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), tolerance);
}

}  // namespace genscene
