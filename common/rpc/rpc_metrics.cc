#include "common/rpc/rpc_metrics.h"

#include <chrono>

#include <google/protobuf/descriptor.h>

#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"

namespace imca {
namespace {

using Clock = std::chrono::steady_clock;

// Unary calls take milliseconds; long polls and streams last up to minutes.
const std::vector<double> kSecondsBuckets = metrics::ExponentialBuckets(0.0005, 4, 10);  // 0.5 ms .. 131 s.

const metrics::Family kServerStarted{"imca_rpc_server_started_total", metrics::Type::kCounter,
                                     "gRPC calls started on the server."};
const metrics::Family kServerHandled{"imca_rpc_server_handled_total", metrics::Type::kCounter,
                                     "gRPC calls completed by the server, by status code."};
const metrics::Family kServerSeconds{"imca_rpc_server_handling_seconds", metrics::Type::kHistogram,
                                     "Seconds from a call's start to its status (a stream's lifetime).",
                                     kSecondsBuckets};
const metrics::Family kClientStarted{"imca_rpc_client_started_total", metrics::Type::kCounter,
                                     "gRPC calls started by the client."};
const metrics::Family kClientHandled{"imca_rpc_client_handled_total", metrics::Type::kCounter,
                                     "gRPC calls completed at the client, by status code."};
const metrics::Family kClientSeconds{"imca_rpc_client_handling_seconds", metrics::Type::kHistogram,
                                     "Seconds from a call's start to its status at the client (a stream's lifetime).",
                                     kSecondsBuckets};

// "UNAVAILABLE" for grpc::StatusCode::UNAVAILABLE (absl's and gRPC's codes agree).
std::string CodeName(grpc::StatusCode code) {
  return absl::AsciiStrToUpper(absl::StatusCodeToString(static_cast<absl::StatusCode>(code)));
}

// Counts a call when created and when its status passes `kHook` (the
// server sending it, the client receiving it).
template <grpc::experimental::InterceptionHookPoints kHook>
class CallInterceptor : public grpc::experimental::Interceptor {
 public:
  CallInterceptor(RpcMetrics* metrics, int method) : metrics_(metrics), method_(method) { metrics_->Started(method_); }
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(kHook)) {
      grpc::StatusCode code;
      if constexpr (kHook == grpc::experimental::InterceptionHookPoints::PRE_SEND_STATUS) {
        code = methods->GetSendStatus().error_code();
      } else {
        const grpc::Status* status = methods->GetRecvStatus();
        code = status != nullptr ? status->error_code() : grpc::StatusCode::UNKNOWN;
      }
      metrics_->Handled(method_, code, std::chrono::duration<double>(Clock::now() - start_).count());
    }
    methods->Proceed();
  }

 private:
  RpcMetrics* const metrics_;
  const int method_;
  const Clock::time_point start_ = Clock::now();
};

class ServerFactory : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  explicit ServerFactory(RpcMetrics* metrics) : metrics_(metrics) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(grpc::experimental::ServerRpcInfo* info) override {
    return new CallInterceptor<grpc::experimental::InterceptionHookPoints::PRE_SEND_STATUS>(
        metrics_, metrics_->MethodIndex(info->method()));
  }

 private:
  RpcMetrics* const metrics_;
};

class ClientFactory : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit ClientFactory(RpcMetrics* metrics) : metrics_(metrics) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(grpc::experimental::ClientRpcInfo* info) override {
    return new CallInterceptor<grpc::experimental::InterceptionHookPoints::POST_RECV_STATUS>(
        metrics_, metrics_->MethodIndex(info->method()));
  }

 private:
  RpcMetrics* const metrics_;
};

}  // namespace

RpcMetrics::RpcMetrics(Side side, const std::vector<std::string>& services, metrics::Registry* registry)
    : side_(side), registry_(registry) {
  std::vector<std::pair<std::string, std::string>> names = {{"grpc.health.v1.Health", "Check"},
                                                            {"grpc.health.v1.Health", "Watch"}};
  for (const std::string& service : services) {
    const google::protobuf::ServiceDescriptor* descriptor =
        google::protobuf::DescriptorPool::generated_pool()->FindServiceByName(service);
    if (descriptor == nullptr) continue;
    for (int i = 0; i < descriptor->method_count(); ++i) names.emplace_back(service, descriptor->method(i)->name());
  }
  names.emplace_back("other", "other");
  const bool server = side_ == Side::kServer;
  for (const auto& [service, name] : names) {
    auto method = std::make_unique<Method>();
    method->service = service;
    method->name = name;
    const metrics::Labels labels = {{"service", service}, {"method", name}};
    method->started = &registry_->AddCounter(server ? kServerStarted : kClientStarted, labels);
    method->seconds = &registry_->AddHistogram(server ? kServerSeconds : kClientSeconds, labels);
    index_[absl::StrCat("/", service, "/", name)] = static_cast<int>(methods_.size());
    methods_.push_back(std::move(method));
  }
}

int RpcMetrics::MethodIndex(const char* full_method) const {
  if (full_method != nullptr) {
    if (auto it = index_.find(full_method); it != index_.end()) return it->second;
  }
  return static_cast<int>(methods_.size()) - 1;
}

void RpcMetrics::Started(int method) { methods_[method]->started->Increment(); }

void RpcMetrics::Handled(int method, grpc::StatusCode code, double seconds) {
  Method& m = *methods_[method];
  m.seconds->Observe(seconds);
  const int c = static_cast<int>(code);
  if (c < 0 || c >= static_cast<int>(m.handled.size())) return;  // Not a gRPC code: timed, not labelled.
  metrics::Counter* counter = m.handled[c].load(std::memory_order_acquire);
  if (counter == nullptr) {
    // Get-or-create in the registry: racing threads get the same counter.
    counter = &registry_->AddCounter(side_ == Side::kServer ? kServerHandled : kClientHandled,
                                     {{"service", m.service}, {"method", m.name}, {"code", CodeName(code)}});
    m.handled[c].store(counter, std::memory_order_release);
  }
  counter->Increment();
}

std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface> RpcMetrics::ServerInterceptorFactory() {
  return std::make_unique<ServerFactory>(this);
}

std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface> RpcMetrics::ClientInterceptorFactory() {
  return std::make_unique<ClientFactory>(this);
}

}  // namespace imca
