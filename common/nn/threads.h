#ifndef IMCA_COMMON_NN_THREADS_H_
#define IMCA_COMMON_NN_THREADS_H_
// Torch-free: any translation unit may include this.

namespace imca::nn {

// Sets LibTorch's intra-op thread count (at least 1) for the process, once:
// the first call takes effect and a later call asking for another count is
// ignored, with one line on stderr. The factories of every LibTorch user
// (Learner::Create, MakeScorer for learned novelties) call it with their
// configuration's count, so one process holds one thread budget whatever it
// builds. (OpenMP counts per thread: a thread a component starts for its own
// work sets its count itself, as PpoTrainer's side thread does.)
void SetTorchThreads(int threads);

}  // namespace imca::nn

#endif  // IMCA_COMMON_NN_THREADS_H_
