// The vector kernels of the SARL scorer (sarl_kernels.hpp): AVX2 + FMA and AVX-512.
#include "sarl_kernels.hpp"

#include <cstddef>
#include <stdexcept>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define SOCIALNAV_X86_KERNELS 1
#include <immintrin.h>
#else
#define SOCIALNAV_X86_KERNELS 0
#endif

namespace socialnav {

// Rows per block. AVX2 (16 ymm registers): 6 (12 accumulators) where the width allows, else 5 (10),
// so that every width the networks use (50, 100, 150, 200) is covered without a short, latency-bound
// remainder block. AVX-512 (32 zmm registers): 10 rows of two vectors (20 accumulators), else 12 or 8.
int kernel_block_rows(int out, ScorerKernel kernel) {
  if (kernel == ScorerKernel::avx512) {
    if (out % 10 == 0) return 10;
    if (out % 12 == 0) return 12;
    if (out % 8 == 0) return 8;
    return 10;
  }
  if (out % 6 == 0) return 6;
  if (out % 5 == 0) return 5;
  return 6;
}

namespace {

#if SOCIALNAV_X86_KERNELS
// Y[r][c0 .. c0+16) for the block's MR rows: acc = bias; acc += W[r][k] · X[k][·] for k = 0 .. K-1
// (one fused multiply-add each, in that order); optional ReLU. The accumulators are named variables
// rather than an array: GCC keeps an array in registers but also stores it to the stack on every
// iteration, which halves the kernel's speed.
#define SN_ROW(R)                                                                               \
  __m256 a##R##0 = MR > R ? _mm256_broadcast_ss(bias + (MR > R ? R : 0)) : _mm256_setzero_ps(); \
  __m256 a##R##1 = a##R##0;
#define SN_FMA(R)                                 \
  if constexpr (MR > R) {                         \
    const __m256 wr = _mm256_broadcast_ss(w + R); \
    a##R##0 = _mm256_fmadd_ps(wr, x0, a##R##0);   \
    a##R##1 = _mm256_fmadd_ps(wr, x1, a##R##1);   \
  }
#define SN_STORE(R)                                                  \
  if constexpr (MR > R) {                                            \
    if (relu) {                                                      \
      a##R##0 = _mm256_max_ps(a##R##0, zero);                        \
      a##R##1 = _mm256_max_ps(a##R##1, zero);                        \
    }                                                                \
    _mm256_storeu_ps(y + static_cast<size_t>(R) * ldy, a##R##0);     \
    _mm256_storeu_ps(y + static_cast<size_t>(R) * ldy + 8, a##R##1); \
  }
template <int MR>
__attribute__((target("avx2,fma"))) void dense_kernel(const float* __restrict wp, const float* __restrict bias,
                                                      const float* __restrict x, int ldx, float* __restrict y, int ldy,
                                                      int K, bool relu) {
  SN_ROW(0)
  SN_ROW(1)
  SN_ROW(2)
  SN_ROW(3)
  SN_ROW(4)
  SN_ROW(5)
  for (int k = 0; k < K; ++k) {
    const __m256 x0 = _mm256_loadu_ps(x + static_cast<size_t>(k) * ldx);
    const __m256 x1 = _mm256_loadu_ps(x + static_cast<size_t>(k) * ldx + 8);
    const float* w = wp + static_cast<size_t>(k) * MR;
    SN_FMA(0)
    SN_FMA(1)
    SN_FMA(2)
    SN_FMA(3)
    SN_FMA(4)
    SN_FMA(5)
  }
  const __m256 zero = _mm256_setzero_ps();
  SN_STORE(0)
  SN_STORE(1)
  SN_STORE(2)
  SN_STORE(3)
  SN_STORE(4)
  SN_STORE(5)
}
#undef SN_ROW
#undef SN_FMA
#undef SN_STORE

using Kernel = void (*)(const float*, const float*, const float*, int, float*, int, int, bool);

Kernel kernel_for(int rows) {
  switch (rows) {
    case 1: return dense_kernel<1>;
    case 2: return dense_kernel<2>;
    case 3: return dense_kernel<3>;
    case 4: return dense_kernel<4>;
    case 5: return dense_kernel<5>;
    case 6: return dense_kernel<6>;
    default: throw std::logic_error("sarl scorer: bad block size");
  }
}

// The AVX-512 kernel: the same arithmetic per output as dense_kernel (acc = bias, then one fused
// multiply-add per input in index order, then the optional ReLU), over NV 16-float vectors of columns
// and up to 12 rows, so its values are bit-identical to the AVX2 kernel's; only the number of outputs
// computed per instruction differs.
#define SN_ROW(R)                                                                       \
  __m512 a##R##0 = MR > R ? _mm512_set1_ps(bias[MR > R ? R : 0]) : _mm512_setzero_ps(); \
  __m512 a##R##1 = a##R##0;
#define SN_FMA(R)                                                     \
  if constexpr (MR > R) {                                             \
    const __m512 wr = _mm512_set1_ps(w[R]);                           \
    a##R##0 = _mm512_fmadd_ps(wr, x0, a##R##0);                       \
    if constexpr (NV > 1) a##R##1 = _mm512_fmadd_ps(wr, x1, a##R##1); \
  }
#define SN_STORE(R)                                                                         \
  if constexpr (MR > R) {                                                                   \
    if (relu) {                                                                             \
      a##R##0 = _mm512_max_ps(a##R##0, zero);                                               \
      if constexpr (NV > 1) a##R##1 = _mm512_max_ps(a##R##1, zero);                         \
    }                                                                                       \
    _mm512_storeu_ps(y + static_cast<size_t>(R) * ldy, a##R##0);                            \
    if constexpr (NV > 1) _mm512_storeu_ps(y + static_cast<size_t>(R) * ldy + 16, a##R##1); \
  }
template <int MR, int NV>
__attribute__((target("avx512f"))) void dense_kernel512(const float* __restrict wp, const float* __restrict bias,
                                                        const float* __restrict x, int ldx, float* __restrict y,
                                                        int ldy, int K, bool relu) {
  SN_ROW(0)
  SN_ROW(1)
  SN_ROW(2)
  SN_ROW(3)
  SN_ROW(4)
  SN_ROW(5)
  SN_ROW(6)
  SN_ROW(7)
  SN_ROW(8)
  SN_ROW(9)
  SN_ROW(10)
  SN_ROW(11)
  for (int k = 0; k < K; ++k) {
    const __m512 x0 = _mm512_loadu_ps(x + static_cast<size_t>(k) * ldx);
    const __m512 x1 = NV > 1 ? _mm512_loadu_ps(x + static_cast<size_t>(k) * ldx + 16) : x0;
    const float* w = wp + static_cast<size_t>(k) * MR;
    SN_FMA(0)
    SN_FMA(1)
    SN_FMA(2)
    SN_FMA(3)
    SN_FMA(4)
    SN_FMA(5)
    SN_FMA(6)
    SN_FMA(7)
    SN_FMA(8)
    SN_FMA(9)
    SN_FMA(10)
    SN_FMA(11)
  }
  const __m512 zero = _mm512_setzero_ps();
  SN_STORE(0)
  SN_STORE(1)
  SN_STORE(2)
  SN_STORE(3)
  SN_STORE(4)
  SN_STORE(5)
  SN_STORE(6)
  SN_STORE(7)
  SN_STORE(8)
  SN_STORE(9)
  SN_STORE(10)
  SN_STORE(11)
}
#undef SN_ROW
#undef SN_FMA
#undef SN_STORE

template <int NV>
Kernel kernel512_for(int rows) {
  switch (rows) {
    case 1: return dense_kernel512<1, NV>;
    case 2: return dense_kernel512<2, NV>;
    case 3: return dense_kernel512<3, NV>;
    case 4: return dense_kernel512<4, NV>;
    case 5: return dense_kernel512<5, NV>;
    case 6: return dense_kernel512<6, NV>;
    case 7: return dense_kernel512<7, NV>;
    case 8: return dense_kernel512<8, NV>;
    case 9: return dense_kernel512<9, NV>;
    case 10: return dense_kernel512<10, NV>;
    case 11: return dense_kernel512<11, NV>;
    case 12: return dense_kernel512<12, NV>;
    default: throw std::logic_error("sarl scorer: bad block size");
  }
}
#endif

}  // namespace

void dense_layer(const DenseLayer& layer, const float* x, float* y, int cols, bool relu) {
#if SOCIALNAV_X86_KERNELS
  // Panel outer, blocks inner: the panel of X (in × 16 or 32 floats) stays in L1 while the packed
  // weights stream through once per panel.
  auto run = [&](int c0, int width, Kernel (*pick)(int)) {
    for (const auto& b : layer.blocks)
      pick(b.rows)(layer.packed.data() + b.offset, layer.bias.data() + b.row0, x + c0, cols,
                   y + static_cast<size_t>(b.row0) * cols + c0, cols, layer.in, relu);
    return c0 + width;
  };
  int c0 = 0;
  if (layer.kernel == ScorerKernel::avx512) {
    while (c0 + 2 * kScorerPanel <= cols) c0 = run(c0, 2 * kScorerPanel, kernel512_for<2>);
    while (c0 < cols) c0 = run(c0, kScorerPanel, kernel512_for<1>);  // cols is a multiple of 16
  } else {
    while (c0 < cols) c0 = run(c0, kScorerPanel, kernel_for);
  }
#else
  (void)layer, (void)x, (void)y, (void)cols, (void)relu;
  throw std::runtime_error("sarl scorer: no vector kernels on this CPU");
#endif
}

bool kernel_supported(ScorerKernel kernel) {
#if SOCIALNAV_X86_KERNELS
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  switch (kernel) {
    case ScorerKernel::avx2: return avx2;
    case ScorerKernel::avx512: return avx2 && __builtin_cpu_supports("avx512f");
    default: return false;
  }
#else
  (void)kernel;
  return false;
#endif
}

}  // namespace socialnav
