#include "nn/archive.h"

#include <sstream>
#include <utility>

#include "absl/strings/str_cat.h"
#include "base/atomic_file.h"

namespace imca::nn {

absl::Status SaveArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::OutputArchive&)>& fill) {
  absl::StatusOr<std::string> bytes = SerializeArchive(tag, fill);
  if (!bytes.ok()) return absl::InternalError(absl::StrCat("writing snapshot '", path, "': ", bytes.status().message()));
  return WriteFileAtomically(path, *bytes);
}

absl::StatusOr<std::string> SerializeArchive(const std::string& tag,
                                             const std::function<void(torch::serialize::OutputArchive&)>& fill) {
  std::ostringstream out;
  try {
    torch::serialize::OutputArchive archive;
    archive.write("tag", c10::IValue(tag));
    fill(archive);
    archive.save_to(out);
  } catch (const std::exception& e) {
    return absl::InternalError(absl::StrCat("serialising snapshot '", tag, "': ", e.what()));
  }
  return std::move(out).str();
}

absl::Status LoadArchive(const std::string& path, const std::string& tag,
                         const std::function<void(torch::serialize::InputArchive&)>& read) {
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const std::exception&) {
    return absl::NotFoundError(absl::StrCat("no readable snapshot at '", path, "'"));
  }
  try {
    c10::IValue stored;
    archive.read("tag", stored);
    if (!stored.isString() || stored.toStringRef() != tag) {
      return absl::FailedPreconditionError(absl::StrCat("snapshot '", path, "' was written by '",
                                                        stored.isString() ? stored.toStringRef() : "?",
                                                        "', not by this configuration"));
    }
    read(archive);
  } catch (const std::exception& e) {
    return absl::DataLossError(absl::StrCat("snapshot '", path, "': ", e.what()));
  }
  return absl::OkStatus();
}

}  // namespace imca::nn
