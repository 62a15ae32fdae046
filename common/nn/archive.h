#ifndef IMCA_COMMON_NN_ARCHIVE_H_
#define IMCA_COMMON_NN_ARCHIVE_H_

// LibTorch-only, see common/nn/mlp.h.
#include <torch/torch.h>

#include <functional>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace imca::nn {

// Writes "tag" and then whatever `fill` adds to `path` atomically (tmp file +
// rename). Errors: INTERNAL naming the path.
absl::Status SaveArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::OutputArchive&)>& fill);
// The same file's bytes, in memory. Errors: INTERNAL.
absl::StatusOr<std::string> SerializeArchive(const std::string& tag,
                                             const std::function<void(torch::serialize::OutputArchive&)>& fill);

// Reads `path`, checks its "tag", then calls `read` (which may throw and
// should swap state in only at its end). Errors: NOT_FOUND (unreadable),
// FAILED_PRECONDITION (other tag), DATA_LOSS (missing or bad entries).
absl::Status LoadArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::InputArchive&)>& read);
// An Adam optimiser's state (each parameter's step and moments) written
// under `key` by the parameter's position. LibTorch's Optimizer::save keys
// it by tensor addresses, so that equal states wrote different bytes in
// every process; this is what makes checkpoints and snapshots of equal runs
// equal. The hyperparameters are not written: they come from the
// configuration.
void WriteAdam(torch::serialize::OutputArchive& archive, const std::string& key, const torch::optim::Adam& adam);
// Replaces `adam`'s state with WriteAdam's entry (`adam` built over
// parameters of the same shapes), or an older file's Optimizer::save under
// `key`. Throws (as archive reads do) on a missing or mismatched entry.
void ReadAdam(torch::serialize::InputArchive& archive, const std::string& key, torch::optim::Adam& adam);

// The learned novelties' snapshot: an optional joint and an optional local
// model (each with Write/Read(archive, prefix)) and one counter, under `tag`,
// as bytes (SerializeArchive). Load reads into fresh models from
// `make_joint` / `make_local` and swaps them in only when everything was
// read. Errors: as SerializeArchive / LoadArchive.
template <typename Model>
absl::StatusOr<std::string> SerializeModels(const std::string& tag, const std::optional<Model>& joint,
                                            const std::optional<Model>& local, const std::string& counter_name,
                                            int64_t counter) {
  return SerializeArchive(tag, [&](torch::serialize::OutputArchive& archive) {
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

}  // namespace imca::nn

#endif  // IMCA_COMMON_NN_ARCHIVE_H_
