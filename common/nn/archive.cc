#include "common/nn/archive.h"

#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/atomic_file.h"

namespace imca::nn {

namespace {

constexpr char kAdamFormat[] = "imca_adam_v1";

std::string ParamKey(size_t group, size_t param, const char* field) {
  return absl::StrCat(group, ".", param, ".", field);
}

// Where LibTorch's Adam keeps a parameter's state (adam.cpp's lookup).
std::string StateKey(const torch::Tensor& param) { return c10::guts::to_string(param.unsafeGetTensorImpl()); }

// The parameters in each of `adam`'s groups.
std::vector<int64_t> GroupSizes(const torch::optim::Adam& adam) {
  std::vector<int64_t> sizes;
  for (const auto& group : adam.param_groups()) sizes.push_back(static_cast<int64_t>(group.params().size()));
  return sizes;
}

}  // namespace

void WriteAdam(torch::serialize::OutputArchive& archive, const std::string& key, const torch::optim::Adam& adam) {
  torch::serialize::OutputArchive sub(archive.compilation_unit());
  sub.write(kAdamFormat, torch::tensor(int64_t{1}));
  sub.write("group_sizes", torch::tensor(GroupSizes(adam), torch::kInt64));  // What ReadAdam checks.
  const auto& groups = adam.param_groups();
  for (size_t g = 0; g < groups.size(); ++g) {
    const auto& params = groups[g].params();
    for (size_t i = 0; i < params.size(); ++i) {
      const auto found = adam.state().find(StateKey(params[i]));
      if (found == adam.state().end()) continue;  // No step taken with it yet.
      const auto& state = static_cast<const torch::optim::AdamParamState&>(*found->second);
      sub.write(ParamKey(g, i, "step"), torch::tensor(state.step()));
      sub.write(ParamKey(g, i, "exp_avg"), state.exp_avg());
      sub.write(ParamKey(g, i, "exp_avg_sq"), state.exp_avg_sq());
      if (state.max_exp_avg_sq().defined()) sub.write(ParamKey(g, i, "max_exp_avg_sq"), state.max_exp_avg_sq());
    }
  }
  archive.write(key, sub);
}

void ReadAdam(torch::serialize::InputArchive& archive, const std::string& key, torch::optim::Adam& adam) {
  torch::serialize::InputArchive sub;
  archive.read(key, sub);
  torch::Tensor format;
  if (!sub.try_read(kAdamFormat, format)) {
    adam.load(sub);  // Written by Optimizer::save (before this format).
    return;
  }
  torch::Tensor sizes;
  sub.read("group_sizes", sizes);
  sizes = sizes.to(torch::kInt64).contiguous();
  if (std::vector<int64_t>(sizes.data_ptr<int64_t>(), sizes.data_ptr<int64_t>() + sizes.numel()) != GroupSizes(adam)) {
    throw std::runtime_error(absl::StrCat(key, ": the file's optimiser has other parameter groups than this one"));
  }
  adam.state().clear();  // The file's state replaces all of it.
  const auto& groups = adam.param_groups();
  for (size_t g = 0; g < groups.size(); ++g) {
    const auto& params = groups[g].params();
    for (size_t i = 0; i < params.size(); ++i) {
      torch::Tensor step, exp_avg, exp_avg_sq, max_exp_avg_sq;
      if (!sub.try_read(ParamKey(g, i, "step"), step)) continue;
      sub.read(ParamKey(g, i, "exp_avg"), exp_avg);
      sub.read(ParamKey(g, i, "exp_avg_sq"), exp_avg_sq);
      if (!exp_avg.sizes().equals(params[i].sizes()) || !exp_avg_sq.sizes().equals(params[i].sizes())) {
        throw std::runtime_error(absl::StrCat(key, ": the moments of parameter ", g, ".", i,
                                              " do not have its shape"));
      }
      auto state = std::make_unique<torch::optim::AdamParamState>();
      state->step(step.item<int64_t>());
      state->exp_avg(exp_avg);
      state->exp_avg_sq(exp_avg_sq);
      if (sub.try_read(ParamKey(g, i, "max_exp_avg_sq"), max_exp_avg_sq)) {
        if (!max_exp_avg_sq.sizes().equals(params[i].sizes())) {
          throw std::runtime_error(absl::StrCat(key, ": max_exp_avg_sq of parameter ", g, ".", i,
                                                " does not have its shape"));
        }
        state->max_exp_avg_sq(max_exp_avg_sq);
      }
      adam.state()[StateKey(params[i])] = std::move(state);
    }
  }
}

absl::Status SaveArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::OutputArchive&)>& fill) {
  absl::StatusOr<std::string> bytes = SerializeArchive(tag, fill);
  if (!bytes.ok()) return absl::InternalError(absl::StrCat("writing snapshot '", path, "': ", bytes.status().message()));
  return WriteFileAtomically(path, *bytes);
}

absl::StatusOr<std::string> SerializeArchive(const std::string& tag,
                                             const std::function<void(torch::serialize::OutputArchive&)>& fill) {
  std::ostringstream out;
  try {
    torch::serialize::OutputArchive archive;
    archive.write("tag", c10::IValue(tag));
    fill(archive);
    archive.save_to(out);
  } catch (const std::exception& e) {
    return absl::InternalError(absl::StrCat("serialising snapshot '", tag, "': ", e.what()));
  }
  return std::move(out).str();
}

absl::Status LoadArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::InputArchive&)>& read) {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const std::exception&) {
    return absl::NotFoundError(absl::StrCat("no readable snapshot at '", path, "'"));
  }
  try {
    c10::IValue stored;
    archive.read("tag", stored);
    if (!stored.isString() || stored.toStringRef() != tag) {
      return absl::FailedPreconditionError(absl::StrCat("snapshot '", path, "' was written by '",
                                                        stored.isString() ? stored.toStringRef() : "?",
                                                        "', not by this configuration"));
    }
    read(archive);
  } catch (const std::exception& e) {
    return absl::DataLossError(absl::StrCat("snapshot '", path, "': ", e.what()));
  }
  return absl::OkStatus();
}

}  // namespace imca::nn
