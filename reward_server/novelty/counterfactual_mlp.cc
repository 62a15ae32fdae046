#include "reward_server/novelty/counterfactual_mlp.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <functional>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace imca::reward {
namespace {

using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ConstMatrixMap = Eigen::Map<const Matrix>;
using ConstRowMap = Eigen::Map<const Eigen::RowVectorXf>;

// Rows per block: two nets' activations of a block (2 x 2 x 256 x 128
// floats) stay in a core's L2.
constexpr int64_t kBlockRows = 256;

// `tail` over the rows of *x (pre-activations of its first hidden layer);
// *y is scratch. Returns the buffer holding the embedding.
Matrix* Forward(const MlpTail& tail, Matrix* x, Matrix* y) {
  for (const MlpTail::Layer& layer : tail.layers) {
    x->array() = x->array().max(0.0f);
    y->resize(x->rows(), layer.out);
    y->noalias() = *x * ConstMatrixMap(layer.weight, layer.out, layer.in).transpose();
    y->rowwise() += ConstRowMap(layer.bias, layer.out);
    std::swap(x, y);
  }
  return x;
}

// CounterfactualNovelties over blocks of `per_block` transitions each (the
// last may be short), taken one at a time from *next until `blocks`, with
// its own buffers.
void NoveltiesOfBlocks(const MlpTail& target, const MlpTail& predictor, int64_t N, int64_t per_block,
                       std::atomic<int64_t>* next, int64_t blocks, int n, int A, int H, const float* h_target,
                       const float* h_predictor, const float* c_target, const float* c_predictor,
                       const int64_t* taken, float* out) {
  const int64_t per = int64_t{n} * (A - 1);  // Counterfactual rows of one transition.
  Matrix zt(per_block * per, H), zp(per_block * per, H), yt, yp;
  Eigen::VectorXf novelty(per_block * per);
  std::vector<int64_t> index(per_block * per);  // Row -> its place in out.
  for (int64_t b = next->fetch_add(1); b < blocks; b = next->fetch_add(1)) {
    const int64_t first = b * per_block, last = std::min(N, first + per_block);
    const int64_t rows = (last - first) * per;
    zt.resize(rows, H);  // Forward reshapes the buffers it passes through.
    zp.resize(rows, H);
    int64_t r = 0;
    for (int64_t i = first; i < last; ++i) {
      const ConstRowMap ht(h_target + i * H, H), hp(h_predictor + i * H, H);
      for (int s = 0; s < n; ++s) {
        const int64_t t = taken[i * n + s];
        const ConstRowMap ct_taken(c_target + (s * A + t) * H, H), cp_taken(c_predictor + (s * A + t) * H, H);
        for (int u = 0; u < A; ++u) {
          if (u == t) continue;
          zt.row(r) = (ht + ConstRowMap(c_target + (s * A + u) * H, H)) - ct_taken;
          zp.row(r) = (hp + ConstRowMap(c_predictor + (s * A + u) * H, H)) - cp_taken;
          index[r++] = (i * n + s) * A + u;
        }
      }
    }
    const Matrix* et = Forward(target, &zt, &yt);
    const Matrix* ep = Forward(predictor, &zp, &yp);
    novelty.head(rows) = (*et - *ep).array().square().rowwise().sum() / static_cast<float>(et->cols());
    for (int64_t k = 0; k < rows; ++k) out[index[k]] = novelty[k];
  }
}

}  // namespace

void CounterfactualNovelties(const MlpTail& target, const MlpTail& predictor, int64_t N, int n, int A, int H,
                             const float* h_target, const float* h_predictor, const float* c_target,
                             const float* c_predictor, const int64_t* taken, const float* taken_novelty,
                             float* out, int threads, const std::function<void()>& alongside) {
  for (int64_t i = 0; i < N; ++i) {
    for (int s = 0; s < n; ++s) out[(i * n + s) * A + taken[i * n + s]] = taken_novelty[i];
  }
  const bool rows = A >= 2 && n >= 1 && N > 0;
  // One grid of blocks from transition 0 whatever the threads, so that every
  // block holds the same rows (a GEMM's rounding may depend on a row's place
  // in its block); the threads take whole blocks as they come free.
  const int64_t per_block = std::max<int64_t>(1, kBlockRows / (int64_t{n} * std::max(A - 1, 1)));
  const int64_t blocks = rows ? (N + per_block - 1) / per_block : 0;
  std::atomic<int64_t> next{0};
  const int helpers = static_cast<int>(std::clamp<int64_t>(threads - 1, 0, blocks));
  std::vector<std::exception_ptr> errors(helpers + 2);  // helpers, the caller's blocks, alongside.
  auto work = [&](int p) {
    try {
      NoveltiesOfBlocks(target, predictor, N, per_block, &next, blocks, n, A, H, h_target, h_predictor, c_target,
                        c_predictor, taken, out);
    } catch (...) {
      errors[p] = std::current_exception();
      next = blocks;  // The others stop at their next block.
    }
  };
  std::vector<std::thread> workers;
  try {
    for (int p = 0; p < helpers; ++p) workers.emplace_back(work, p);
  } catch (const std::system_error&) {
    // No more threads to be had: the caller takes the rest.
  }
  if (alongside) {
    try {
      alongside();
    } catch (...) {
      errors[helpers + 1] = std::current_exception();
      next = blocks;
    }
  }
  work(helpers);
  for (std::thread& worker : workers) worker.join();
  // The alongside's error first: it is the caller's own work.
  if (errors[helpers + 1]) std::rethrow_exception(errors[helpers + 1]);
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
}

}  // namespace imca::reward
