#ifndef IMCA_REWARD_SERVER_NOVELTY_COUNTERFACTUAL_MLP_H_
#define IMCA_REWARD_SERVER_NOVELTY_COUNTERFACTUAL_MLP_H_

#include <cstdint>
#include <functional>
#include <vector>

namespace imca::reward {

// A ReLU MLP past its first Linear, as views of row-major float arrays
// (LibTorch's parameters, or a test's): each layer is relu, then
// y = x W^T + b; the last layer's output is the embedding.
struct MlpTail {
  struct Layer {
    const float* weight;  // [out][in]
    const float* bias;    // [out]
    int out;
    int in;
  };
  std::vector<Layer> layers;  // Empty: the first layer's pre-activation is the embedding.
};

// The imca counterfactual novelties of RND (docs/credit.md), past the first
// layer. A counterfactual row (i, s, u) is transition i with the action in
// joint-input slot s set to u; its first-layer pre-activation in each net is
//   z = (h[i] + c[s][u]) - c[s][taken[i][s]],
// with h [N][H] the taken row's pre-activation and c [n][A][H] the first
// layer's response to slot s taking action u. Writes
//   out[i][s][u] = mean_k (target(z)_k - predictor(z)_k)^2
// for every u != taken[i][s], and out[i][s][taken[i][s]] = taken_novelty[i]
// (that row is the taken one). `out` is [N][n][A]; every taken[i][s] is in
// [0, A), and both tails have the same widths, the first `in` being H.
//
// Computed in blocks of rows that stay in cache, with Eigen's kernels: at
// these sizes (tens of thousands of rows, widths of 64-128) LibTorch's passes
// over the whole [N][n][A][H] tensor and its BLAS cost several times the
// arithmetic (docs/benchmarks.md, "Credit's cost end to end"). With
// `threads` > 1 the blocks are shared out between that many threads (the
// caller's and threads - 1 started for the call); the blocks, and so the
// values, are the same for any `threads`.
//
// `alongside`, if set, runs once on the caller's thread while the helpers
// take their first blocks; the caller then joins them on the blocks left.
// It is other work of the caller's that needs none of the outputs (the
// predictor's training step): it must not write any input of this call, so
// tails it would change must be copies. An exception of `alongside` is
// rethrown first, else one of any thread, after all have finished; `out` is
// then unspecified. Blocks the calling thread. Thread-compatible: concurrent
// calls on distinct outputs are safe.
void CounterfactualNovelties(const MlpTail& target, const MlpTail& predictor, int64_t N, int n, int A, int H,
                             const float* h_target, const float* h_predictor, const float* c_target,
                             const float* c_predictor, const int64_t* taken, const float* taken_novelty,
                             float* out, int threads = 1, const std::function<void()>& alongside = {});

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_NOVELTY_COUNTERFACTUAL_MLP_H_
