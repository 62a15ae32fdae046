#ifndef IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_PARTS_H_
#define IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_PARTS_H_

// The pieces of CMAE (cmae.h) as its released code has them (CMAE's
// q_learner.py: QLearning, Storage and ActiveQLearning; docs/baselines.md), each alone so
// that tests can work them by hand. Not thread-safe; the algorithm owns them.

#include <array>
#include <cstdint>
#include <functional>
#include <istream>
#include <ostream>
#include <optional>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "common/base/rng.h"

namespace imca::learner::cmae {

inline constexpr int kMaxActions = 5;

// One agent's Q-table over joint states (QLearning.q_table): a state's row
// of num_actions values, 0 where absent.
class QTable {
 public:
  explicit QTable(int num_actions) : num_actions_(num_actions) {}

  int num_actions() const { return num_actions_; }
  // Q(s, .), or nullptr if s has no row (all 0).
  const double* Row(int64_t state) const;
  double Value(int64_t state, int action) const;
  // max_a Q(s, a) (0 for an absent row).
  double Max(int64_t state) const;
  // update_q: Q(s,a) <- (1 - lr) Q(s,a) + lr (r + gamma max Q(s')), or
  // lr * r in place of the bracket's bootstrap when `done`.
  void Update(int64_t state, int action, double reward, int64_t next_state, bool done, double lr, double gamma);
  void Clear() { rows_.clear(); }
  int64_t rows() const { return static_cast<int64_t>(rows_.size()); }
  // The states whose row has a nonzero value, ascending.
  std::vector<int64_t> NonzeroStates() const;

  // Every row (not only nonzero ones), in state order; Read replaces the
  // table. Errors: DATA_LOSS on a short stream.
  void Write(std::ostream& out) const;
  absl::Status Read(std::istream& in);

 private:
  int num_actions_;
  absl::flat_hash_map<int64_t, std::array<double, kMaxActions>> rows_;
};

// A joint transition of the replay.
struct Transition {
  int64_t state = 0;
  int64_t next_state = 0;
  int64_t joint_action = 0;
  double reward = 0;  // The team's extrinsic reward.
  bool done = false;

  // For checkpoints (Read: false on a short stream).
  void Write(std::ostream& out) const;
  bool Read(std::istream& in);
};

// CMAE's Storage: a ring of `capacity` transitions, each with its step
// within its episode (time stamp 0 at an episode's first step, the count
// restarting after a done one). Finds, as the code's np.where does, the
// lowest slot holding a state or a reward of at least 1 (the code's test
// of success), kept in indexes so that a lookup costs no scan of the ring.
class Replay {
 public:
  explicit Replay(int64_t capacity);

  void Insert(const Transition& t);
  int64_t size() const { return size_; }
  int64_t capacity() const { return capacity_; }
  const Transition& at(int64_t slot) const { return slots_[slot]; }
  int32_t time_stamp(int64_t slot) const { return stamps_[slot]; }

  // get_goal_tractories: the slots of the episode leading into the lowest
  // slot holding `goal` (its time stamp's worth of slots before it, in time
  // order; the ring wraps where the code's slice would come out empty), and
  // that slot. nullopt if no slot holds `goal`.
  std::optional<std::pair<std::vector<int64_t>, int64_t>> GoalTrajectory(int64_t goal) const;
  // get_prioritized_batch(batch): the slots of the episode into the lowest
  // slot with a reward >= 1, that slot first and back to the episode's
  // start, then uniform draws (with replacement) up to `batch` slots. Empty
  // while no slot has one.
  std::vector<int64_t> PrioritizedBatch(int batch, Rng& rng) const;
  // sample_states: min(count, size) distinct slots, uniformly.
  std::vector<int64_t> SampleDistinct(int count, Rng& rng) const;

  void Write(std::ostream& out) const;
  absl::Status Read(std::istream& in);

 private:
  void Unindex(int64_t slot);
  void Index(int64_t slot);

  // A state's slots, oldest first: the ring overwrites its oldest slot, so
  // the front leaves first; slot numbers rise along it but for one wrap
  // round the ring, so the lowest is found by bisection.
  struct Slots {
    std::vector<int64_t> slots;
    size_t head = 0;  // slots[head..] are live.
    int64_t Lowest() const;
  };

