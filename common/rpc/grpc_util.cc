#include "common/rpc/grpc_util.h"

#include <unistd.h>

#include <atomic>
#include <csignal>
#include <thread>

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/health_check_service_interface.h>

#include "absl/strings/str_cat.h"
#include "common/base/rng.h"
#include "common/rpc/rpc_metrics.h"

namespace imca {
namespace {

std::atomic<bool> g_shutdown{false};

void OnSignal(int) { g_shutdown.store(true); }

}  // namespace

grpc::Status ToGrpcStatus(const absl::Status& status) {
  if (status.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(status.code()), std::string(status.message()));
}

absl::Status FromGrpcStatus(const grpc::Status& status) {
  if (status.ok()) return absl::OkStatus();
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

void InstallShutdownSignalHandlers() {
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

bool ShutdownRequested() { return g_shutdown.load(); }
void RequestShutdown() { g_shutdown.store(true); }

absl::StatusOr<std::unique_ptr<grpc::Server>> StartServer(const std::string& listen,
                                                          const std::vector<grpc::Service*>& services,
                                                          int* bound_port, const ServerOptions& options) {
  if (absl::Status valid = ValidateServerTransport(options.transport); !valid.ok()) return valid;
  if (options.max_receive_bytes < 1) return absl::InvalidArgumentError("--max_receive_mb must be >= 1");
  absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> credentials = MakeServerCredentials(options.transport);
  if (!credentials.ok()) return credentials.status();
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(listen, *credentials, bound_port);
  builder.SetMaxReceiveMessageSize(options.max_receive_bytes);
  builder.SetMaxSendMessageSize(kMaxMessageBytes);
  // Without this gRPC may reuse a port another process holds (SO_REUSEPORT).
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  // One connection cannot hold more calls than this at once (an actor holds
  // one stream and one unary call).
  builder.AddChannelArgument(GRPC_ARG_MAX_CONCURRENT_STREAMS, kMaxStreamsPerConnection);
  // Keepalive, set together with MakeChannel's: the server pings too (a
  // vanished client frees its stream within kKeepaliveTime +
  // kKeepaliveTimeout), and accepts the clients' pings at their interval,
  // also between calls (otherwise it answers them with GOAWAY
  // too_many_pings).
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, kKeepaliveTimeMs);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, kKeepaliveTimeoutMs);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, kKeepaliveTimeMs / 2);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  for (grpc::Service* service : services) builder.RegisterService(service);
  if (options.rpc_metrics != nullptr) {
    std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> interceptors;
    interceptors.push_back(options.rpc_metrics->ServerInterceptorFactory());
    builder.experimental().SetInterceptorCreators(std::move(interceptors));
  }
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (server == nullptr || *bound_port == 0) {
    return absl::UnavailableError(
        absl::StrCat("--listen: cannot listen on ", listen, " (address in use or invalid)"));
  }
  server->GetHealthCheckService()->SetServingStatus(true);
  return server;
}

namespace {

grpc::ChannelArguments ChannelArgs() {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(kMaxMessageBytes);
  args.SetMaxSendMessageSize(kMaxMessageBytes);
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
  // gRPC's client keepalive is off by default: a peer that vanished without
  // closing its connection (a killed host, a dropped network) would hold a
  // stream until its deadline. With pings every kKeepaliveTimeMs, such a
  // connection fails within kKeepaliveTimeMs + kKeepaliveTimeoutMs.
  args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, kKeepaliveTimeMs);
  args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, kKeepaliveTimeoutMs);
  args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  return args;
}

}  // namespace

std::shared_ptr<grpc::Channel> MakeChannel(const std::string& target) {
  return grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), ChannelArgs());
}

absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const std::string& target,
                                                           const TransportConfig& transport,
                                                           RpcMetrics* rpc_metrics) {
  if (absl::Status valid = ValidateClientTransport(transport); !valid.ok()) return valid;
  absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> credentials = MakeChannelCredentials(transport);
  if (!credentials.ok()) return credentials.status();
  grpc::ChannelArguments args = ChannelArgs();
  if (!transport.tls_server_name.empty()) args.SetSslTargetNameOverride(transport.tls_server_name);
  if (rpc_metrics == nullptr) return grpc::CreateCustomChannel(target, *credentials, args);
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> interceptors;
  interceptors.push_back(rpc_metrics->ClientInterceptorFactory());
  return grpc::experimental::CreateCustomChannelWithInterceptors(target, *credentials, args, std::move(interceptors));
}

grpc::Status GenericUnaryCall(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                              const std::string& request_bytes, std::chrono::milliseconds timeout,
                              std::string* response_bytes) {
  grpc::GenericStub stub(channel);
  grpc::CompletionQueue queue;
  grpc::ClientContext context;
  context.set_deadline(DeadlineIn(timeout));
  grpc::Slice slice(request_bytes);
  grpc::ByteBuffer request(&slice, 1), response;
  auto call = stub.PrepareUnaryCall(&context, method, request, &queue);
  call->StartCall();
  grpc::Status status;
  call->Finish(&response, &status, nullptr);
  void* tag;
  bool ok;
  queue.Next(&tag, &ok);
  response_bytes->clear();
  std::vector<grpc::Slice> slices;
  if (status.ok() && response.Dump(&slices).ok()) {
    for (const grpc::Slice& s : slices) response_bytes->append(reinterpret_cast<const char*>(s.begin()), s.size());
  }
  return status;
}

absl::StatusOr<bool> CheckHealth(const std::shared_ptr<grpc::Channel>& channel, std::chrono::milliseconds timeout) {
  // Debian ships no generated health stubs: a generic call with an empty
  // HealthCheckRequest; the answer's field 1 is the status, 1 = SERVING.
  std::string bytes;
  const grpc::Status status = GenericUnaryCall(channel, "/grpc.health.v1.Health/Check", "", timeout, &bytes);
  if (!status.ok()) return FromGrpcStatus(status);
  return bytes == std::string("\x08\x01", 2);
}

Backoff::Backoff()
    : state_(static_cast<uint64_t>(getpid()) * 0x9e3779b97f4a7c15ULL ^ reinterpret_cast<uintptr_t>(this) ^
             static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count())) {}

void Backoff::Wait() { Wait(ShutdownRequested); }

void Backoff::Wait(const std::function<bool()>& stopped) {
  const int64_t cap_ms = std::min<int64_t>(5000, int64_t{50} << std::min(attempt_, 10));
  ++attempt_;
  uint64_t s = state_;
  const int64_t delay_ms = static_cast<int64_t>(Rng::SplitMix64(s) % static_cast<uint64_t>(cap_ms + 1));
  state_ = s;
  for (int64_t waited = 0; waited < delay_ms && !stopped(); waited += 50) {
    std::this_thread::sleep_for(std::chrono::milliseconds(std::min<int64_t>(50, delay_ms - waited)));
  }
}

}  // namespace imca
