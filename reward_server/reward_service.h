#ifndef IMCA_REWARD_SERVER_REWARD_SERVICE_H_
#define IMCA_REWARD_SERVER_REWARD_SERVICE_H_

#include <array>
#include <atomic>
#include <memory>
#include <string>
#include <utility>

#include "absl/base/thread_annotations.h"
#include "absl/container/flat_hash_map.h"
#include "absl/synchronization/mutex.h"
#include "common/env/env.h"
#include "common/metrics/metrics.h"
#include "common/rpc/admission.h"
#include "imca/v1/reward_service.grpc.pb.h"
#include "reward_server/credit.h"
#include "reward_server/scorer.h"

namespace imca::reward {

// How many Score calls run at once: in total, and of one actor id. A call
// over either bound ends at once with RESOURCE_EXHAUSTED (an actor retries
// it with backoff), so one client that floods the server cannot starve the
// others. An honest actor has one call in flight, two while a timed-out
// call still runs.
struct ServiceLimits {
  int max_inflight = 64;
  int max_inflight_per_actor = 4;
  // Actor ids whose last Score is remembered to answer a retry without
  // counting it again; a new id past this is scored but not remembered.
  size_t max_tracked_actors = 1 << 16;
};

// The gRPC face of a Scorer: validates each request completely (names the bad
// field in INVALID_ARGUMENT) before the scorer sees it, so a rejected request
// changes nothing. The first Score of each actor id logs it with the peer's
// identity (docs/security.md). Thread-safe.
class RewardServiceImpl final : public v1::RewardService::Service {
 public:
  // `scenario` and `scorer` must outlive the service. `snapshot_path` may be
  // empty (Snapshot then answers FAILED_PRECONDITION).
  RewardServiceImpl(const env::Scenario* scenario, Scorer* scorer, std::string reward_kind,
                    ScorerConfig config, std::string snapshot_path, ServiceLimits limits = {});

  grpc::Status Score(grpc::ServerContext* context, const v1::ScoreRequest* request,
                     v1::ScoreResponse* response) override;
  grpc::Status GetStats(grpc::ServerContext* context, const v1::GetStatsRequest* request,
                        v1::RewardStats* response) override;
  grpc::Status Snapshot(grpc::ServerContext* context, const v1::SnapshotRequest* request,
                        v1::SnapshotResponse* response) override;

  // What GetStats answers.
  v1::RewardStats Stats() const;

  // After this, Score answers UNAVAILABLE (used while draining at shutdown).
  void StopAccepting() { accepting_.store(false); }

  // The reward server's Prometheus families (docs/metrics.md), read from
  // Stats() at each scrape: transitions scored, requests served, rejected
  // and repeated, table entries, model updates; and the answered calls'
  // seconds by phase and in the handler.
  const metrics::Registry& metrics() const { return registry_; }

 private:
  const env::Scenario* scenario_;
  Scorer* scorer_;
  const std::string reward_kind_;
  const ScorerConfig config_;
  const std::string snapshot_path_;
  ConcurrencyLimiter inflight_;
  std::atomic<bool> accepting_{true};
  std::atomic<int64_t> transitions_scored_{0};
  std::atomic<int64_t> requests_served_{0};
  std::atomic<int64_t> requests_rejected_{0};
  std::atomic<int64_t> requests_repeated_{0};
  // The newest scored (incarnation, sequence) of each actor id, to answer a
  // retry without counting it twice; at most max_tracked_actors_ ids.
  const size_t max_tracked_actors_;
  absl::Mutex scored_mu_;
  absl::flat_hash_map<std::string, std::pair<uint64_t, int64_t>> last_scored_ ABSL_GUARDED_BY(scored_mu_);
  metrics::Registry registry_;
  std::array<metrics::Counter*, kNumScorePhases> score_seconds_{};  // By ScorePhase.
  metrics::Counter* handler_seconds_ = nullptr;
};

}  // namespace imca::reward

#endif  // IMCA_REWARD_SERVER_REWARD_SERVICE_H_
