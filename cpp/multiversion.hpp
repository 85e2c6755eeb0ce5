// Function multi-versioning of the per-step kernels: a function marked SOCIALNAV_AVX2_CLONE is compiled twice,
// for AVX2 and for the baseline, and the dynamic loader picks one for the CPU it runs on (an ifunc). Both run
// the same IEEE operations in the same order (no contraction: -ffp-contract=off), so they give the same
// values. Multi-versioning needs ifunc support (GCC or Clang on x86-64 Linux); elsewhere (aarch64, macOS)
// each kernel is compiled once, for the target.
//
// SOCIALNAV_AVX512_CLONE adds a third build, for x86-64-v4 (AVX-512 with its 32 vector registers, which
// kernels that use explicit 4-lane vectors need so as not to spill them to the stack), with GCC 11 or later
// (the first that knows the level); with other compilers it is SOCIALNAV_AVX2_CLONE.
#pragma once

#if defined(__x86_64__) && defined(__linux__) && (defined(__GNUC__) || defined(__clang__))
#define SOCIALNAV_AVX2_CLONE __attribute__((target_clones("avx2", "default")))
#if !defined(__clang__) && __GNUC__ >= 11
#define SOCIALNAV_AVX512_CLONE __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#define SOCIALNAV_HAS_AVX512_CLONE 1
#else
#define SOCIALNAV_AVX512_CLONE SOCIALNAV_AVX2_CLONE
#endif
#else
#define SOCIALNAV_AVX2_CLONE
#define SOCIALNAV_AVX512_CLONE
#endif

namespace socialnav {

// The build of a SOCIALNAV_AVX512_CLONE function that runs on this CPU: "x86-64-v4", "avx2" or "baseline".
inline const char* avx512_clone_build() {
#if defined(SOCIALNAV_HAS_AVX512_CLONE)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("x86-64-v4")) return "x86-64-v4";
#endif
#if defined(__x86_64__) && defined(__linux__) && (defined(__GNUC__) || defined(__clang__))
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2")) return "avx2";
#endif
  return "baseline";
}

}  // namespace socialnav
