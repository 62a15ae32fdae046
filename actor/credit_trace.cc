#include "actor/credit_trace.h"

#include <cstdio>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/atomic_file.h"
#include "common/env/env.h"

namespace imca::actor {

CreditTrace::CreditTrace(std::string path, std::chrono::seconds period, std::string log_name)
    : path_(std::move(path)), period_(period), log_name_(std::move(log_name)) {}

void CreditTrace::Add(const v1::Unroll& u) {
  const int E = u.num_envs(), n = u.num_agents(), k = u.state_size();
  if (u.intrinsic_rewards_size() != int64_t{u.length()} * E * n) {
    gap_ = true;  // A malformed response: the learner rejects the unroll too.
    return;
  }
  const bool diagnostics = u.contributions_size() == u.intrinsic_rewards_size() &&
                           u.global_rewards_size() * n == u.intrinsic_rewards_size() &&
                           u.credit_shares_size() == u.intrinsic_rewards_size();
  for (int t = 0; t < u.length(); ++t) {
    const int64_t i = int64_t{t} * E;  // Env 0 of step t.
    const int32_t* state = u.states().data() + i * k;
    const int32_t* next = u.next_states().data() + i * k;
    const int step = state[k - 1];  // The state's last entry is the episode's step count.
    if (step == 0) {
      current_.clear();
      gap_ = false;
    }
    for (int a = 0; a < n; ++a) {
      const int64_t j = i * n + a;
      absl::StrAppendFormat(&current_, "%d,%d,%d,%d,%d,%d,%.6g,%.6g,%.6g,%.6g\n", u.episode_ids(i), step, a,
                            state[env::AgentIndex(a)], next[env::AgentIndex(a)], u.actions(j),
                            diagnostics ? u.credit_shares(j) : 0.0f, diagnostics ? u.contributions(j) : 0.0f,
                            u.intrinsic_rewards(j), diagnostics ? u.global_rewards(i) : 0.0f);
    }
    if (u.terminated(i) || u.truncated(i)) {
      if (!gap_) last_.swap(current_);
      current_.clear();
      gap_ = false;
    }
  }
  if (!last_.empty() && std::chrono::steady_clock::now() - written_ >= period_) Flush();
}

void CreditTrace::Flush() {
  written_ = std::chrono::steady_clock::now();
  if (last_.empty()) return;
  const absl::Status written = WriteFileAtomically(path_, absl::StrCat(kCreditTraceHeader, "\n", last_));
  if (!written.ok()) {
    std::fprintf(stderr, "%s: trace: %s\n", log_name_.c_str(), std::string(written.message()).c_str());
  }
}

}  // namespace imca::actor
