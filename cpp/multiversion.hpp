// Function multi-versioning of the per-step kernels: a function marked SOCIALNAV_AVX2_CLONE is compiled twice,
// for AVX2 and for the baseline, and the dynamic loader picks one for the CPU it runs on (an ifunc). Both run
// the same IEEE operations in the same order (no contraction: -ffp-contract=off), so they give the same
// values. Multi-versioning needs ifunc support (GCC or Clang on x86-64 Linux); elsewhere (aarch64, macOS)
// each kernel is compiled once, for the target.
#pragma once

#if defined(__x86_64__) && defined(__linux__) && (defined(__GNUC__) || defined(__clang__))
#define SOCIALNAV_AVX2_CLONE __attribute__((target_clones("avx2", "default")))
#else
#define SOCIALNAV_AVX2_CLONE
#endif
