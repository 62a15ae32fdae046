#ifndef IMCA_COMMON_NN_TORCH_STATUS_H_
#define IMCA_COMMON_NN_TORCH_STATUS_H_

// LibTorch-only, see common/nn/mlp.h.
#include <c10/util/Exception.h>

#include <exception>
#include "absl/strings/string_view.h"
#include <type_traits>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"

namespace imca::nn {

// The exception boundary: runs `f` and turns anything LibTorch (or the
// standard library) throws into "<what>: <message>" with `code` (INTERNAL
// unless the caller knows better: a file that parsed but does not fit is
// INVALID_ARGUMENT). `f` returns void, absl::Status or absl::StatusOr<T>;
// so does TorchCall.
template <typename F>
auto TorchCall(absl::string_view what, F&& f, absl::StatusCode code = absl::StatusCode::kInternal)
    -> std::conditional_t<std::is_void_v<std::invoke_result_t<F>>, absl::Status, std::invoke_result_t<F>> {
  try {
    if constexpr (std::is_void_v<std::invoke_result_t<F>>) {
      f();
      return absl::OkStatus();
    } else {
      return f();
    }
  } catch (const c10::Error& e) {
    return absl::Status(code, absl::StrCat(what, ": ", e.what_without_backtrace()));
  } catch (const std::exception& e) {
    return absl::Status(code, absl::StrCat(what, ": ", e.what()));
  }
}

}  // namespace imca::nn

#endif  // IMCA_COMMON_NN_TORCH_STATUS_H_
