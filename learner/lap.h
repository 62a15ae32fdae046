#ifndef IMCA_LEARNER_LAP_H_
#define IMCA_LEARNER_LAP_H_

#include <chrono>

namespace imca::learner {

using Clock = std::chrono::steady_clock;

// Seconds since `start`, and restarts it there: consecutive laps time the
// phases of one iteration. Pure apart from reading the clock; thread-safe.
inline double Lap(Clock::time_point& start) {
  const Clock::time_point now = Clock::now();
  const double seconds = std::chrono::duration<double>(now - start).count();
  start = now;
  return seconds;
}

}  // namespace imca::learner

#endif  // IMCA_LEARNER_LAP_H_
