// Sparse forward-mode automatic differentiation (the paper's section IV): a number carries its
// value and its derivatives with respect to the few mesh vertices it depends on, as a short list
// sorted by vertex. Arithmetic merges the lists, so a path that meets a new triangle "involves new
// vertex terms as required" and the derivatives of every bounce are carried forward.
//
// The parameters are vertex positions, so one entry holds the gradient with respect to a whole
// vertex (d value / d position, a 3-vector): a flat-shaded hit depends on 3 entries, a
// smooth-shaded one on the 3 vertices' one-rings (about 12). A number with an empty list is a
// constant; with no seeded variables the same code computes values only.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <utility>
#include <vector>

namespace genscene::render {

class SparseDual {
 public:
  struct Partial {
    int vertex;
    Eigen::Vector3d d;  // d value / d (vertex position)
  };

  SparseDual() = default;
  SparseDual(double value)
      : v_(value) {}  // NOLINT(google-explicit-constructor): constants mix freely
  // The coordinate `axis` of vertex `vertex`, whose value is `value`.
  static SparseDual Variable(double value, int vertex, int axis) {
    SparseDual x(value);
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[axis] = 1.0;
    x.d_.push_back({vertex, d});
    return x;
  }

  double value() const { return v_; }
  const std::vector<Partial>& partials() const { return d_; }
  // d value / d (coordinate `axis` of `vertex`); 0 when the number does not depend on it.
  double Derivative(int vertex, int axis) const {
    for (const Partial& p : d_) {
      if (p.vertex == vertex) return p.d[axis];
    }
    return 0.0;
  }

  // a x + b y (values and derivatives), the one merge every operator uses.
  static SparseDual Linear(double a, const SparseDual& x, double b, const SparseDual& y,
                           double value) {
    SparseDual r(value);
    r.d_.reserve(x.d_.size() + y.d_.size());
    auto i = x.d_.begin(), j = y.d_.begin();
    while (i != x.d_.end() || j != y.d_.end()) {
      if (j == y.d_.end() || (i != x.d_.end() && i->vertex < j->vertex)) {
        r.d_.push_back({i->vertex, a * i->d});
        ++i;
      } else if (i == x.d_.end() || j->vertex < i->vertex) {
        r.d_.push_back({j->vertex, b * j->d});
        ++j;
      } else {
        r.d_.push_back({i->vertex, a * i->d + b * j->d});
        ++i, ++j;
      }
    }
    return r;
  }
  // f(x) with f'(x) = `slope`: the chain rule on the derivative list.
  SparseDual Chain(double value, double slope) const& {
    SparseDual r(value);
    r.d_ = d_;
    for (Partial& p : r.d_) p.d *= slope;
    return r;
  }
  SparseDual Chain(double value, double slope) && {
    v_ = value;
    for (Partial& p : d_) p.d *= slope;
    return std::move(*this);
  }

  SparseDual operator-() const& { return Chain(-v_, -1.0); }
  SparseDual operator-() && { return std::move(*this).Chain(-v_, -1.0); }

  friend SparseDual operator+(const SparseDual& x, const SparseDual& y) {
    return Linear(1, x, 1, y, x.v_ + y.v_);
  }
  friend SparseDual operator-(const SparseDual& x, const SparseDual& y) {
    return Linear(1, x, -1, y, x.v_ - y.v_);
  }
  friend SparseDual operator*(const SparseDual& x, const SparseDual& y) {
    return Linear(y.v_, x, x.v_, y, x.v_ * y.v_);
  }
  friend SparseDual operator/(const SparseDual& x, const SparseDual& y) {
    const double inv = 1.0 / y.v_;
    return Linear(inv, x, -x.v_ * inv * inv, y, x.v_ * inv);
  }
  // With plain numbers: no merge.
  friend SparseDual operator+(SparseDual x, double c) { return std::move(x).Chain(x.v_ + c, 1.0); }
  friend SparseDual operator+(double c, SparseDual x) { return std::move(x) + c; }
  friend SparseDual operator-(SparseDual x, double c) { return std::move(x).Chain(x.v_ - c, 1.0); }
  friend SparseDual operator-(double c, SparseDual x) { return std::move(x).Chain(c - x.v_, -1.0); }
  friend SparseDual operator*(SparseDual x, double c) { return std::move(x).Chain(x.v_ * c, c); }
  friend SparseDual operator*(double c, SparseDual x) { return std::move(x) * c; }
  friend SparseDual operator/(SparseDual x, double c) { return std::move(x) * (1.0 / c); }
  friend SparseDual operator/(double c, SparseDual x) {
    const double inv = 1.0 / x.v_;
    return std::move(x).Chain(c * inv, -c * inv * inv);
  }
  SparseDual& operator+=(const SparseDual& y) { return *this = *this + y; }
  SparseDual& operator-=(const SparseDual& y) { return *this = *this - y; }
  SparseDual& operator*=(const SparseDual& y) { return *this = *this * y; }
  SparseDual& operator*=(double c) { return *this = std::move(*this) * c; }

