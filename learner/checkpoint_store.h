#ifndef IMCA_LEARNER_CHECKPOINT_STORE_H_
#define IMCA_LEARNER_CHECKPOINT_STORE_H_

#include <functional>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "imca/v1/learner_service.pb.h"

namespace imca::learner {

// The learner's checkpoints in one folder (<run_dir>/checkpoints): each is
// ckpt-<version>.pt, the algorithm's state, completed by ckpt-<version>.meta,
// a v1::CheckpointMeta in protobuf's text format written after it. Every file
// is written atomically, so a crash leaves complete checkpoints and at most a
// .pt without its .meta, which is not one. The newest `keep` are kept.
//
// Thread-compatible: one writer (the learner's training thread); Restore
// before training starts.
class CheckpointStore {
 public:
  // Writes or reads the algorithm's state at a path.
  using StateIo = std::function<absl::Status(const std::string& path)>;

  explicit CheckpointStore(std::string dir, int keep = 3);

  // Writes checkpoint meta.version(): save(<stem>.pt), then <stem>.meta; then
  // removes all but the newest `keep` complete checkpoints. Errors: save's,
  // or INTERNAL naming the file.
  absl::Status Save(const v1::CheckpointMeta& meta, const StateIo& save) const;

  // Loads the newest complete checkpoint: its .meta, then load(<stem>.pt).
  // If that fails (a damaged file: the disk, not a crash mid-write), the next
  // older one, and so on, saying on stderr which was restored instead; a
  // damaged newest costs one checkpoint interval, not the run. Returns the
  // loaded one's metadata. Errors: NOT_FOUND if the folder holds none (or
  // does not exist); INTERNAL if it cannot be read; if none loads, the
  // newest's error (INVALID_ARGUMENT for metadata that does not parse, or
  // load's: INVALID_ARGUMENT if the state does not fit the algorithm).
  absl::StatusOr<v1::CheckpointMeta> Restore(const StateIo& load) const;

  // The .meta path of the newest complete checkpoint. Errors as Restore's
  // NOT_FOUND and INTERNAL.
  absl::StatusOr<std::string> Newest() const;

  const std::string& dir() const { return dir_; }

 private:
  const std::string dir_;
  const int keep_;
};

// The checkpoint folder a starting learner resumes from, from its flags
// --resume (a folder) and --auto_resume (<run_dir>/checkpoints if it holds a
// checkpoint), or "" to start fresh. Errors: INVALID_ARGUMENT naming the
// flag (both given; --auto_resume without a run folder), INTERNAL if the run
// folder's checkpoints cannot be read (starting fresh would lose the run).
absl::StatusOr<std::string> ResumeFolder(const std::string& resume, bool auto_resume, const std::string& run_dir);

}  // namespace imca::learner

#endif  // IMCA_LEARNER_CHECKPOINT_STORE_H_
