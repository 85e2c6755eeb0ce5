#include "sarl_scorer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "sarl_kernels.hpp"

namespace socialnav {

namespace {

// Runs layers[from ..] on x, alternating between p and q (neither may alias x unless x is one of
// them), the last layer into `last_out` if given; ReLU between layers and after the last one if
// `last_relu`. Returns the output buffer (x itself when there is no layer to run).
const float* chain(const std::vector<DenseLayer>& layers, size_t from, const float* x, int cols, float* p, float* q,
                   bool last_relu, float* last_out = nullptr) {
  const float* cur = x;
  for (size_t i = from; i < layers.size(); ++i) {
    const bool last = i + 1 == layers.size();
    float* dst = (last && last_out) ? last_out : (cur == p) ? q : p;
    dense_layer(layers[i], cur, dst, cols, !last || last_relu);
    cur = dst;
  }
  return cur;
}

}  // namespace

DenseLayer::DenseLayer(const float* weight, const float* b, int out_, int in_, ScorerKernel kernel_)
    : in(in_), out(out_), kernel(kernel_) {
  if (in <= 0 || out <= 0) throw std::invalid_argument("sarl scorer: layer sizes must be positive");
  const int mr = kernel_block_rows(out, kernel);
  packed.resize(static_cast<size_t>(in) * out);
  size_t offset = 0;
  for (int row0 = 0; row0 < out; row0 += mr) {
    const int rows = std::min(mr, out - row0);
    blocks.push_back({row0, rows, offset});
    for (int k = 0; k < in; ++k)
      for (int r = 0; r < rows; ++r) packed[offset++] = weight[static_cast<size_t>(row0 + r) * in + k];
  }
  if (b)
    bias.assign(b, b + out);
  else
    bias.assign(static_cast<size_t>(out), 0.0f);
}

SarlScorer::SarlScorer(std::vector<DenseLayer> mlp1, std::vector<DenseLayer> mlp2, std::vector<DenseLayer> attention,
                       std::vector<DenseLayer> global_term, std::vector<DenseLayer> mlp3, int self_dim)
    : mlp1_(std::move(mlp1)),
      mlp2_(std::move(mlp2)),
      attention_(std::move(attention)),
      mlp3_(std::move(mlp3)),
      with_global_state_(!global_term.empty()),
      self_dim_(self_dim) {
  if (mlp1_.empty() || mlp2_.empty() || attention_.empty() || mlp3_.empty())
    throw std::invalid_argument("sarl scorer: every MLP needs at least one layer");
  if (global_term.size() > 1) throw std::invalid_argument("sarl scorer: the global term is one layer");
  kernel_ = mlp1_.front().kernel;
  for (const auto* layers : {&mlp1_, &mlp2_, &attention_, &global_term, &mlp3_})
    for (const auto& l : *layers)
      if (l.kernel != kernel_) throw std::invalid_argument("sarl scorer: layers packed for different kernels");
  input_dim_ = mlp1_.front().in;
  e_dim_ = mlp1_.back().out;
  auto check_chain = [](const std::vector<DenseLayer>& layers, int in, const char* name) {
    for (const auto& l : layers) {
      if (l.in != in)
        throw std::invalid_argument(std::string("sarl scorer: ") + name + " layer expects " + std::to_string(l.in) +
                                    " inputs, gets " + std::to_string(in));
      in = l.out;
    }
    return in;
  };
  check_chain(mlp1_, input_dim_, "mlp1");
  const int h_dim = check_chain(mlp2_, e_dim_, "mlp2");
  if (check_chain(mlp3_, self_dim_ + h_dim, "mlp3") != 1)
    throw std::invalid_argument("sarl scorer: mlp3 must end in 1");
  if (check_chain(attention_, e_dim_, "attention") != 1)
    throw std::invalid_argument("sarl scorer: the attention MLP must end in 1");
  if (with_global_state_) {
    attention_g_ = std::move(global_term.front());
    if (attention_g_.in != e_dim_ || attention_g_.out != attention_.front().out)
      throw std::invalid_argument("sarl scorer: the global term must map " + std::to_string(e_dim_) + " to " +
                                  std::to_string(attention_.front().out) + " values");
  }
  width_ = std::max({input_dim_, self_dim_ + h_dim, 1});
  for (const auto* layers : {&mlp1_, &mlp2_, &attention_, &mlp3_})
    for (const auto& l : *layers) width_ = std::max(width_, l.out);
}

bool SarlScorer::supported() { return kernel_supported(ScorerKernel::avx2); }

ScorerKernel resolve_kernel(const std::string& name) {
  if (name == "auto") {
    if (kernel_supported(ScorerKernel::avx512)) return ScorerKernel::avx512;
    if (kernel_supported(ScorerKernel::avx2)) return ScorerKernel::avx2;
    throw std::runtime_error("sarl scorer: this CPU lacks AVX2/FMA");
  }
  ScorerKernel kernel;
  if (name == "avx2")
    kernel = ScorerKernel::avx2;
  else if (name == "avx512")
    kernel = ScorerKernel::avx512;
  else
    throw std::invalid_argument("sarl scorer: unknown kernel '" + name + "' (expected auto, avx2 or avx512)");
  if (!kernel_supported(kernel)) throw std::runtime_error("sarl scorer: this CPU cannot run the " + name + " kernel");
  return kernel;
}

const char* kernel_name(ScorerKernel kernel) {
  switch (kernel) {
    case ScorerKernel::avx2: return "avx2";
    case ScorerKernel::avx512: return "avx512";
    default: return "none";
  }
}

void SarlScorer::values(const float* joint, const uint8_t* mask, int64_t M, int N, float* out, ThreadPool& pool,
                        int states_per_tile) const {
  if (!kernel_supported(kernel_)) throw std::runtime_error("sarl scorer: this CPU lacks AVX2/FMA");
  if (N < 1) throw std::invalid_argument("sarl scorer: N must be >= 1");
  if (states_per_tile < kScorerPanel || states_per_tile % kScorerPanel != 0)
    throw std::invalid_argument("sarl scorer: states_per_tile must be a positive multiple of 16");
  const int S = states_per_tile;
  const int64_t tiles = (M + S - 1) / S;
  if (tiles > INT32_MAX) throw std::invalid_argument("sarl scorer: too many states");
  pool.parallel_for(static_cast<int>(tiles), [&](int begin, int end, int /*worker*/) {
    // Per-thread activations, kept from call to call: the pool's threads live as long as the pool,
    // so a small call (one episode: three tiles) allocates nothing.
    thread_local std::vector<float> scratch;
    for (int t = begin; t < end; ++t) {
      const int64_t first = static_cast<int64_t>(t) * S;
      const int count = static_cast<int>(std::min<int64_t>(S, M - first));
      tile_values(joint, mask, first, count, N, S, out, scratch);
    }
  });
}

void SarlScorer::tile_values(const float* joint, const uint8_t* mask, int64_t first, int count, int N, int S,
                             float* out, std::vector<float>& scratch) const {
  const int C = N * S;  // column i·S + s: human i of state s
  const int D = input_dim_, E = e_dim_, W = width_;
  const size_t wc = static_cast<size_t>(W) * C;
  const size_t need = static_cast<size_t>(D) * C + static_cast<size_t>(E) * C + 3 * wc + C +
                      static_cast<size_t>(E) * S + 2 * static_cast<size_t>(W) * S + static_cast<size_t>(N) * S;
  if (scratch.size() < need) scratch.resize(need);
  // Every buffer is written before it is read (x0 and x3 are cleared below).
  float* x0 = scratch.data();                  // D × C inputs
  float* e = x0 + static_cast<size_t>(D) * C;  // E × C embeddings
  float* a = e + static_cast<size_t>(E) * C;   // attention's first layer
  float* p = a + wc;                           // p, q: ping-pong buffers of the MLP chains
  float* q = p + wc;
  float* score_buf = q + wc;                       // C attention scores
  float* g = score_buf + C;                        // E × S mean embedding
  float* gterm = g + static_cast<size_t>(E) * S;   // W × S global term of the first attention layer
  float* x3 = gterm + static_cast<size_t>(W) * S;  // W × S mlp3 input: robot part, then the weighted h
  float* wts = x3 + static_cast<size_t>(W) * S;    // N × S softmax weights

  // Inputs, feature-major; padded humans and the padding states of the last tile are zeros.
  std::fill(x0, x0 + static_cast<size_t>(D) * C, 0.0f);
  std::fill(x3, x3 + static_cast<size_t>(W) * S, 0.0f);
  for (int s = 0; s < count; ++s) {
    const int64_t m = first + s;
    const uint8_t* mk = mask + m * N;
    int self_row = 0;  // the first real human's row carries the robot part (slot 0 when none is real)
    while (self_row < N && !mk[self_row]) ++self_row;
    if (self_row == N) self_row = 0;
    const float* js = joint + static_cast<size_t>(m) * N * D;
    for (int d = 0; d < self_dim_; ++d) x3[static_cast<size_t>(d) * S + s] = js[static_cast<size_t>(self_row) * D + d];
    for (int i = 0; i < N; ++i) {
      if (!mk[i]) continue;
      for (int d = 0; d < D; ++d) x0[static_cast<size_t>(d) * C + i * S + s] = js[static_cast<size_t>(i) * D + d];
    }
  }

  // e = mlp1(x), ReLU after every layer.
  chain(mlp1_, 0, x0, C, p, q, true, e);

  // Attention scores.
  const DenseLayer& att0 = attention_.front();
  const bool att0_relu = attention_.size() > 1;
  if (with_global_state_) {
    // g = masked mean of e over the real humans of each state; gterm = W_g g + b. The mask as 0/1
    // factors (wts holds them until the softmax) keeps the loops branch-free; e is finite (padded
    // humans' inputs are zeros), so adding 0 · e adds nothing.
    for (int i = 0; i < N; ++i)
      for (int s = 0; s < S; ++s) wts[i * S + s] = (s < count && mask[(first + s) * N + i]) ? 1.0f : 0.0f;
    for (int k = 0; k < E; ++k) {
      float* gk = g + static_cast<size_t>(k) * S;
      const float* ek = e + static_cast<size_t>(k) * C;
      for (int s = 0; s < S; ++s) gk[s] = 0.0f;
      for (int i = 0; i < N; ++i)
        for (int s = 0; s < S; ++s) gk[s] += wts[i * S + s] * ek[i * S + s];
    }
    for (int s = 0; s < S; ++s) {
      float real = 0.0f;
      for (int i = 0; i < N; ++i) real += wts[i * S + s];
      const float div = real > 0.0f ? real : 1.0f;
      for (int k = 0; k < E; ++k) g[static_cast<size_t>(k) * S + s] /= div;
    }
    dense_layer(attention_g_, g, gterm, S, false);
    dense_layer(att0, e, a, C, false);
    for (int r = 0; r < att0.out; ++r) {
      float* ar = a + static_cast<size_t>(r) * C;
      const float* gr = gterm + static_cast<size_t>(r) * S;
      for (int i = 0; i < N; ++i)
        for (int s = 0; s < S; ++s) {
          const float v = ar[i * S + s] + gr[s];
          ar[i * S + s] = (att0_relu && v < 0.0f) ? 0.0f : v;
        }
    }
  } else {
    dense_layer(att0, e, a, C, att0_relu);
  }
  // Into their own buffer (or still in `a` for a one-layer attention MLP): mlp2 reuses p and q.
  const float* scores = chain(attention_, 1, a, C, p, q, false, score_buf);

  // Masked softmax over each state's humans (all-zero weights when none is real).
  for (int s = 0; s < count; ++s) {
    const uint8_t* mk = mask + (first + s) * N;
    float mx = -INFINITY;
    for (int i = 0; i < N; ++i)
      if (mk[i]) mx = std::max(mx, scores[i * S + s]);
    if (!std::isfinite(mx)) mx = 0.0f;
    float den = 0.0f;
    for (int i = 0; i < N; ++i) {
      const float ex = mk[i] ? std::exp(scores[i * S + s] - mx) : 0.0f;
      wts[i * S + s] = ex;
      den += ex;
    }
    for (int i = 0; i < N; ++i) wts[i * S + s] = den > 0.0f ? wts[i * S + s] / den : 0.0f;
  }
  for (int s = count; s < S; ++s)
    for (int i = 0; i < N; ++i) wts[i * S + s] = 0.0f;

  // h = mlp2(e) (no ReLU after the last layer), the weighted sum into mlp3's input after the robot part.
  const float* h = chain(mlp2_, 0, e, C, p, q, false);
  const int H = mlp2_.back().out;
  for (int f = 0; f < H; ++f) {
    float* xf = x3 + static_cast<size_t>(self_dim_ + f) * S;
    const float* hf = h + static_cast<size_t>(f) * C;
    for (int i = 0; i < N; ++i)
      for (int s = 0; s < S; ++s) xf[s] += wts[i * S + s] * hf[i * S + s];
  }
  const float* v = chain(mlp3_, 0, x3, S, p, q, false);
  for (int s = 0; s < count; ++s) out[first + s] = v[s];
}

}  // namespace socialnav