  friend SparseDual sqrt(SparseDual x) {
    const double s = std::sqrt(x.v_);
    return std::move(x).Chain(s, s > 0.0 ? 0.5 / s : 0.0);
  }
  friend SparseDual abs(SparseDual x) { return x.v_ < 0.0 ? -std::move(x) : std::move(x); }

 private:
  double v_ = 0.0;
  std::vector<Partial> d_;  // sorted by vertex, no duplicates
};

// A 3-vector of sparse duals with the few operations the path tracer needs.
struct DualVec3 {
  SparseDual x, y, z;

  DualVec3() = default;
  DualVec3(SparseDual a, SparseDual b, SparseDual c)
      : x(std::move(a)), y(std::move(b)), z(std::move(c)) {}
  explicit DualVec3(const Eigen::Vector3d& c) : x(c.x()), y(c.y()), z(c.z()) {}
  // Vertex `vertex` at position `p`, its three coordinates seeded as variables.
  static DualVec3 Variable(const Eigen::Vector3d& p, int vertex) {
    return {SparseDual::Variable(p.x(), vertex, 0), SparseDual::Variable(p.y(), vertex, 1),
            SparseDual::Variable(p.z(), vertex, 2)};
  }

  Eigen::Vector3d value() const { return {x.value(), y.value(), z.value()}; }
  const SparseDual& operator[](int i) const { return i == 0 ? x : i == 1 ? y : z; }

  friend DualVec3 operator+(const DualVec3& a, const DualVec3& b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
  }
  friend DualVec3 operator-(const DualVec3& a, const DualVec3& b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
  }
  friend DualVec3 operator-(const DualVec3& a) { return {-a.x, -a.y, -a.z}; }
  friend DualVec3 operator*(const SparseDual& s, const DualVec3& a) {
    return {s * a.x, s * a.y, s * a.z};
  }
  friend DualVec3 operator*(double s, const DualVec3& a) { return {s * a.x, s * a.y, s * a.z}; }
  friend DualVec3 operator+(const DualVec3& a, const Eigen::Vector3d& b) {
    return {a.x + b.x(), a.y + b.y(), a.z + b.z()};
  }
  friend DualVec3 operator-(const Eigen::Vector3d& b, const DualVec3& a) {
    return {b.x() - a.x, b.y() - a.y, b.z() - a.z};
  }
};

inline SparseDual Dot(const DualVec3& a, const DualVec3& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline SparseDual Dot(const DualVec3& a, const Eigen::Vector3d& b) {
  return a.x * b.x() + a.y * b.y() + a.z * b.z();
}
inline DualVec3 Cross(const DualVec3& a, const DualVec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline SparseDual SquaredNorm(const DualVec3& a) {
  return Dot(a, a);
}
inline SparseDual Norm(const DualVec3& a) {
  return sqrt(SquaredNorm(a));
}
// a / |a|; a must not be zero.
inline DualVec3 Normalized(const DualVec3& a) {
  const SparseDual inv = 1.0 / Norm(a);
  return inv * a;
}

}  // namespace genscene::render
