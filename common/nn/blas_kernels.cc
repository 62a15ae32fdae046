#include "common/nn/blas_kernels.h"

#include <dlfcn.h>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

// ATen's version header alone: torch/torch.h costs ~15 s to compile.
#include <ATen/Version.h>

#include "common/base/load_time_env.h"

namespace imca::nn {
namespace {

// OpenBLAS's kernels' name, or null when no OpenBLAS is loaded. LibTorch's
// BLAS is libblas.so.3; when that is OpenBLAS, it is loaded with the binary
// and its symbols are in the global scope.
const char* OpenBlasCore() {
  using CoreName = char* (*)();
  const auto corename = reinterpret_cast<CoreName>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  return corename != nullptr ? corename() : nullptr;
}

}  // namespace

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
  const char* core = OpenBlasCore();
  const std::string type(CoreTypeToForce(std::getenv("OPENBLAS_CORETYPE"), core, ThisCpu()));
  std::vector<std::pair<std::string, std::string>> vars = OurLoadTimeEnv();
  if (!type.empty()) {
    std::fprintf(stderr, "%s: OpenBLAS chose its %s kernels on this CPU; restarting with OPENBLAS_CORETYPE=%s\n",
                 argv[0], core, type.c_str());
    vars.emplace_back("OPENBLAS_CORETYPE", type);
  }
  ReexecWith(argv, vars);
}

const std::string& KernelsInUse() {
  static const std::string* const kernels = [] {
    // at::native::get_cpu_capability is not exported by Debian's LibTorch;
    // show_config prints the same cached level as "CPU capability usage:
    // NO AVX|AVX2|AVX512".
    const std::string config = at::show_config();
    constexpr std::string_view kKey = "CPU capability usage: ";
    std::string aten = "unknown";
    if (const size_t pos = config.find(kKey); pos != std::string::npos) {
      const size_t from = pos + kKey.size();
      const std::string level = config.substr(from, config.find('\n', from) - from);
      aten = level == "NO AVX" ? "default" : level == "AVX2" ? "avx2" : level == "AVX512" ? "avx512" : level;
    }
    const char* core = OpenBlasCore();
    return new std::string("aten=" + aten + " openblas=" + (core != nullptr ? core : "none"));
  }();
  return *kernels;
}

}  // namespace imca::nn
