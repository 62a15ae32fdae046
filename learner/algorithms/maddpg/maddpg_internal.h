#ifndef IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_INTERNAL_H_
#define IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_INTERNAL_H_

// LibTorch-only pieces of MADDPG, exposed for its unit test.
#include <torch/torch.h>

namespace imca::learner::internal {

// The straight-through hard Gumbel-softmax sample of `logits` [..., A]:
// forward value onehot(argmax(logits + g)), gradient that of
// softmax((logits + g) / temperature), with g = -log(-log(uniform)) and
// `uniform` in (0, 1), of logits' shape.
inline torch::Tensor GumbelSoftmaxHard(const torch::Tensor& logits, const torch::Tensor& uniform,
                                       double temperature = 1.0) {
  const torch::Tensor gumbel = -torch::log(-torch::log(uniform));
  const torch::Tensor soft = torch::softmax((logits + gumbel) / temperature, -1);
  const torch::Tensor hard =
      torch::zeros_like(soft).scatter_(-1, soft.argmax(-1, /*keepdim=*/true), 1.0);
  return hard - soft.detach() + soft;
}

// onehot(argmax(logits)) along the last dimension, no gradient.
inline torch::Tensor OneHotArgmax(const torch::Tensor& logits) {
  return torch::zeros_like(logits).scatter_(-1, logits.argmax(-1, /*keepdim=*/true), 1.0).detach();
}

}  // namespace imca::learner::internal

#endif  // IMCA_LEARNER_ALGORITHMS_MADDPG_MADDPG_INTERNAL_H_
