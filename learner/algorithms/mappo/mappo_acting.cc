#include "learner/algorithms/acting.h"

namespace imca::learner {

// MAPPO acts with the actor's own defaults.
AlgorithmActing MappoActing() { return {"mappo"}; }

}  // namespace imca::learner
