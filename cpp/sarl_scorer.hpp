// Native forward pass of the SARL value network for batched action scoring (inference only).
//
// SARL: C. Chen, Y. Liu, S. Kreiss, A. Alahi, "Crowd-Robot Interaction: Crowd-aware Robot Navigation
// with Attention-based Deep Reinforcement Learning", ICRA 2019. The network (mlp1 → mlp2 / attention
// → masked softmax → weighted sum → mlp3) is the one of socialnav/policies/learned/sarl.py; the
// PyTorch module stays the definition and the training path, this is a faster evaluator of it.
//
// Why it exists: on a CPU, evaluating the network layer by layer over a large block of states moves
// every activation through L3 or memory between two matmuls, which caps a chain of library matmuls
// at well under the machine's matmul rate. Here a small tile of states goes through all layers while
// its activations stay in L1/L2, and bias, ReLU and the global-state term are applied in the
// matmul's registers.
//
// Numerics: float32 with fused multiply-adds, each output summed in a fixed order (bias first, then
// the inputs in index order), so a state's value depends only on that state: identical for any batch
// size, tile size and thread count. Values differ from PyTorch's (whose summation order is the
// library's) by float32 rounding only.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thread_pool.hpp"

namespace socialnav {

// The vector kernel a scorer runs. Both compute every output with the same operations in the same
// order (bias, then one fused multiply-add per input in index order), so their values are
// bit-identical; AVX-512 computes twice as many outputs per instruction.
enum class ScorerKernel { none, avx2, avx512 };

// Whether this CPU runs `kernel` (x86-64: AVX2 + FMA; AVX-512F on top for avx512).
bool kernel_supported(ScorerKernel kernel);
// "auto" (the widest this CPU runs), "avx2" or "avx512"; throws with the reason when it cannot run.
ScorerKernel resolve_kernel(const std::string& name);
const char* kernel_name(ScorerKernel kernel);

struct DenseLayer {
  int in = 0;
  int out = 0;
  ScorerKernel kernel = ScorerKernel::avx2;  // the weights' packing (rows per block) is the kernel's
  // Row blocks of the weight matrix, each packed as [k][rows of the block] so that the kernel reads
  // it as one contiguous stream.
  struct Block {
    int row0;
    int rows;
    size_t offset;
  };
  std::vector<Block> blocks;
  std::vector<float> packed;
  std::vector<float> bias;  // out

  // weight: row-major (out, in) as PyTorch stores it; bias: (out) or null for zeros.
  DenseLayer(const float* weight, const float* bias, int out, int in, ScorerKernel kernel);
  DenseLayer() = default;
};

class SarlScorer {
 public:
  // Layers in PyTorch order, but for the first attention layer: with the global state, PyTorch's
  // Linear(2e, a) is given as its e-half (no bias) at the front of `attention` and its g-half with
  // the bias as the one layer of `global_term`, computed once per state; without it, `global_term`
  // is empty and the attention layers are PyTorch's.
  SarlScorer(std::vector<DenseLayer> mlp1, std::vector<DenseLayer> mlp2, std::vector<DenseLayer> attention,
             std::vector<DenseLayer> global_term, std::vector<DenseLayer> mlp3, int self_dim);

  // True when this CPU runs the vector kernels (x86-64 with AVX2 and FMA); the scorer refuses to run
  // otherwise (the caller uses PyTorch).
  static bool supported();

  int input_dim() const { return input_dim_; }
  ScorerKernel kernel() const { return kernel_; }

  // joint: (M, N, input_dim) float32, mask: (M, N) bytes (0/1), out: (M) float32.
  void values(const float* joint, const uint8_t* mask, int64_t M, int N, float* out, ThreadPool& pool,
              int states_per_tile) const;

 private:
  void tile_values(const float* joint, const uint8_t* mask, int64_t first, int count, int N, int S, float* out,
                   std::vector<float>& scratch) const;

  std::vector<DenseLayer> mlp1_, mlp2_, attention_, mlp3_;
  DenseLayer attention_g_;  // the g-half of the first attention layer (with its bias)
  ScorerKernel kernel_ = ScorerKernel::avx2;
  bool with_global_state_;
  int self_dim_;
  int input_dim_;
  int e_dim_;
  int width_;  // the widest activation
};

}  // namespace socialnav
