// Counter-based random numbers (DESIGN.md §1): a generator is keyed by (seed, and up to three
// stream ids such as pixel, sample and iteration) and its n-th draw is a pure hash of (key, n).
// The same seed gives the same numbers whatever the thread count or scheduling.
#pragma once

#include <cstdint>

namespace genscene {

// SplitMix64 finaliser: a bijective 64-bit mixer.
inline uint64_t Mix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

class CounterRng {
 public:
  CounterRng(uint64_t seed, uint64_t stream_a, uint64_t stream_b = 0, uint64_t stream_c = 0)
      : key_(Mix64(Mix64(Mix64(Mix64(seed) ^ stream_a) ^ stream_b) ^ stream_c)) {}

  uint64_t NextU64() { return Mix64(key_ + 0xD1B54A32D192ED03ull * (++counter_)); }
  // Uniform in [0, 1), 24 random bits.
  float Uniform() { return static_cast<float>(NextU64() >> 40) * (1.0f / 16777216.0f); }
  // Uniform in [0, 1), 53 random bits.
  double UniformDouble() {
    return static_cast<double>(NextU64() >> 11) * (1.0 / 9007199254740992.0);
  }
  // Uniform integer in [0, n), n > 0 (Lemire's multiply-shift; bias below 2^-32 for n < 2^32).
  uint32_t UniformInt(uint32_t n) {
    return static_cast<uint32_t>(((NextU64() >> 32) * static_cast<uint64_t>(n)) >> 32);
  }
  // Standard normal (Box-Muller, one of the pair).
  double Normal();

  uint64_t counter() const { return counter_; }

 private:
  uint64_t key_;
  uint64_t counter_ = 0;
};

}  // namespace genscene
