#ifndef IMCA_COMMON_NN_BLAS_KERNELS_H_
#define IMCA_COMMON_NN_BLAS_KERNELS_H_
// Torch-free: any translation unit may include this.

#include <string>
#include <string_view>

namespace imca::nn {

// What the CPU running the process can execute, of what OpenBLAS's kernels use.
struct CpuFeatures {
  bool avx2_fma = false;
  bool avx512 = false;  // F, BW, VL and DQ: OpenBLAS's SkylakeX kernels.
};
CpuFeatures ThisCpu();

// The OPENBLAS_CORETYPE to force when OpenBLAS chose the kernels of `core`
// (openblas_get_corename, any case) on a CPU with `cpu`: "SkylakeX" or
// "Haswell" when those are newer than `core`'s, else empty (keep them).
// OpenBLAS 0.3.21 (Debian 12's) picks kernels by CPU model and falls back to
// Prescott's SSE3 ones on models it does not know, as on VMs that report a
// generic "Intel Xeon Processor": its GEMMs then run 2-4x slower, and so do
// LibTorch's small MLPs (docs/benchmarks.md, "OpenBLAS's kernels").
std::string_view BetterCoreType(std::string_view core, const CpuFeatures& cpu);

// UseTheCpusBlasKernels's decision: the OPENBLAS_CORETYPE to restart with,
// or empty to go on. `set` is the variable's value (null: unset), `core`
// what OpenBLAS chose (null: no OpenBLAS loaded). Pure.
std::string_view CoreTypeToForce(const char* set, const char* core, const CpuFeatures& cpu);

// Call first in main() of a LibTorch binary, with main's argv: our
// load-time environment (common/base/load_time_env.h: OMP_WAIT_POLICY), and if the
// process's OpenBLAS chose older kernels than this CPU runs
// (BetterCoreType) and OPENBLAS_CORETYPE is not set, that too, said in one
// line on stderr; OpenBLAS reads it only as it loads. Re-executes the binary
// (same pid, arguments and environment) once if a variable was set; returns
// otherwise, or if the re-execution failed (one line on stderr; the process
// goes on as it was). Not thread-safe: call before any thread of the
// program's own starts.
void UseTheCpusBlasKernels(char** argv);

// The CPU kernels this process's numerics run, as
// "aten=<default|avx2|avx512> openblas=<core>" ("openblas=none" without an
// OpenBLAS): ATen's dispatch level (Debian's LibTorch 1.13: avx2 on a CPU
// with AVX2 and FMA, else default; ATEN_CPU_CAPABILITY overrides it) and
// OpenBLAS's kernels (by CPU model, or OPENBLAS_CORETYPE). A deterministic
// run replays bit for bit where these are the same (docs/learner.md,
// "Deterministic runs"). Fixed for the process's life; thread-safe.
const std::string& KernelsInUse();

}  // namespace imca::nn

#endif  // IMCA_COMMON_NN_BLAS_KERNELS_H_
