#ifndef IMCA_COMMON_BASE_LOAD_TIME_ENV_H_
#define IMCA_COMMON_BASE_LOAD_TIME_ENV_H_

#include <string>
#include <utility>
#include <vector>

namespace imca {

// Environment variables that libraries read once, as they load (libgomp's
// OMP_WAIT_POLICY, OpenBLAS's OPENBLAS_CORETYPE): setting one in main() is
// too late, so the process re-executes itself with it.

// The load-time environment of every process of ours, as (name, value):
// OMP_WAIT_POLICY (after parallel work libgomp's threads otherwise spin,
// taking the cores gRPC's and the other processes' threads need). Chosen in
// the top CMakeLists.txt (IMCA_LOAD_TIME_ENV), which also gives it to the
// tests and writes it to bin/load_time_env for the tools: a process started
// with it set does not re-execute.
std::vector<std::pair<std::string, std::string>> OurLoadTimeEnv();

// Sets each (name, value) of `vars` whose name is unset and re-executes the
// binary (/proc/self/exe: same pid, arguments and the environment plus
// those) if any was; returns if none was unset, or if the re-execution
// failed (one line on stderr naming argv[0]; the variables set are unset
// again, so the process goes on as it was). After the re-execution they are
// set, so this returns. Not thread-safe: call first in main().
void ReexecWith(char** argv, const std::vector<std::pair<std::string, std::string>>& vars);

// ReexecWith(argv, OurLoadTimeEnv()): what main() of every binary
// and test that may run OpenMP code calls first (LibTorch binaries call
// nn::UseTheCpusBlasKernels, which adds OpenBLAS's variable).
void UseOurLoadTimeEnv(char** argv);

}  // namespace imca

#endif  // IMCA_COMMON_BASE_LOAD_TIME_ENV_H_
