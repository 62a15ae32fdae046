#ifndef IMCA_REWARD_SERVER_TORCH_MLP_H_
#define IMCA_REWARD_SERVER_TORCH_MLP_H_

// LibTorch-only: include from .cc files that compile torch anyway, never from
// a header that gRPC or test code includes.
#include <torch/torch.h>

#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace imca::reward {

// Linear layers of the given sizes (in, hidden..., out) with ReLU between
// them; orthogonal weights (gain sqrt 2), zero biases.
class MlpImpl : public torch::nn::Module {
 public:
  explicit MlpImpl(const std::vector<int64_t>& sizes) {
    for (size_t i = 0; i + 1 < sizes.size(); ++i) {
      torch::nn::Linear layer(sizes[i], sizes[i + 1]);
      torch::nn::init::orthogonal_(layer->weight, std::sqrt(2.0));
      torch::nn::init::zeros_(layer->bias);
      layers_.push_back(register_module(std::to_string(i), layer));
    }
  }

  torch::Tensor forward(torch::Tensor x) {
    for (size_t i = 0; i < layers_.size(); ++i) {
      x = layers_[i]->forward(x);
      if (i + 1 < layers_.size()) x = torch::relu(x);
    }
    return x;
  }

  std::vector<torch::nn::Linear>& layers() { return layers_; }

 private:
  std::vector<torch::nn::Linear> layers_;
};
TORCH_MODULE(Mlp);

// Running mean and variance (parallel Welford merge, float64), per column.
struct RunningMoments {
  torch::Tensor mean, var;
  double count = 1e-4;

  explicit RunningMoments(int64_t dim = 1)
      : mean(torch::zeros({dim}, torch::kFloat64)), var(torch::ones({dim}, torch::kFloat64)) {}

  // Merges the rows of `x` ([rows][dim]).
  void Update(const torch::Tensor& x) {
    const torch::Tensor xd = x.to(torch::kFloat64);
    const double rows = static_cast<double>(xd.size(0));
    if (rows == 0) return;
    const torch::Tensor batch_mean = xd.mean(0);
    const torch::Tensor batch_var = xd.var(0, /*unbiased=*/false);
    const torch::Tensor delta = batch_mean - mean;
    const double total = count + rows;
    mean = mean + delta * (rows / total);
    var = (var * count + batch_var * rows + delta * delta * (count * rows / total)) / total;
    count = total;
  }
};

// Writes "tag" and then whatever `fill` adds to `path` atomically (tmp file +
// rename). Errors: INTERNAL naming the path.
absl::Status SaveArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::OutputArchive&)>& fill);
// Reads `path`, checks its "tag", then calls `read` (which may throw and
// should swap state in only at its end). Errors: NOT_FOUND (unreadable),
// FAILED_PRECONDITION (other tag), DATA_LOSS (missing or bad entries).
absl::Status LoadArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::InputArchive&)>& read);
// The learned scorers' snapshot: an optional joint and an optional local
// model (each with Write/Read(archive, prefix)) and one counter, under `tag`.
// Load reads into fresh models from `make_joint` / `make_local` and swaps them
// in only when everything was read. Errors: as SaveArchive / LoadArchive.
template <typename Model>
absl::Status SaveModels(const std::string& path, const std::string& tag, const std::optional<Model>& joint,
                        const std::optional<Model>& local, const std::string& counter_name, int64_t counter) {
  return SaveArchive(path, tag, [&](torch::serialize::OutputArchive& archive) {
    if (joint) joint->Write(archive, "joint.");
    if (local) local->Write(archive, "local.");
    archive.write(counter_name, torch::tensor(counter, torch::kInt64));
  });
}
template <typename Model>
absl::Status LoadModels(const std::string& path, const std::string& tag, std::optional<Model>* joint,
                        std::optional<Model>* local, const std::function<Model()>& make_joint,
                        const std::function<Model()>& make_local, const std::string& counter_name,
                        int64_t* counter) {
  return LoadArchive(path, tag, [&](torch::serialize::InputArchive& archive) {
    std::optional<Model> fresh_joint, fresh_local;
    if (*joint) {
      fresh_joint.emplace(make_joint());
      fresh_joint->Read(archive, "joint.");
    }
    if (*local) {
      fresh_local.emplace(make_local());
      fresh_local->Read(archive, "local.");
    }
    torch::Tensor count;
    archive.read(counter_name, count);
    joint->swap(fresh_joint);
    local->swap(fresh_local);
    *counter = count.item<int64_t>();
  });
}

// Sets layer `layer` of `mlp` to weight [out][in] and bias [out].
// Errors: INVALID_ARGUMENT on a bad layer or shape.
absl::Status SetLinear(Mlp& mlp, int layer, const std::vector<float>& weight, const std::vector<float>& bias);

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_TORCH_MLP_H_
