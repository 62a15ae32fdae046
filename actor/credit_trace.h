#ifndef IMCA_ACTOR_CREDIT_TRACE_H_
#define IMCA_ACTOR_CREDIT_TRACE_H_

#include <chrono>
#include <string>

#include "imca/v1/unroll.pb.h"

namespace imca::actor {

// The credit of one episode, for a reader (tools' report, docs/credit.md):
// env 0's newest finished training episode, one CSV row per step and agent,
// written atomically to a file at most every `period` and on Flush().
// Columns: kCreditTraceHeader. Not thread-safe.
inline constexpr char kCreditTraceHeader[] =
    "episode,t,agent,cell,next_cell,action,share,contribution,agent_reward,global_reward";

class CreditTrace {
 public:
  // `log_name` prefixes the failures logged (the actor id).
  CreditTrace(std::string path, std::chrono::seconds period, std::string log_name);

  // Appends env 0's scored steps of `unroll`; an episode with a step missing
  // (an unroll lost, or a response without rewards) is not written.
  void Add(const v1::Unroll& unroll);
  // Writes the newest finished episode, if any.
  void Flush();

 private:
  const std::string path_;
  const std::chrono::seconds period_;
  const std::string log_name_;
  std::string current_;  // Rows of env 0's current episode.
  std::string last_;     // Rows of the last finished one.
  bool gap_ = false;     // The current one lost a step.
  std::chrono::steady_clock::time_point written_{};
};

}  // namespace imca::actor

#endif  // IMCA_ACTOR_CREDIT_TRACE_H_
