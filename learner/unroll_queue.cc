#include "learner/unroll_queue.h"

#include <cstdio>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/time.h"
#include "common/base/status_macros.h"
#include "common/protocol/unroll_check.h"

namespace imca::learner {
UnrollQueue::UnrollQueue(Options options) : options_(std::move(options)) {}

absl::StatusOr<PushOutcome> UnrollQueue::Push(v1::Unroll unroll, const std::function<bool()>& cancelled) {
  if (PushOutcome valid = options_.validate(unroll); !valid.accepted()) {
    absl::MutexLock lock(&mu_);
    ++stats_.rejected;
    return valid;
  }
  int64_t admitted_version;
  {
    absl::MutexLock lock(&mu_);
    IMCA_ASSIGN_OR_RETURN(PushOutcome admitted, Admit(unroll));
    if (!admitted.accepted()) return admitted;
    admitted_version = version_;
  }
  // Featurised here, on the pushing (gRPC) thread, so that the training
  // thread only computes values and GAE and trains.
  FeaturisedUnroll queued = options_.featurise(std::move(unroll));
  absl::MutexLock lock(&mu_);
  ++stats_.pushers_waiting;
  const absl::Condition room(
      +[](UnrollQueue* self) ABSL_EXCLUSIVE_LOCKS_REQUIRED(self->mu_) {
        return self->closed_ || static_cast<int>(self->queue_.size()) < self->options_.capacity;
      },
      this);
  // Not queued after all: its steps no longer count towards this version's
  // batch, and a resend of it is not a duplicate.
  const auto withdraw = [&]() ABSL_EXCLUSIVE_LOCKS_REQUIRED(mu_) {
    if (options_.synchronous && version_ == admitted_version) version_steps_ -= UnrollSteps(queued.unroll);
  };
  // No wait without a timeout: every second, whether the pusher is still there.
  bool gone = false;
  while (!mu_.AwaitWithTimeout(room, absl::Seconds(1))) {
    if (cancelled != nullptr && cancelled()) {
      gone = true;
      break;
    }
  }
  --stats_.pushers_waiting;
  // Checked again after the wait: the pusher may have gone (and resent this
  // unroll on a new stream, which another push may have queued meanwhile).
  if (gone || (cancelled != nullptr && cancelled())) {
    withdraw();
    return absl::CancelledError("the pusher went away while the queue was full");
  }
  if (closed_) return ClosedStatus();
  // Both checked again: other pushes may have been queued during the wait
  // (a resend of this unroll, or new ids that filled the id cap).
  PushOutcome checked = CheckNotDuplicate(queued.unroll);
  if (checked.accepted()) checked = CheckActorIdRoom(queued.unroll);
  if (!checked.accepted()) {
    withdraw();
    return checked;
  }
  Accept(queued.unroll);
  if (options_.on_accept) options_.on_accept(queued.unroll);
  stats_.queued_steps += UnrollSteps(queued.unroll);
  queue_.push_back(std::move(queued));
  return PushOutcome();
}

void UnrollQueue::Accept(const v1::Unroll& u) {
  ++stats_.received;
  if (actors_.insert(u.actor_id()).second) ++stats_.actor_ids;
  if (u.incarnation() == 0) return;
  auto [it, inserted] = accepted_.try_emplace(u.actor_id(), Accepted{u.incarnation(), u.sequence()});
  if (inserted || it->second.incarnation != u.incarnation()) {
    ++stats_.incarnations;
    if (!inserted) {
      std::fprintf(stderr, "learner: %s restarted (incarnation %016llx, was %016llx)\n", u.actor_id().c_str(),
                   static_cast<unsigned long long>(u.incarnation()),
                   static_cast<unsigned long long>(it->second.incarnation));
    }
  }
  it->second = Accepted{u.incarnation(), u.sequence()};
}

PushOutcome UnrollQueue::CheckActorIdRoom(const v1::Unroll& unroll) {
  if (actors_.size() >= static_cast<size_t>(options_.max_actor_ids) && actors_.count(unroll.actor_id()) == 0) {
    // Each id is remembered for exactly-once delivery and reported in the
    // status: a client inventing ids must not grow them without bound.
    ++stats_.rejected;
    return Refused(v1::REJECTION_OVER_CAP, absl::StrCat("the learner tracks at most ", options_.max_actor_ids,
                                                        " actor ids; unroll.actor_id is one more"));
  }
  return PushOutcome();
}

PushOutcome UnrollQueue::CheckNotDuplicate(const v1::Unroll& unroll) {
  if (unroll.incarnation() == 0) return PushOutcome();
  auto it = accepted_.find(unroll.actor_id());
  if (it != accepted_.end() && it->second.incarnation == unroll.incarnation() &&
      unroll.sequence() <= it->second.sequence) {
    ++stats_.duplicate;
    return Refused(v1::REJECTION_DUPLICATE, absl::StrCat("duplicate: unroll ", unroll.sequence(), " of ",
                                                         unroll.actor_id(), " was accepted before"));
  }
  return PushOutcome();
}

bool UnrollQueue::TooOld(const v1::Unroll& unroll) const {
  return options_.max_policy_lag.has_value() && version_ - unroll.policy_version() > *options_.max_policy_lag;
}

absl::StatusOr<PushOutcome> UnrollQueue::Admit(const v1::Unroll& unroll) {
  if (closed_) return ClosedStatus();
  if (PushOutcome checked = CheckNotDuplicate(unroll); !checked.accepted()) return checked;
  if (PushOutcome checked = CheckActorIdRoom(unroll); !checked.accepted()) return checked;
  if (unroll.policy_version() > version_) {
    // A learner restarted from an older checkpoint: the actor must refetch.
    ++stats_.rejected;
    return Refused(v1::REJECTION_AHEAD, absl::StrCat("ahead: unroll.policy_version ", unroll.policy_version(),
                                                     " is newer than the learner's ", version_));
  }
  if (options_.synchronous) {
    if (unroll.policy_version() != version_) {
      ++stats_.stale;
      return Refused(v1::REJECTION_STALE, absl::StrCat("stale: policy version ", unroll.policy_version(),
                                                       " is not the synchronous learner's ", version_));
    }
    if (version_steps_ >= options_.batch_steps) {
      ++stats_.stale;
      return Refused(v1::REJECTION_STALE, absl::StrCat("stale: the batch of policy version ", version_,
                                                       " is full (synchronous learner)"));
    }
    version_steps_ += UnrollSteps(unroll);
  } else if (TooOld(unroll)) {
    ++stats_.stale;
    return Refused(v1::REJECTION_STALE, absl::StrCat("stale: policy version ", unroll.policy_version(),
                                                     " is more than ", *options_.max_policy_lag, " behind ",
                                                     version_));
  }
  return PushOutcome();
}

absl::Status UnrollQueue::ClosedStatus() const {
  return budget_done_ ? absl::OutOfRangeError("budget done: the learner has trained its --steps")
                      : absl::UnavailableError("learner is stopping");
}

std::optional<FeaturisedUnroll> UnrollQueue::Next(int* dropped_stale) {
  absl::MutexLock lock(&mu_);
  while (true) {
    mu_.Await(absl::Condition(
        +[](UnrollQueue* self) ABSL_EXCLUSIVE_LOCKS_REQUIRED(self->mu_) {
          return self->closed_ || !self->queue_.empty();
        },
        this));
    if (closed_) return std::nullopt;
    FeaturisedUnroll queued = std::move(queue_.front());
    queue_.pop_front();
    stats_.queued_steps -= UnrollSteps(queued.unroll);
    if (TooOld(queued.unroll)) {
      ++stats_.stale;
      ++*dropped_stale;
      continue;
    }
    return queued;
  }
}

void UnrollQueue::NewVersion(int64_t version) {
  absl::MutexLock lock(&mu_);
  version_ = version;
  version_steps_ = 0;
}

void UnrollQueue::MarkTrained(const std::vector<v1::Unroll>& unrolls) {
  absl::MutexLock lock(&mu_);
  for (const v1::Unroll& u : unrolls) {
    if (u.incarnation() == 0) continue;
    Accepted& trained = trained_[u.actor_id()];
    if (trained.incarnation != u.incarnation() || trained.sequence < u.sequence()) {
      trained = Accepted{u.incarnation(), u.sequence()};
    }
  }
}

absl::flat_hash_map<std::string, UnrollQueue::Accepted> UnrollQueue::Trained() const {
  absl::MutexLock lock(&mu_);
  return trained_;
}

void UnrollQueue::Restore(int64_t version, const absl::flat_hash_map<std::string, Accepted>& trained) {
  absl::MutexLock lock(&mu_);
  version_ = version;
  version_steps_ = 0;
  trained_ = trained;
  accepted_ = trained;
}

void UnrollQueue::Close(bool budget_done) {
  absl::MutexLock lock(&mu_);
  closed_ = true;
  budget_done_ = budget_done;
}

std::vector<std::string> UnrollQueue::ActorIds() const {
  absl::MutexLock lock(&mu_);
  return std::vector<std::string>(actors_.begin(), actors_.end());
}

UnrollQueue::Stats UnrollQueue::stats() const {
  absl::MutexLock lock(&mu_);
  Stats s = stats_;
  s.depth = static_cast<int32_t>(queue_.size());
  return s;
}

}  // namespace imca::learner
