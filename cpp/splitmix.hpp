// Counter-based hashing shared by the native random draws: splitmix64's finaliser (Steele, Lea & Flood,
// "Fast splittable pseudorandom number generators", OOPSLA 2014) and the chaining of words into one hash
// (socialnav/scenarios/episode_random.py mirrors both bit for bit; wrap-around is intended).
#pragma once

#include <cstdint>

namespace socialnav {

inline constexpr uint64_t kGolden = 0x9E3779B97F4A7C15ULL;

inline uint64_t fmix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// The hash of `h` followed by `word` (random.py: _chain_int).
inline uint64_t chain64(uint64_t h, uint64_t word) { return fmix64((h ^ word) + kGolden); }

}  // namespace socialnav
