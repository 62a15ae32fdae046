#ifndef IMCA_COMMON_BASE_LAP_H_
#define IMCA_COMMON_BASE_LAP_H_

#include <chrono>

namespace imca {

using Clock = std::chrono::steady_clock;

// Seconds since `start`, and restarts it there: consecutive laps time the
// phases of one piece of work (a learner iteration, a Score call, an actor's
// loop). Pure apart from reading the clock; thread-safe.
inline double Lap(Clock::time_point& start) {
  const Clock::time_point now = Clock::now();
  const double seconds = std::chrono::duration<double>(now - start).count();
  start = now;
  return seconds;
}

}  // namespace imca

#endif  // IMCA_COMMON_BASE_LAP_H_