  int64_t capacity_;
  std::vector<Transition> slots_;
  std::vector<int32_t> stamps_;
  int64_t size_ = 0;
  int64_t next_ = 0;   // Slot the next insert writes.
  int32_t step_ = 0;   // Time stamp of the next insert.
  absl::flat_hash_map<int64_t, Slots> slots_of_state_;
  std::set<int64_t> positive_;  // Slots with a reward >= 1.
};

// The restricted-space counts of CMAE's meta learner with --tree_subspace
// and --stochastic_select_subspace (ActiveQLearning.get_goal,
// update_counts, compute_ent_subspaces): counters of (projection of the
// state onto a subset of its variables, joint action), kept for the
// subsets in a tree grown from the single variables; a priority queue of
// (normalised entropy, level, combination rank); the tracked subsets
// (counted as steps arrive). Every `every`-th goal the `max_tracked`
// lowest-entropy subsets are taken off the queue, their entropies computed
// and put back, one is picked with probability proportional to
// exp(-recip_t * H) and the supersets one variable larger of the picked
// one that have no counter yet get one, filled from the replay, and are
// tracked. Goals come from the picked subset's counter.
class Subspaces {
 public:
  // A variable subset as a bit mask (bit v: variable v).
  using Mask = uint32_t;
  // Calls `visit(vars, joint_action)` for every step the new counter must
  // hold (the replay's, CMAE's _init_counter_from_storage).
  using ForEachStep = std::function<void(const std::function<void(const int32_t*, int64_t)>&)>;

  Subspaces(std::vector<int64_t> ranges, int64_t joint_actions, int max_tracked, double recip_t, int every);

  // update_counts: one step into every tracked counter.
  void Count(const int32_t* vars, int64_t joint_action);
  // The (goal state, goal joint action) of get_goal given the states of
  // the replay's sample (`vars_of(i, vars)` writes state i's variables):
  // first, every `every`-th call, the subset is chosen again (Reselect);
  // then among the sampled states and every joint action, a pair of least
  // count in the chosen subset's counter, uniformly among ties. Returns
  // the index into the sample and the joint action; nullopt for an empty
  // sample.
  std::optional<std::pair<int, int64_t>> Goal(int samples, const std::function<void(int, int32_t*)>& vars_of,
                                             const ForEachStep& replay, Rng& rng);

  // The normalised entropy of a subset's counter: H(counts) / ln(|range|),
  // |range| = the product of its variables' ranges times the joint actions
  // (0 for a counter with no counts: the code's would be NaN).
  double NormalisedEntropy(Mask mask) const;
  // The rank of a subset among itertools.combinations of its size (the
  // code's count_id).
  int64_t Rank(Mask mask) const;
  // The count of (projection of vars onto `mask`, joint action).
  uint32_t CountOf(Mask mask, const int32_t* vars, int64_t joint_action) const;
  Mask chosen() const { return chosen_; }
  const std::vector<Mask>& tracked() const { return tracked_; }
  int64_t goals() const { return goals_; }
  bool has_counter(Mask mask) const { return counters_.contains(mask); }
  int num_counters() const { return static_cast<int>(counters_.size()); }
  // The choice step of Goal, by itself: the probabilities it chose with
  // (over the subsets taken off the queue, in queue order).
  std::vector<std::pair<Mask, double>> Reselect(const ForEachStep& replay, Rng& rng);

  void Write(std::ostream& out) const;
  absl::Status Read(std::istream& in);

 private:
  struct Counter {
    absl::flat_hash_map<int64_t, uint32_t> counts;  // Projection * joint actions + joint action.
    int64_t total = 0;
    double sum_c_log_c = 0;  // Sum of c ln c, for the entropy.
  };
  int64_t Key(Mask mask, const int32_t* vars, int64_t joint_action) const;
  void Increment(Counter& counter, int64_t key);
  int Level(Mask mask) const;
  // Queue entries: (entropy, level, rank, mask), smallest first.
  using Entry = std::tuple<double, int, int64_t, Mask>;
  Entry EntryOf(double entropy, Mask mask) const { return {entropy, Level(mask), Rank(mask), mask}; }

  std::vector<int64_t> ranges_;
  int64_t joint_actions_;
  int max_tracked_;
  double recip_t_;
  int every_;
  absl::flat_hash_map<Mask, Counter> counters_;
  std::set<Entry> queue_;
  std::vector<Mask> tracked_;
  Mask chosen_ = 1;  // The code starts at (level 0, count_id 0).
  int64_t goals_ = 0;
};

// Plain values in and out of the parts' Write/Read (host byte order: a
// checkpoint is read back on the machine type that wrote it).
template <typename T>
void WritePod(std::ostream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}
template <typename T>
bool ReadPod(std::istream& in, T* value) {
  return static_cast<bool>(in.read(reinterpret_cast<char*>(value), sizeof(T)));
}

}  // namespace imca::learner::cmae

#endif  // IMCA_LEARNER_ALGORITHMS_CMAE_CMAE_PARTS_H_
