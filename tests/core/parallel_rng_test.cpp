#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/check.h"
#include "core/parallel.h"
#include "core/rng.h"

namespace genscene {
namespace {

double SumOfSquares(size_t n) {
  return DeterministicReduce(
      n, 1000, 0.0,
      [](size_t b, size_t e) {
        double s = 0.0;
        for (size_t i = b; i < e; ++i) s += std::sin(0.001 * i) * 1e-3 + 1.0 / (1.0 + i);
        return s;
      },
      [](double a, double b) { return a + b; });
}

TEST(Parallel, ReductionIsBitIdenticalWithOneAndTwoThreads) {
  SetThreadCount(1);
  const double one = SumOfSquares(1000003);
  SetThreadCount(2);
  const double two = SumOfSquares(1000003);
  SetThreadCount(0);
  const double all = SumOfSquares(1000003);
  EXPECT_EQ(one, two);
  EXPECT_EQ(one, all);
}

TEST(Parallel, ForVisitsEveryIndexOnce) {
  std::vector<int> hits(10007, 0);
  ParallelFor(
      0, hits.size(), [&](size_t i) { hits[i] += 1; }, 64);
  for (int h : hits) EXPECT_EQ(h, 1);
  EXPECT_THROW(SetThreadCount(-1), Error);
}

TEST(Rng, SameKeySameStreamDifferentKeyDifferentStream) {
  CounterRng a(42, 7, 3), b(42, 7, 3), c(42, 7, 4), d(43, 7, 3);
  for (int i = 0; i < 100; ++i) {
    const uint64_t x = a.NextU64();
    EXPECT_EQ(x, b.NextU64());
    EXPECT_NE(x, c.NextU64());
    EXPECT_NE(x, d.NextU64());
  }
}

TEST(Rng, UniformAndNormalMoments) {
  CounterRng rng(1, 2, 3);
  const int n = 200000;
  double sum = 0.0, sum2 = 0.0, nsum = 0.0, nsum2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double u = rng.Uniform();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    sum += u;
    sum2 += u * u;
    const double z = rng.Normal();
    nsum += z;
    nsum2 += z * z;
  }
  // Means within ~5 standard errors.
  EXPECT_NEAR(sum / n, 0.5, 5.0 * std::sqrt(1.0 / 12.0 / n));
  EXPECT_NEAR(sum2 / n - std::pow(sum / n, 2), 1.0 / 12.0, 2e-3);
  EXPECT_NEAR(nsum / n, 0.0, 5.0 / std::sqrt(n));
  EXPECT_NEAR(nsum2 / n, 1.0, 0.02);
  for (int i = 0; i < 1000; ++i) EXPECT_LT(rng.UniformInt(7), 7u);
}

}  // namespace
}  // namespace genscene
