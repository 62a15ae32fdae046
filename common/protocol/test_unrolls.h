#ifndef IMCA_COMMON_PROTOCOL_TEST_UNROLLS_H_
#define IMCA_COMMON_PROTOCOL_TEST_UNROLLS_H_

#include <cstdint>

#include "common/env/env.h"
#include "imca/v1/unroll.pb.h"

namespace imca::testing {

// A valid Unroll of T steps of E envs of `scenario` under a uniform random
// policy (rewards, flags, log-probs and episode ids filled; intrinsic rewards
// set to zero). For tests and benchmarks.
v1::Unroll RandomUnroll(const env::Scenario& scenario, int length, int num_envs, uint64_t seed);

}  // namespace imca::testing

#endif  // IMCA_COMMON_PROTOCOL_TEST_UNROLLS_H_
