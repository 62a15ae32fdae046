// The flags every service binary has (common/rpc/service_flags.h).
#include "common/rpc/service_flags.h"

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/atomic_file.h"
#include "google/protobuf/descriptor.h"
#include "google/protobuf/util/json_util.h"

ABSL_FLAG(bool, list, false,
          "print this binary's choices, defaults and limits (scenarios, kinds, columns, caps, exit codes) as JSON "
          "and exit: what the Python tools ask instead of copying them");
ABSL_FLAG(bool, print_config, false,
          "resolve the configuration (defaults, the scenario's or kind's tuning, the flags given), validate it as "
          "a start would, print it as JSON (flag name: value) and exit: 0, or 2 with the error");
ABSL_FLAG(std::string, status_file, "",
          "if set, write a one-line JSON status record here every second (for a supervisor; docs/reliability.md)");
ABSL_FLAG(int, signal_exit_code, 0,
          "exit code when SIGINT/SIGTERM stops the process before its work is done (Kubernetes Jobs: 143, so "
          "that an evicted learner or actor is replaced rather than counted as finished)");

namespace imca {

absl::StatusOr<ServiceFlags> ServiceFlagsFromFlags() {
  ServiceFlags flags;
  flags.list = absl::GetFlag(FLAGS_list);
  flags.print_config = absl::GetFlag(FLAGS_print_config);
  flags.status_file = absl::GetFlag(FLAGS_status_file);
  flags.signal_exit_code = absl::GetFlag(FLAGS_signal_exit_code);
  if (flags.signal_exit_code < 0 || flags.signal_exit_code > 255) {
    return absl::InvalidArgumentError("--signal_exit_code must be in [0, 255]");
  }
  return flags;
}

absl::Status WriteStatusFile(const std::string& path, const google::protobuf::Message& status) {
  if (path.empty()) return absl::OkStatus();
  google::protobuf::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  options.always_print_primitive_fields = true;
  std::string json;
  if (const auto printed = google::protobuf::util::MessageToJsonString(status, &json, options); !printed.ok()) {
    return absl::InternalError(absl::StrFormat("status record: %s", printed.ToString()));
  }
  // Singular 64-bit integers unquoted: the printer writes them as
  // "name":"<value>", unique in the object (field names are).
  const google::protobuf::Descriptor* descriptor = status.GetDescriptor();
  const google::protobuf::Reflection* reflection = status.GetReflection();
  for (int i = 0; i < descriptor->field_count(); ++i) {
    const google::protobuf::FieldDescriptor* field = descriptor->field(i);
    if (field->is_repeated()) continue;
    std::string value;
    switch (field->cpp_type()) {
      case google::protobuf::FieldDescriptor::CPPTYPE_INT64:
        value = absl::StrCat(reflection->GetInt64(status, field));
        break;
      case google::protobuf::FieldDescriptor::CPPTYPE_UINT64:
        value = absl::StrCat(reflection->GetUInt64(status, field));
        break;
      default:
        continue;
    }
    const std::string quoted = absl::StrCat("\"", field->name(), "\":\"", value, "\"");
    if (const size_t at = json.find(quoted); at != std::string::npos) {
      json.replace(at, quoted.size(), absl::StrCat("\"", field->name(), "\":", value));
    }
  }
  // The message's object with "time" appended: {...} -> {...,"time":t}.
  if (json.size() < 2 || json.back() != '}') return absl::InternalError("status record: not a JSON object");
  json.pop_back();
  absl::StrAppendFormat(&json, "%s\"time\":%.3f}\n", json.size() > 1 ? "," : "", UnixSeconds());
  return WriteFileAtomically(path, json);
}

}  // namespace imca
