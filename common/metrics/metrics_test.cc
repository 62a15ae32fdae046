#include "common/metrics/metrics.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/metrics/metrics_server.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"

namespace imca::metrics {
namespace {

using ::testing::HasSubstr;

const Family kRequests{"test_requests_total", Type::kCounter, "Requests served."};
const Family kDepth{"test_queue_depth", Type::kGauge, "Items queued."};
const Family kLatency{"test_latency_seconds", Type::kHistogram, "Latency.", {0.1, 1, 10}};

TEST(RegistryTest, RendersTheTextFormatExactly) {
  Registry r;
  r.AddCounter(kRequests, {{"code", "OK"}}).Increment(3);
  r.AddCounter(kRequests, {{"code", "UNAVAILABLE"}}).Increment();
  r.AddGauge(kDepth).Set(2.5);
  Histogram& h = r.AddHistogram(kLatency);
  for (double v : {0.05, 0.1, 0.5, 20.0}) h.Observe(v);
  EXPECT_EQ(r.Text(),
            "# HELP test_requests_total Requests served.\n"
            "# TYPE test_requests_total counter\n"
            "test_requests_total{code=\"OK\"} 3\n"
            "test_requests_total{code=\"UNAVAILABLE\"} 1\n"
            "# HELP test_queue_depth Items queued.\n"
            "# TYPE test_queue_depth gauge\n"
            "test_queue_depth 2.5\n"
            "# HELP test_latency_seconds Latency.\n"
            "# TYPE test_latency_seconds histogram\n"
            "test_latency_seconds_bucket{le=\"0.1\"} 2\n"
            "test_latency_seconds_bucket{le=\"1\"} 3\n"
            "test_latency_seconds_bucket{le=\"10\"} 3\n"
            "test_latency_seconds_bucket{le=\"+Inf\"} 4\n"
            "test_latency_seconds_sum 20.65\n"
            "test_latency_seconds_count 4\n");
}

TEST(RegistryTest, AddingAnExistingSeriesReturnsIt) {
  Registry r;
  Counter& a = r.AddCounter(kRequests, {{"code", "OK"}});
  Counter& b = r.AddCounter(kRequests, {{"code", "OK"}});
  EXPECT_EQ(&a, &b);
  EXPECT_EQ(r.FamilyNames(), std::vector<std::string>{"test_requests_total"});
}

TEST(RegistryTest, CountersNeverGoDown) {
  Counter c;
  c.Increment(2);
  c.Increment(-1);
  c.Increment(std::nan(""));
  c.Increment(INFINITY);
  EXPECT_EQ(c.value(), 2);
}

TEST(RegistryTest, EscapesHelpAndLabelValues) {
  Registry r;
  r.AddGauge({"test_escaped", Type::kGauge, "back\\slash\nnewline"}, {{"path", "a\"b\\c\nd"}}).Set(1);
  EXPECT_EQ(r.Text(),
            "# HELP test_escaped back\\\\slash\\nnewline\n# TYPE test_escaped gauge\n"
            "test_escaped{path=\"a\\\"b\\\\c\\nd\"} 1\n");
}

TEST(RegistryTest, CallbacksAreReadAtEachScrapeAndSpecialValuesAreSpelled) {
  Registry r;
  double value = 1;
  r.AddCallback(kDepth, [&value] { return value; });
  EXPECT_THAT(r.Text(), HasSubstr("test_queue_depth 1\n"));
  value = INFINITY;
  EXPECT_THAT(r.Text(), HasSubstr("test_queue_depth +Inf\n"));
  value = std::nan("");
  EXPECT_THAT(r.Text(), HasSubstr("test_queue_depth NaN\n"));
}

TEST(RegistryTest, ASnapshotIsReadOncePerScrapeForAllItsFamilies) {
  Registry r;
  int reads = 0;
  double depth = 2;
  r.AddSnapshot([&](Snapshot& s) {
    ++reads;
    s.Set(kRequests, 10 * reads);
    s.Set(kDepth, depth);
  });
  EXPECT_EQ(reads, 1);  // Once at registration, to learn the families.
  depth = 5;
  EXPECT_EQ(r.Text(),
            "# HELP test_requests_total Requests served.\n# TYPE test_requests_total counter\n"
            "test_requests_total 20\n"
            "# HELP test_queue_depth Items queued.\n# TYPE test_queue_depth gauge\n"
            "test_queue_depth 5\n");
  EXPECT_EQ(reads, 2);
  EXPECT_THAT(r.Text(), HasSubstr("test_requests_total 30\n"));
  EXPECT_EQ(reads, 3);
}

TEST(RegistryDeathTest, ASnapshotMustSetTheSameFamiliesEachTime) {
  Registry r;
  bool swap = false;
  r.AddSnapshot([&](Snapshot& s) {
    s.Set(swap ? kDepth : kRequests, 1);
    s.Set(swap ? kRequests : kDepth, 1);
  });
  swap = true;
  EXPECT_DEATH(r.Text(), "same families in the same order");
}

TEST(RegistryTest, HistogramsStayConsistentUnderConcurrentObservers) {
  Registry r;
  Histogram& h = r.AddHistogram(kLatency);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&h] {
      for (int i = 0; i < 10000; ++i) h.Observe(i % 20);
    });
  }
  for (int i = 0; i < 50; ++i) {
    const Histogram::Snapshot s = h.Take();
    EXPECT_EQ(s.cumulative.back(), s.count);
    for (size_t b = 1; b < s.cumulative.size(); ++b) EXPECT_LE(s.cumulative[b - 1], s.cumulative[b]);
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(h.Take().count, 40000u);
}

