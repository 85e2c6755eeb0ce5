// The vector kernels of the SARL scorer (sarl_scorer.hpp): one dense layer over a panel of columns, in
// AVX2 + FMA and in AVX-512, each output computed with the same operations in the same order (bias,
// then one fused multiply-add per input in index order, then the optional ReLU), so the two kernels'
// values are bit-identical. Their register budgets decide how a layer's weights are packed.
#pragma once

#include "sarl_scorer.hpp"

namespace socialnav {

constexpr int kScorerPanel = 16;  // columns per AVX2 kernel call (two 8-float vectors); AVX-512 takes 16 or 32

// Rows per packed weight block of a layer with `out` outputs, for `kernel` (DenseLayer's packing).
int kernel_block_rows(int out, ScorerKernel kernel);

// Y (layer.out x cols) = layer(X (layer.in x cols)), feature-major with row stride `cols` (a multiple of
// kScorerPanel), by the layer's kernel; ReLU after when `relu`. Throws where no vector kernel is compiled.
void dense_layer(const DenseLayer& layer, const float* x, float* y, int cols, bool relu);

}  // namespace socialnav
