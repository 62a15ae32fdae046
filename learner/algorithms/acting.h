#ifndef IMCA_LEARNER_ALGORITHMS_ACTING_H_
#define IMCA_LEARNER_ALGORITHMS_ACTING_H_

#include <optional>
#include <string>
#include <vector>

namespace imca::learner {

// What an actor needs to know of an algorithm before any policy arrives:
// torch-free, so the actor links it (the learner's registry, registry.h,
// has the rest). Each folder defines its own (mappo/mappo_acting.cc, ...),
// algorithms.def lists them.
struct AlgorithmActing {
  std::string name;  // --algo.
  // The collection the algorithm's loop needs where it differs from the
  // actor's defaults (the scenario's tuning).
  std::optional<int> num_envs;
  std::optional<int> unroll_length;
};

// Every algorithm's, in algorithms.def's order (the first the default).
const std::vector<AlgorithmActing>& AlgorithmsActing();

// Each folder's (algorithms.def).
#define IMCA_ALGORITHM(name, Prefix) AlgorithmActing Prefix##Acting();
#include "learner/algorithms/algorithms.def"
#undef IMCA_ALGORITHM

}  // namespace imca::learner

#endif  // IMCA_LEARNER_ALGORITHMS_ACTING_H_
