#include "learner/algorithms/cmae/cmae_parts.h"

#include <algorithm>
#include <cmath>

#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"

namespace imca::learner::cmae {

namespace {

absl::Status Short(const char* what) { return absl::DataLossError(absl::StrCat("checkpoint: ", what, " cut short")); }

}  // namespace

// ---- QTable ----

const double* QTable::Row(int64_t state) const {
  const auto it = rows_.find(state);
  return it == rows_.end() ? nullptr : it->second.data();
}

double QTable::Value(int64_t state, int action) const {
  const double* row = Row(state);
  return row == nullptr ? 0 : row[action];
}

double QTable::Max(int64_t state) const {
  const double* row = Row(state);
  if (row == nullptr) return 0;
  return *std::max_element(row, row + num_actions_);
}

void QTable::Update(int64_t state, int action, double reward, int64_t next_state, bool done, double lr,
                    double gamma) {
  const double target = done ? reward : reward + gamma * Max(next_state);
  auto [it, inserted] = rows_.try_emplace(state);
  if (inserted) it->second.fill(0);
  double& q = it->second[action];
  q = (1 - lr) * q + lr * target;
}

std::vector<int64_t> QTable::NonzeroStates() const {
  std::vector<int64_t> states;
  for (const auto& [state, row] : rows_) {
    if (std::any_of(row.begin(), row.begin() + num_actions_, [](double v) { return v != 0; })) {
      states.push_back(state);
    }
  }
  std::sort(states.begin(), states.end());
  return states;
}

void QTable::Write(std::ostream& out) const {
  std::vector<int64_t> states;
  states.reserve(rows_.size());
  for (const auto& entry : rows_) states.push_back(entry.first);
  std::sort(states.begin(), states.end());
  WritePod(out, static_cast<int64_t>(states.size()));
  for (int64_t state : states) {
    WritePod(out, state);
    const auto& row = rows_.at(state);
    for (int a = 0; a < num_actions_; ++a) WritePod(out, row[a]);
  }
}

absl::Status QTable::Read(std::istream& in) {
  int64_t count = 0;
  if (!ReadPod(in, &count) || count < 0) return Short("a Q-table");
  absl::flat_hash_map<int64_t, std::array<double, kMaxActions>> rows;
  rows.reserve(count);
  for (int64_t i = 0; i < count; ++i) {
    int64_t state = 0;
    std::array<double, kMaxActions> row{};
    if (!ReadPod(in, &state)) return Short("a Q-table");
    for (int a = 0; a < num_actions_; ++a) {
      if (!ReadPod(in, &row[a])) return Short("a Q-table");
    }
    rows.emplace(state, row);
  }
  rows_.swap(rows);
  return absl::OkStatus();
}

// ---- Replay ----

void Transition::Write(std::ostream& out) const {
  WritePod(out, state);
  WritePod(out, next_state);
  WritePod(out, joint_action);
  WritePod(out, reward);
  WritePod(out, static_cast<uint8_t>(done));
}

bool Transition::Read(std::istream& in) {
  uint8_t flag = 0;
  if (!ReadPod(in, &state) || !ReadPod(in, &next_state) || !ReadPod(in, &joint_action) || !ReadPod(in, &reward) ||
      !ReadPod(in, &flag)) {
    return false;
  }
  done = flag != 0;
  return true;
}

Replay::Replay(int64_t capacity) : capacity_(capacity), slots_(capacity), stamps_(capacity, 0) {}

int64_t Replay::Slots::Lowest() const {
  size_t lo = head, hi = slots.size() - 1;
  while (lo < hi) {
    const size_t mid = lo + (hi - lo) / 2;
    if (slots[mid] > slots[hi]) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return slots[lo];
}

void Replay::Unindex(int64_t slot) {
  // The slot overwritten is the ring's oldest, so its state's oldest.
  auto it = slots_of_state_.find(slots_[slot].state);
  if (it != slots_of_state_.end()) {
    Slots& s = it->second;
    if (s.head < s.slots.size() && s.slots[s.head] == slot) ++s.head;
    if (s.head == s.slots.size()) {
      slots_of_state_.erase(it);
    } else if (s.head * 2 > s.slots.size()) {
      s.slots.erase(s.slots.begin(), s.slots.begin() + static_cast<std::ptrdiff_t>(s.head));
      s.head = 0;
    }
  }
  positive_.erase(slot);
}

void Replay::Index(int64_t slot) {
  slots_of_state_[slots_[slot].state].slots.push_back(slot);
  if (slots_[slot].reward >= 1) positive_.insert(slot);
}

void Replay::Insert(const Transition& t) {
  if (size_ == capacity_) Unindex(next_);
  slots_[next_] = t;
  stamps_[next_] = step_;
  Index(next_);
  step_ = t.done ? 0 : step_ + 1;
  next_ = (next_ + 1) % capacity_;
  size_ = std::min(size_ + 1, capacity_);
}

std::optional<std::pair<std::vector<int64_t>, int64_t>> Replay::GoalTrajectory(int64_t goal) const {
  const auto it = slots_of_state_.find(goal);
  if (it == slots_of_state_.end()) return std::nullopt;
  const int64_t slot = it->second.Lowest();
  std::vector<int64_t> before;
  const int32_t t = stamps_[slot];
  before.reserve(t);
  for (int32_t back = t; back >= 1; --back) before.push_back(((slot - back) % capacity_ + capacity_) % capacity_);
  return std::make_pair(std::move(before), slot);
}

std::vector<int64_t> Replay::PrioritizedBatch(int batch, Rng& rng) const {
  std::vector<int64_t> slots;
  if (positive_.empty()) return slots;
  const int64_t slot = *positive_.begin();
  for (int32_t back = 0; back <= stamps_[slot]; ++back) {
    slots.push_back(((slot - back) % capacity_ + capacity_) % capacity_);
  }
  while (static_cast<int64_t>(slots.size()) < batch) {
    slots.push_back(static_cast<int64_t>(rng.UniformDouble() * static_cast<double>(size_)));
  }
  return slots;
}

std::vector<int64_t> Replay::SampleDistinct(int count, Rng& rng) const {
  // Floyd's algorithm: min(count, size) distinct slots of [0, size).
  const int64_t k = std::min<int64_t>(count, size_);
  std::vector<int64_t> picked;
  picked.reserve(k);
  absl::flat_hash_set<int64_t> seen;
  for (int64_t j = size_ - k; j < size_; ++j) {
    const int64_t r = static_cast<int64_t>(rng.UniformDouble() * static_cast<double>(j + 1));
    const int64_t slot = seen.insert(r).second ? r : j;
    if (slot == j) seen.insert(j);
    picked.push_back(slot);
  }
  return picked;
}

void Replay::Write(std::ostream& out) const {
  WritePod(out, capacity_);
  WritePod(out, size_);
  WritePod(out, next_);
  WritePod(out, step_);
  for (int64_t i = 0; i < size_; ++i) {
    slots_[i].Write(out);
    WritePod(out, stamps_[i]);
  }
}

absl::Status Replay::Read(std::istream& in) {
  int64_t capacity = 0, size = 0, next = 0;
  int32_t step = 0;
  if (!ReadPod(in, &capacity) || !ReadPod(in, &size) || !ReadPod(in, &next) || !ReadPod(in, &step)) {
    return Short("the replay");
  }
  if (capacity != capacity_) {
    return absl::InvalidArgumentError(
        absl::StrCat("checkpoint: a replay of ", capacity, " transitions, not this configuration's ", capacity_));
  }
  if (size < 0 || size > capacity || next < 0 || next >= capacity) return absl::DataLossError("checkpoint: replay sizes");
  Replay fresh(capacity);
  for (int64_t i = 0; i < size; ++i) {
    if (!fresh.slots_[i].Read(in) || !ReadPod(in, &fresh.stamps_[i])) return Short("the replay");
  }
  // Indexed oldest first, as they were inserted.
  const int64_t oldest = size == capacity ? next : 0;
  for (int64_t i = 0; i < size; ++i) fresh.Index((oldest + i) % capacity);
  fresh.size_ = size;
  fresh.next_ = next;
  fresh.step_ = step;
  *this = std::move(fresh);
  return absl::OkStatus();
}

// ---- Subspaces ----

Subspaces::Subspaces(std::vector<int64_t> ranges, int64_t joint_actions, int max_tracked, double recip_t, int every)
    : ranges_(std::move(ranges)),
      joint_actions_(joint_actions),
      max_tracked_(max_tracked),
      recip_t_(recip_t),
      every_(every) {
  // One counter per variable, all queued at entropy 0; the first
  // max_tracked of them (in queue order) are counted from the start.
  for (int v = 0; v < static_cast<int>(ranges_.size()); ++v) {
    counters_[Mask{1} << v];
    queue_.insert(EntryOf(0, Mask{1} << v));
  }
  for (const Entry& entry : queue_) {
    if (static_cast<int>(tracked_.size()) == max_tracked_) break;
    tracked_.push_back(std::get<3>(entry));
  }
}

int Subspaces::Level(Mask mask) const { return __builtin_popcount(mask) - 1; }

int64_t Subspaces::Rank(Mask mask) const {
  // Lexicographic rank among the k-subsets of n variables.
  const int n = static_cast<int>(ranges_.size()), k = __builtin_popcount(mask);
  auto choose = [](int a, int b) -> int64_t {
    if (b < 0 || b > a) return 0;
    int64_t c = 1;
    for (int i = 1; i <= b; ++i) c = c * (a - b + i) / i;
    return c;
  };
  int64_t rank = 0;
  int previous = -1, i = 0;
  for (int v = 0; v < n; ++v) {
    if (!((mask >> v) & 1u)) continue;
    for (int j = previous + 1; j < v; ++j) rank += choose(n - 1 - j, k - 1 - i);
    previous = v;
    ++i;
  }
  return rank;
}

int64_t Subspaces::Key(Mask mask, const int32_t* vars, int64_t joint_action) const {
  int64_t projection = 0, stride = 1;
  for (int v = 0; v < static_cast<int>(ranges_.size()); ++v) {
    if (!((mask >> v) & 1u)) continue;
    projection += vars[v] * stride;
    stride *= ranges_[v];
  }
  return projection * joint_actions_ + joint_action;
}

void Subspaces::Increment(Counter& counter, int64_t key) {
  uint32_t& c = counter.counts[key];
  const double before = c > 1 ? c * std::log(static_cast<double>(c)) : 0;
  ++c;
  counter.sum_c_log_c += c * std::log(static_cast<double>(c)) - before;
  ++counter.total;
}

void Subspaces::Count(const int32_t* vars, int64_t joint_action) {
  for (Mask mask : tracked_) Increment(counters_[mask], Key(mask, vars, joint_action));
}

uint32_t Subspaces::CountOf(Mask mask, const int32_t* vars, int64_t joint_action) const {
  const auto counter = counters_.find(mask);
  if (counter == counters_.end()) return 0;
  const auto it = counter->second.counts.find(Key(mask, vars, joint_action));
  return it == counter->second.counts.end() ? 0 : it->second;
}

double Subspaces::NormalisedEntropy(Mask mask) const {
  const auto it = counters_.find(mask);
  if (it == counters_.end() || it->second.total == 0) return 0;
  const Counter& c = it->second;
  const double n = static_cast<double>(c.total);
  const double entropy = std::log(n) - c.sum_c_log_c / n;
  double range = static_cast<double>(joint_actions_);
  for (int v = 0; v < static_cast<int>(ranges_.size()); ++v) {
    if ((mask >> v) & 1u) range *= static_cast<double>(ranges_[v]);
  }
  return entropy / std::log(range);
}

std::vector<std::pair<Subspaces::Mask, double>> Subspaces::Reselect(const ForEachStep& replay, Rng& rng) {
  std::vector<Mask> taken;
  while (static_cast<int>(taken.size()) < max_tracked_ && !queue_.empty()) {
    taken.push_back(std::get<3>(*queue_.begin()));
    queue_.erase(queue_.begin());
  }
  std::vector<std::pair<Mask, double>> weights;
  double total = 0;
  for (Mask mask : taken) {
    const double h = NormalisedEntropy(mask);
    queue_.insert(EntryOf(h, mask));
    const double w = std::exp(-recip_t_ * h);
    weights.emplace_back(mask, w);
    total += w;
  }
  tracked_ = taken;
  if (weights.empty()) return weights;
  for (auto& [mask, w] : weights) w /= total;
  // np.random.multinomial(1, p): one categorical draw.
  const double u = rng.UniformDouble();
  double cumulative = 0;
  chosen_ = weights.back().first;
  for (const auto& [mask, p] : weights) {
    cumulative += p;
    if (u < cumulative) {
      chosen_ = mask;
      break;
    }
  }
  // Grow the tree: the chosen subset's supersets one variable larger.
  const int n = static_cast<int>(ranges_.size());
  if (Level(chosen_) < n - 1) {
    for (int v = 0; v < n; ++v) {
      const Mask grown = chosen_ | (Mask{1} << v);
      if (grown == chosen_ || counters_.contains(grown)) continue;
      Counter& counter = counters_[grown];
      replay([&](const int32_t* vars, int64_t joint_action) {
        Increment(counter, Key(grown, vars, joint_action));
      });
      tracked_.push_back(grown);
      queue_.insert(EntryOf(0, grown));
    }
  }
  return weights;
}

std::optional<std::pair<int, int64_t>> Subspaces::Goal(int samples, const std::function<void(int, int32_t*)>& vars_of,
                                                      const ForEachStep& replay, Rng& rng) {
  ++goals_;
  if (goals_ % every_ == 0) Reselect(replay, rng);
  if (samples == 0) return std::nullopt;
  const Counter& counter = counters_[chosen_];
  std::vector<int32_t> vars(ranges_.size());
  uint32_t least = UINT32_MAX;
  std::vector<std::pair<int, int64_t>> ties;
  for (int i = 0; i < samples; ++i) {
    vars_of(i, vars.data());
    const int64_t base = Key(chosen_, vars.data(), 0);
    for (int64_t a = 0; a < joint_actions_; ++a) {
      const auto it = counter.counts.find(base + a);
      const uint32_t c = it == counter.counts.end() ? 0 : it->second;
      if (c < least) {
        least = c;
        ties.clear();
      }
      if (c == least) ties.emplace_back(i, a);
    }
  }
  return ties[static_cast<size_t>(rng.UniformDouble() * static_cast<double>(ties.size()))];
}

void Subspaces::Write(std::ostream& out) const {
  std::vector<Mask> masks;
  for (const auto& entry : counters_) masks.push_back(entry.first);
  std::sort(masks.begin(), masks.end());
  WritePod(out, static_cast<int64_t>(masks.size()));
  for (Mask mask : masks) {
    const Counter& c = counters_.at(mask);
    std::vector<std::pair<int64_t, uint32_t>> entries(c.counts.begin(), c.counts.end());
    std::sort(entries.begin(), entries.end());
    WritePod(out, mask);
    WritePod(out, c.total);
    WritePod(out, c.sum_c_log_c);
    WritePod(out, static_cast<int64_t>(entries.size()));
    for (const auto& [key, count] : entries) {
      WritePod(out, key);
      WritePod(out, count);
    }
  }
  WritePod(out, static_cast<int64_t>(queue_.size()));
  for (const Entry& entry : queue_) {
    WritePod(out, std::get<0>(entry));
    WritePod(out, std::get<3>(entry));
  }
  WritePod(out, static_cast<int64_t>(tracked_.size()));
  for (Mask mask : tracked_) WritePod(out, mask);
  WritePod(out, chosen_);
  WritePod(out, goals_);
}

absl::Status Subspaces::Read(std::istream& in) {
  Subspaces fresh = *this;
  fresh.counters_.clear();
  fresh.queue_.clear();
  fresh.tracked_.clear();
  const Mask all = ranges_.size() >= 32 ? ~Mask{0} : (Mask{1} << ranges_.size()) - 1;
  auto valid = [&](Mask mask) { return mask != 0 && (mask & ~all) == 0; };
  int64_t counters = 0;
  if (!ReadPod(in, &counters) || counters < 0) return Short("the subspace counters");
  for (int64_t i = 0; i < counters; ++i) {
    Mask mask = 0;
    int64_t entries = 0;
    Counter c;
    if (!ReadPod(in, &mask) || !ReadPod(in, &c.total) || !ReadPod(in, &c.sum_c_log_c) || !ReadPod(in, &entries) ||
        entries < 0 || !valid(mask)) {
      return Short("the subspace counters");
    }
    c.counts.reserve(entries);
    for (int64_t e = 0; e < entries; ++e) {
      int64_t key = 0;
      uint32_t count = 0;
      if (!ReadPod(in, &key) || !ReadPod(in, &count)) return Short("the subspace counters");
      c.counts.emplace(key, count);
    }
    fresh.counters_.emplace(mask, std::move(c));
  }
  int64_t queued = 0, tracked = 0;
  if (!ReadPod(in, &queued) || queued < 0) return Short("the subspace queue");
  for (int64_t i = 0; i < queued; ++i) {
    double h = 0;
    Mask mask = 0;
    if (!ReadPod(in, &h) || !ReadPod(in, &mask) || !valid(mask)) return Short("the subspace queue");
    fresh.queue_.insert(EntryOf(h, mask));
  }
  if (!ReadPod(in, &tracked) || tracked < 0) return Short("the tracked subspaces");
  for (int64_t i = 0; i < tracked; ++i) {
    Mask mask = 0;
    if (!ReadPod(in, &mask) || !valid(mask) || !fresh.counters_.contains(mask)) return Short("the tracked subspaces");
    fresh.tracked_.push_back(mask);
  }
  if (!ReadPod(in, &fresh.chosen_) || !ReadPod(in, &fresh.goals_) || !fresh.counters_.contains(fresh.chosen_)) {
    return Short("the chosen subspace");
  }
  *this = std::move(fresh);
  return absl::OkStatus();
}

}  // namespace imca::learner::cmae
