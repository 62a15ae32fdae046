#ifndef IMCA_FUZZ_FUZZ_CHECK_H_
#define IMCA_FUZZ_FUZZ_CHECK_H_

#include <cstdio>
#include <cstdlib>

// An invariant of a fuzz target: on violation, say which and abort (the
// fuzzer keeps the input; the replay test fails).
#define FUZZ_CHECK(condition)                                                      \
  do {                                                                             \
    if (!(condition)) {                                                            \
      std::fprintf(stderr, "%s:%d: FUZZ_CHECK failed: %s\n", __FILE__, __LINE__, #condition); \
      std::abort();                                                                \
    }                                                                              \
  } while (0)

#endif  // IMCA_FUZZ_FUZZ_CHECK_H_
