#include "nn/blas_kernels.h"

#include <dlfcn.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace imca::nn {

CpuFeatures ThisCpu() {
  __builtin_cpu_init();
  CpuFeatures cpu;
  cpu.avx2_fma = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  cpu.avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
               __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq");
  return cpu;
}

std::string_view BetterCoreType(std::string_view core, const CpuFeatures& cpu) {
  std::string name(core);
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  // Kernels at least as new as SkylakeX's, or Haswell's (AVX2 + FMA).
  const bool has_avx512_kernels = name == "skylakex" || name == "cooperlake" || name == "sapphirerapids";
  const bool has_avx2_kernels = has_avx512_kernels || name == "haswell" || name == "zen";
  if (cpu.avx512 && cpu.avx2_fma && !has_avx512_kernels) return "SkylakeX";
  if (cpu.avx2_fma && !has_avx2_kernels) return "Haswell";
  return {};
}

std::string_view CoreTypeToForce(const char* set, const char* core, const CpuFeatures& cpu) {
  if (set != nullptr || core == nullptr) return {};
  return BetterCoreType(core, cpu);
}

void UseTheCpusBlasKernels(char** argv) {
  const char* set = std::getenv("OPENBLAS_CORETYPE");
  // LibTorch's BLAS is libblas.so.3; when that is OpenBLAS, it is loaded
  // with the binary and its symbols are in the global scope.
  using CoreName = char* (*)();
  const auto corename = reinterpret_cast<CoreName>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  const char* core = corename != nullptr ? corename() : nullptr;
  const std::string type(CoreTypeToForce(set, core, ThisCpu()));
  if (type.empty()) return;
  std::fprintf(stderr, "%s: OpenBLAS chose its %s kernels on this CPU; restarting with OPENBLAS_CORETYPE=%s\n",
               argv[0], core, type.c_str());
  if (setenv("OPENBLAS_CORETYPE", type.c_str(), 1) != 0) return;
  execv("/proc/self/exe", argv);
  std::fprintf(stderr, "%s: restarting failed (%s); going on with OpenBLAS's %s kernels\n", argv[0],
               std::strerror(errno), core);
  unsetenv("OPENBLAS_CORETYPE");
}

}  // namespace imca::nn
