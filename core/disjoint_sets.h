// Union-find with path halving over the elements 0..n-1. The root of a set is its smallest
// member, so the result does not depend on the order of the unions (deterministic labels).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

#include "core/check.h"

namespace genscene {

class DisjointSets {
 public:
  explicit DisjointSets(size_t n) : parent_(n) {
    GS_CHECK_LE(n, static_cast<size_t>(UINT32_MAX));
    std::iota(parent_.begin(), parent_.end(), 0u);
  }
  uint32_t Find(uint32_t a) {
    while (parent_[a] != a) a = parent_[a] = parent_[parent_[a]];
    return a;
  }
  void Union(uint32_t a, uint32_t b) {
    a = Find(a), b = Find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<uint32_t> parent_;
};

}  // namespace genscene
