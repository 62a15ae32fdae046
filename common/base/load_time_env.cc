#include "common/base/load_time_env.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace imca {

void ReexecWith(char** argv, const std::vector<std::pair<std::string, std::string>>& vars) {
  std::vector<std::string> set;
  for (const auto& [name, value] : vars) {
    if (std::getenv(name.c_str()) != nullptr) continue;
    if (setenv(name.c_str(), value.c_str(), 1) != 0) break;
    set.push_back(name);
  }
  if (set.empty()) return;
  execv("/proc/self/exe", argv);
  std::fprintf(stderr, "%s: restarting with %s set failed (%s); going on without\n", argv[0], set.front().c_str(),
               std::strerror(errno));
  for (const std::string& name : set) unsetenv(name.c_str());
}

std::vector<std::pair<std::string, std::string>> OurLoadTimeEnv() {
  return {{"OMP_WAIT_POLICY", IMCA_OMP_WAIT_POLICY}};
}

void UseOurLoadTimeEnv(char** argv) { ReexecWith(argv, OurLoadTimeEnv()); }

}  // namespace imca
