// Plain image containers. Row-major, row 0 at the top, pixel (u, v) = column u, row v.
// Colour images hold LINEAR RGB floats (the sRGB decode happens once, at input, see color.h);
// depth images hold planar z in meters with 0 meaning "no measurement".
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <type_traits>
#include <vector>

#include "core/check.h"

namespace genscene {

// Zero of a pixel type: 0 for numbers, T::Zero() for Eigen vectors (whose default constructor
// leaves them uninitialised).
template <typename T>
T ZeroPixel() {
  if constexpr (std::is_arithmetic_v<T>) {
    return T(0);
  } else {
    return T::Zero();
  }
}

template <typename T>
class Image {
 public:
  Image() = default;
  // A width x height image with every pixel `fill` (zero by default).
  Image(int width, int height, const T& fill = ZeroPixel<T>()) : width_(width), height_(height) {
    GS_CHECK_GE(width, 0);
    GS_CHECK_GE(height, 0);
    data_.assign(static_cast<size_t>(width) * static_cast<size_t>(height), fill);
  }

  int width() const { return width_; }
  int height() const { return height_; }
  bool empty() const { return data_.empty(); }
  size_t size() const { return data_.size(); }

  T& operator()(int u, int v) { return data_[Index(u, v)]; }
  const T& operator()(int u, int v) const { return data_[Index(u, v)]; }
  T* data() { return data_.data(); }
  const T* data() const { return data_.data(); }
  std::vector<T>& pixels() { return data_; }
  const std::vector<T>& pixels() const { return data_; }

  bool SameSize(int width, int height) const { return width_ == width && height_ == height; }
  template <typename U>
  bool SameSize(const Image<U>& other) const {
    return SameSize(other.width(), other.height());
  }

 private:
  size_t Index(int u, int v) const {
    return static_cast<size_t>(v) * static_cast<size_t>(width_) + static_cast<size_t>(u);
  }

  int width_ = 0;
  int height_ = 0;
  std::vector<T> data_;
};

using ImageRgb = Image<Eigen::Vector3f>;  // linear RGB
using ImageDepth = Image<float>;          // planar z in meters, 0 = invalid
using ImageGray = Image<float>;

}  // namespace genscene
