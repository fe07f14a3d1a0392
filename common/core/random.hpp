// Hashing and pseudo-random numbers that Grotto owns, so that a world is the same on every
// machine and standard library: no std:: distributions, no hash-map iteration order.
#pragma once

#include <cstdint>

namespace grotto {

// SplitMix64 finalizer (Steele, Lea, Flood 2014): a bijective 64-bit mixer.
constexpr uint64_t mix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// Combines a running hash with one more 64-bit word; order matters.
constexpr uint64_t hash_combine(uint64_t h, uint64_t v) {
  return mix64(h ^ mix64(v));
}

template <typename... Words>
constexpr uint64_t hash_words(uint64_t first, Words... rest) {
  uint64_t h = mix64(first);
  ((h = hash_combine(h, static_cast<uint64_t>(rest))), ...);
  return h;
}

// 64-bit FNV-1a over bytes: the digest of serialized layouts and meshes.
constexpr uint64_t fnv1a64(const unsigned char* data, uint64_t size,
                           uint64_t h = 0xcbf29ce484222325ull) {
  for (uint64_t i = 0; i < size; ++i) {
    h ^= data[i];
    h *= 0x100000001b3ull;
  }
  return h;
}

// A SplitMix64 stream: tiny, fast, passes BigCrush, and its whole state is one word, so a
// stream is cheap to derive from a hash of (seed, what it is for).
class Rng {
 public:
  explicit constexpr Rng(uint64_t seed) : state_(seed) {}

  constexpr uint64_t next_u64() {
    state_ += 0x9e3779b97f4a7c15ull;
    uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1) with 53 random bits.
  constexpr double uniform() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  constexpr double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [0, n) for n > 0 (Lemire's multiply-shift; bias below 2^-32 for our n).
  constexpr uint32_t below(uint32_t n) {
    return static_cast<uint32_t>(((next_u64() >> 32) * static_cast<uint64_t>(n)) >> 32);
  }
  constexpr bool chance(double p) { return uniform() < p; }

 private:
  uint64_t state_;
};

}  // namespace grotto
