#include "learner/algorithms/acting.h"

namespace imca::learner {

// MADDPG acts with the actor's own defaults.
AlgorithmActing MaddpgActing() { return {"maddpg"}; }

}  // namespace imca::learner