TEST(RegistryDeathTest, MisnamedOrInconsistentFamiliesAreProgrammingErrors) {
  Registry r;
  EXPECT_DEATH(r.AddCounter({"test_requests", Type::kCounter, "h"}), "end in _total");
  EXPECT_DEATH(r.AddGauge({"test_depth_total", Type::kGauge, "h"}), "end in _total");
  EXPECT_DEATH(r.AddGauge({"test_latency_ms", Type::kGauge, "h"}), "abbreviated unit");
  EXPECT_DEATH(r.AddGauge({"Test-Depth", Type::kGauge, "h"}), "invalid metric name");
  EXPECT_DEATH(r.AddGauge({"test_nohelp", Type::kGauge, ""}), "no help");
  EXPECT_DEATH(r.AddHistogram({"test_h_seconds", Type::kHistogram, "h", {1, 1}}), "strictly increasing");
  EXPECT_DEATH(r.AddHistogram({"test_h_seconds", Type::kHistogram, "h", {1}}, {{"le", "x"}}), "invalid label");
  r.AddCounter(kRequests, {{"code", "OK"}});
  EXPECT_DEATH(r.AddCounter(kRequests, {{"method", "x"}}), "same label names");
  EXPECT_DEATH(r.AddCounter({"test_requests_total", Type::kCounter, "other help"}), "different definitions");
  Registry other;
  other.AddCounter(kRequests);
  EXPECT_EQ(SharedFamily({&r, &other}), "test_requests_total");
  EXPECT_DEATH(Text({&r, &other}), "exported by two registries");
  absl::StatusOr<std::unique_ptr<MetricsServer>> server = MetricsServer::Start("0", {&r, &other});
  EXPECT_TRUE(absl::IsInternal(server.status())) << server.status();
}

TEST(ProcessMetricsTest, ReadsMemoryCpuAndDescriptors) {
  Registry r;
  AddProcessMetrics(&r);
  std::map<std::string, double> values;
  for (absl::string_view line : absl::StrSplit(r.Text(), '\n', absl::SkipEmpty())) {
    if (line[0] == '#') continue;
    std::vector<std::string> parts = absl::StrSplit(line, ' ');
    values[parts[0]] = std::stod(parts[1]);
  }
  EXPECT_GT(values["process_resident_memory_bytes"], 1e6);
  EXPECT_GE(values["process_virtual_memory_bytes"], values["process_resident_memory_bytes"]);
  EXPECT_GT(values["process_open_fds"], 2);
  EXPECT_GE(values["process_threads"], 1);
  EXPECT_GE(values["process_cpu_seconds_total"], 0);
  // This test process's start: before now, and not long before.
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  EXPECT_LE(values["process_start_time_seconds"], now + 1);
  EXPECT_GT(values["process_start_time_seconds"], now - 3600);
}

// A plain HTTP/1.0 GET over a socket, so the server is tested against a
// client that is not its own library. Returns the whole response.
std::string HttpGet(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    close(fd);
    return "";
  }
  const std::string request = absl::StrCat("GET ", path, " HTTP/1.0\r\nHost: localhost\r\n\r\n");
  (void)!write(fd, request.data(), request.size());
  std::string response;
  char buffer[4096];
  for (ssize_t n; (n = read(fd, buffer, sizeof(buffer))) > 0;) response.append(buffer, n);
  close(fd);
  return response;
}

TEST(MetricsServerTest, ServesTheRegistriesOverHttp) {
  Registry a, b;
  a.AddCounter(kRequests).Increment(7);
  b.AddGauge(kDepth).Set(4);
  absl::StatusOr<std::unique_ptr<MetricsServer>> server = MetricsServer::Start("127.0.0.1:0", {&a, &b});
  ASSERT_TRUE(server.ok()) << server.status();
  ASSERT_GT((*server)->port(), 0);
  const std::string response = HttpGet((*server)->port(), "/metrics");
  EXPECT_THAT(response, HasSubstr("200 OK"));
  EXPECT_THAT(response, HasSubstr("Content-Type: text/plain; version=0.0.4; charset=utf-8"));
  EXPECT_THAT(response, HasSubstr("\r\n\r\n# HELP test_requests_total Requests served.\n"));
  EXPECT_THAT(response, HasSubstr("test_requests_total 7\n"));
  EXPECT_THAT(response, HasSubstr("test_queue_depth 4\n"));
  a.AddCounter(kRequests).Increment();
  EXPECT_THAT(HttpGet((*server)->port(), "/metrics"), HasSubstr("test_requests_total 8\n"));
  EXPECT_THAT(HttpGet((*server)->port(), "/nothing"), HasSubstr("404"));
}

TEST(MetricsServerTest, RefusesBadAddressesNamingTheFlag) {
  for (const char* bad : {"", "x", "127.0.0.1:", "127.0.0.1:70000", ":9100", "localhost:-1"}) {
    absl::StatusOr<std::unique_ptr<MetricsServer>> server = MetricsServer::Start(bad, {});
    EXPECT_TRUE(absl::IsInvalidArgument(server.status())) << bad << ": " << server.status();
    EXPECT_THAT(server.status().message(), HasSubstr("--metrics_listen"));
  }
  absl::StatusOr<std::unique_ptr<MetricsServer>> first = MetricsServer::Start("0", {});
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ((*first)->host(), "127.0.0.1");
  absl::StatusOr<std::unique_ptr<MetricsServer>> second =
      MetricsServer::Start(absl::StrCat((*first)->port()), {});
  EXPECT_TRUE(absl::IsUnavailable(second.status())) << second.status();
  EXPECT_THAT(second.status().message(), HasSubstr("--metrics_listen: cannot listen on 127.0.0.1:"));
}

}  // namespace
}  // namespace imca::metrics
