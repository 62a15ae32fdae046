#include "common/nn/threads.h"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <mutex>

// ATen's parallel header alone: torch/torch.h costs ~15 s to compile.
#include <ATen/Parallel.h>

namespace imca::nn {

void SetTorchThreads(int threads) {
  static std::once_flag once;
  static std::atomic<int> set{0};
  static std::atomic<bool> warned{false};
  threads = std::max(1, threads);
  std::call_once(once, [threads] {
    at::set_num_threads(threads);
    set = threads;
  });
  if (set != threads && !warned.exchange(true)) {
    std::fprintf(stderr, "LibTorch threads stay %d for this process (%d asked later is ignored)\n", set.load(),
                 threads);
  }
}

}  // namespace imca::nn
