#include "learner/checkpoint_store.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <system_error>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/atomic_file.h"
#include "common/base/status_macros.h"
#include "google/protobuf/io/tokenizer.h"
#include "google/protobuf/text_format.h"

namespace imca::learner {
namespace {

namespace fs = std::filesystem;

// The complete checkpoints of `dir` (those with a .meta), newest first.
// Errors: INTERNAL if it cannot be read.
absl::StatusOr<std::vector<fs::path>> CompleteCheckpoints(const std::string& dir) {
  std::vector<fs::path> metas;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(dir, error)) {
    if (entry.path().extension() == ".meta") metas.push_back(entry.path());
  }
  if (error && error != std::errc::no_such_file_or_directory) {
    // Unreadable is not "no checkpoint": starting fresh would lose the run.
    return absl::InternalError(absl::StrCat("cannot read ", dir, ": ", error.message()));
  }
  std::sort(metas.rbegin(), metas.rend());
  return metas;
}

// The metadata written before CheckpointMeta (lines "key value", "accepted
// <incarnation> <sequence> <actor id>"), so that runs of earlier versions
// still resume.
bool ParseLegacyMeta(const std::string& text, v1::CheckpointMeta* meta) {
  std::istringstream lines(text);
  bool version = false, env_steps = false;
  for (std::string line; std::getline(lines, line);) {
    std::istringstream fields(line);
    std::string key;
    fields >> key;
    if (key == "version") {
      int64_t v = 0;
      version = static_cast<bool>(fields >> v);
      meta->set_version(v);
    } else if (key == "env_steps") {
      int64_t v = 0;
      env_steps = static_cast<bool>(fields >> v);
      meta->set_env_steps(v);
    } else if (key == "wall_seconds") {
      double v = 0;
      if (fields >> v) meta->set_wall_seconds(v);
    } else if (key == "iteration") {
      int64_t v = 0;
      if (fields >> v) meta->set_iteration(v);
    } else if (key == "accepted") {
      uint64_t incarnation = 0;
      int64_t sequence = 0;
      std::string actor;
      if (fields >> incarnation >> sequence && fields.get() == ' ' && std::getline(fields, actor)) {
        v1::CheckpointMeta::Trained* trained = meta->add_trained();
        trained->set_actor_id(actor);
        trained->set_incarnation(incarnation);
        trained->set_sequence(sequence);
      }
    } else if (!key.empty()) {
      return false;
    }
  }
  return version && env_steps;
}

// Parse errors are reported by the caller, naming the file.
class QuietErrors : public google::protobuf::io::ErrorCollector {
 public:
  void AddError(int, google::protobuf::io::ColumnNumber, const std::string&) override {}
};

// The metadata of one checkpoint. Errors: INVALID_ARGUMENT naming the file.
absl::StatusOr<v1::CheckpointMeta> ReadMeta(const std::string& path) {
  IMCA_ASSIGN_OR_RETURN(const std::string text, ReadFile(path, "checkpoint metadata"));
  v1::CheckpointMeta meta;
  google::protobuf::TextFormat::Parser parser;
  QuietErrors errors;
  parser.RecordErrorsTo(&errors);
  if (!parser.ParseFromString(text, &meta)) {
    meta.Clear();
    if (!ParseLegacyMeta(text, &meta)) {
      return absl::InvalidArgumentError(absl::StrCat("bad checkpoint metadata ", path));
    }
  }
  if (meta.version() < 0 || meta.env_steps() < 0 || meta.iteration() < 0) {
    return absl::InvalidArgumentError(absl::StrCat("bad checkpoint metadata ", path, ": negative counts"));
  }
  return meta;
}

}  // namespace

CheckpointStore::CheckpointStore(std::string dir, int keep) : dir_(std::move(dir)), keep_(std::max(1, keep)) {}

absl::Status CheckpointStore::Save(const v1::CheckpointMeta& meta, const StateIo& save) const {
  const std::string stem = (fs::path(dir_) / absl::StrFormat("ckpt-%08d", meta.version())).string();
  // The .pt first, then its .meta: the .meta is the marker that the
  // checkpoint is complete.
  IMCA_RETURN_IF_ERROR(save(stem + ".pt"));
  std::string text;
  if (!google::protobuf::TextFormat::PrintToString(meta, &text)) {
    return absl::InternalError(absl::StrCat("cannot print the metadata of ", stem));
  }
  IMCA_RETURN_IF_ERROR(WriteFileAtomically(stem + ".meta", text));
  IMCA_ASSIGN_OR_RETURN(const std::vector<fs::path> metas, CompleteCheckpoints(dir_));
  std::error_code error;
  for (size_t i = keep_; i < metas.size(); ++i) {
    fs::path pt = metas[i];
    pt.replace_extension(".pt");
    fs::remove(metas[i], error);
    fs::remove(pt, error);
  }
  return absl::OkStatus();
}

absl::StatusOr<std::string> CheckpointStore::Newest() const {
  IMCA_ASSIGN_OR_RETURN(const std::vector<fs::path> metas, CompleteCheckpoints(dir_));
  if (metas.empty()) return absl::NotFoundError(absl::StrCat("no checkpoint in ", dir_));
  return metas.front().string();
}

absl::StatusOr<v1::CheckpointMeta> CheckpointStore::Restore(const StateIo& load) const {
  IMCA_ASSIGN_OR_RETURN(const std::vector<fs::path> metas, CompleteCheckpoints(dir_));
  if (metas.empty()) return absl::NotFoundError(absl::StrCat("no checkpoint in ", dir_));
  absl::Status newest_error;
  for (const fs::path& meta_path : metas) {
    absl::StatusOr<v1::CheckpointMeta> meta = ReadMeta(meta_path.string());
    absl::Status loaded = meta.status();
    if (loaded.ok()) {
      fs::path pt = meta_path;
      pt.replace_extension(".pt");
      loaded = load(pt.string());
    }
    if (loaded.ok()) {
      if (!newest_error.ok()) {
        std::fprintf(stderr, "learner: restored the older checkpoint %s instead (%s)\n", meta_path.c_str(),
                     std::string(newest_error.message()).c_str());
      }
      return meta;
    }
    if (newest_error.ok()) newest_error = loaded;
  }
  return newest_error;
}

absl::StatusOr<std::string> ResumeFolder(const std::string& resume, bool auto_resume, const std::string& run_dir) {
  if (!auto_resume) return resume;
  if (!resume.empty()) return absl::InvalidArgumentError("--auto_resume and --resume exclude each other");
  if (run_dir.empty()) return absl::InvalidArgumentError("--auto_resume needs --run_dir");
  const CheckpointStore store((fs::path(run_dir) / "checkpoints").string());
  const absl::StatusOr<std::string> newest = store.Newest();
  if (newest.ok()) return store.dir();
  if (absl::IsNotFound(newest.status())) return std::string();
  return absl::InternalError(absl::StrCat("--auto_resume: ", newest.status().message()));
}

}  // namespace imca::learner
