#ifndef IMCA_COMMON_BASE_STATUS_MACROS_H_
#define IMCA_COMMON_BASE_STATUS_MACROS_H_

#include "absl/status/status.h"
#include "absl/status/statusor.h"

// Abseil 20220623 has no RETURN_IF_ERROR; these are the project's own.
#define IMCA_RETURN_IF_ERROR(expr)                   \
  do {                                               \
    const ::absl::Status imca_status_ = (expr);      \
    if (!imca_status_.ok()) return imca_status_;     \
  } while (0)

#define IMCA_CONCAT_INNER_(a, b) a##b
#define IMCA_CONCAT_(a, b) IMCA_CONCAT_INNER_(a, b)
#define IMCA_ASSIGN_OR_RETURN(lhs, expr) \
  IMCA_ASSIGN_OR_RETURN_IMPL_(IMCA_CONCAT_(imca_statusor_, __LINE__), lhs, expr)
#define IMCA_ASSIGN_OR_RETURN_IMPL_(tmp, lhs, expr) \
  auto tmp = (expr);                                \
  if (!tmp.ok()) return tmp.status();               \
  lhs = std::move(tmp).value()

#endif  // IMCA_COMMON_BASE_STATUS_MACROS_H_
