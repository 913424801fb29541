// SE(3) helpers on Eigen. Transforms are named by direction (DESIGN.md §1): `world_from_camera`
// maps camera-frame points to the world frame; its inverse is `camera_from_world`.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace genscene {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Builds a rigid transform from a translation and a (not necessarily normalised) quaternion.
// Throws Error when the quaternion is not finite or has norm below 1e-9.
Eigen::Isometry3d PoseFromTranslationQuaternion(const Eigen::Vector3d& t,
                                                const Eigen::Quaterniond& q);

// The translation and unit quaternion of a rigid transform, with qw >= 0 (TUM's habit).
void ToTranslationQuaternion(const Eigen::Isometry3d& pose, Eigen::Vector3d* t,
                             Eigen::Quaterniond* q);

// Pose between a (alpha = 0) and b (alpha = 1): translation linear, rotation slerp.
Eigen::Isometry3d InterpolatePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                                  double alpha);

// Rotation angle of a transform in radians, in [0, pi].
double RotationAngle(const Eigen::Isometry3d& pose);

// Exponential map of se(3): xi = (rho, phi) = (translation part, rotation vector) -> SE(3),
// with the left Jacobian V so that ExpSE3 and LogSE3 are exact inverses.
Eigen::Isometry3d ExpSE3(const Vector6d& xi);
Vector6d LogSE3(const Eigen::Isometry3d& pose);

// Skew-symmetric matrix [v]x with [v]x w = v x w.
Eigen::Matrix3d Skew(const Eigen::Vector3d& v);

// True when every entry is finite and the rotation block is orthonormal to `tolerance`.
bool IsValidRigidTransform(const Eigen::Matrix4d& m, double tolerance = 1e-4);

}  // namespace genscene
