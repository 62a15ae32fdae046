#include "common/metrics/metrics_server.h"

#include <httplib.h>

#include <sys/socket.h>

#include <chrono>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace imca::metrics {

struct MetricsServer::Impl {
  httplib::Server http;
  std::vector<const Registry*> registries;
};

absl::StatusOr<std::unique_ptr<MetricsServer>> MetricsServer::Start(const std::string& listen,
                                                                    std::vector<const Registry*> registries) {
  std::string host = "127.0.0.1", port_text = listen;
  if (const size_t colon = listen.rfind(':'); colon != std::string::npos) {
    host = listen.substr(0, colon);
    port_text = listen.substr(colon + 1);
    if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  }
  int port = 0;
  if (host.empty() || !absl::SimpleAtoi(port_text, &port) || port < 0 || port > 65535) {
    return absl::InvalidArgumentError(
        absl::StrCat("--metrics_listen: '", listen, "' is not PORT or HOST:PORT with a port in [0, 65535]"));
  }
  if (const std::string shared = SharedFamily(registries); !shared.empty()) {
    return absl::InternalError(absl::StrCat("metrics family ", shared, " is exported by two components"));
  }
  std::unique_ptr<MetricsServer> server(new MetricsServer());
  server->impl_ = std::make_unique<Impl>();
  server->impl_->registries = std::move(registries);
  httplib::Server& http = server->impl_->http;
  // Two threads are plenty for a scraper or two (the default is 8 or more).
  http.new_task_queue = [] { return new httplib::ThreadPool(2); };
  http.set_read_timeout(5);
  http.set_write_timeout(5);
  http.set_payload_max_length(64 << 10);
  // An idle keep-alive connection holds a worker (and stop() waits for it):
  // 1 s is plenty between a scraper's requests of one scrape.
  http.set_keep_alive_max_count(100);
  http.set_keep_alive_timeout(1);
  // SO_REUSEADDR only: httplib's default adds SO_REUSEPORT, with which a
  // second process could bind the same port and take half the scrapes.
  http.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  const std::vector<const Registry*>* served = &server->impl_->registries;
  http.Get("/metrics", [served](const httplib::Request&, httplib::Response& response) {
    response.set_content(Text(*served), kTextContentType);
  });
  http.Get("/", [](const httplib::Request&, httplib::Response& response) {
    response.set_content("<a href=\"/metrics\">/metrics</a>\n", "text/html");
  });
  if (port == 0) {
    port = http.bind_to_any_port(host);
    if (port < 0) port = -1;
  } else if (!http.bind_to_port(host, port)) {
    port = -1;
  }
  if (port < 0) {
    return absl::UnavailableError(absl::StrCat("--metrics_listen: cannot listen on ", host, ":", port_text,
                                               " (in use, or not an address of this machine)"));
  }
  server->host_ = host;
  server->port_ = port;
  server->thread_ = std::thread([&http] { http.listen_after_bind(); });
  // 0.11 has no wait_until_ready(): the socket is bound, so a scrape that
  // comes early waits in the backlog; this only bounds how long stop waits.
  for (int i = 0; i < 200 && !http.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  return server;
}

MetricsServer::~MetricsServer() {
  if (impl_ == nullptr) return;
  // stop() before the loop runs would be lost: wait for it to run first.
  for (int i = 0; i < 400 && !impl_->http.is_running() && thread_.joinable(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  impl_->http.stop();
  if (thread_.joinable()) thread_.join();
}

}  // namespace imca::metrics
