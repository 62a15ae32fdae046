#include "learner/algorithms/acting.h"

namespace imca::learner {

const std::vector<AlgorithmActing>& AlgorithmsActing() {
  static const std::vector<AlgorithmActing>* const kActing = new std::vector<AlgorithmActing>{
#define IMCA_ALGORITHM(name, Prefix) Prefix##Acting(),
#include "learner/algorithms/algorithms.def"
#undef IMCA_ALGORITHM
  };
  return *kActing;
}

}  // namespace imca::learner
