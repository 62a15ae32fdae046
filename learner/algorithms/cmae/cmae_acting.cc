#include "common/protocol/policy_table.h"
#include "learner/algorithms/acting.h"

namespace imca::learner {

// CMAE's loop: one environment, one unroll per episode (its step limit).
AlgorithmActing CmaeActing() { return {"cmae", 1, kCmaeEpisodeSteps}; }

}  // namespace imca::learner
