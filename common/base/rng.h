#ifndef IMCA_COMMON_BASE_RNG_H_
#define IMCA_COMMON_BASE_RNG_H_

#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <random>
#include <string_view>

#include "common/base/hash.h"

namespace imca {

// xoshiro256** seeded by splitmix64: fast, small, reproducible across
// platforms (unlike std::uniform_int_distribution). Not thread-safe; give each
// thread or environment its own.
class Rng {
 public:
  explicit Rng(uint64_t seed = 0) { Seed(seed); }

  void Seed(uint64_t seed) {
    for (uint64_t& word : s_) word = SplitMix64(seed);
  }

  uint64_t Next() {
    const uint64_t result = Rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = Rotl(s_[3], 45);
    return result;
  }

  // Uniform integer in [0, bound), bound >= 1 (Lemire's multiply-shift; the
  // bias is below 2^-32 for the small bounds used here).
  uint32_t Uniform(uint32_t bound) {
    return static_cast<uint32_t>(((Next() >> 32) * static_cast<uint64_t>(bound)) >> 32);
  }

  // Uniform double in [0, 1).
  double UniformDouble() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }

  // The generator's whole state, for checkpoints: SetState(State()) continues
  // the same stream.
  std::array<uint64_t, 4> State() const { return {s_[0], s_[1], s_[2], s_[3]}; }
  void SetState(const std::array<uint64_t, 4>& state) {
    for (int i = 0; i < 4; ++i) s_[i] = state[i];
  }

  static uint64_t SplitMix64(uint64_t& state) {
    uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }

 private:
  static uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  uint64_t s_[4];
};

// The seed of the stream `name` #`index` of a run seeded `seed` (e.g. an
// actor's Score call: its id and sequence): the same for the same three
// values in any process, unrelated for different ones.
inline uint64_t NamedSeed(uint64_t seed, std::string_view name, uint64_t index) {
  uint64_t h = Fnv1a(name);
  uint64_t state = seed;
  const uint64_t a = Rng::SplitMix64(state);
  uint64_t mixed = a ^ Rng::SplitMix64(h) ^ (index * 0x9e3779b97f4a7c15ULL);
  return Rng::SplitMix64(mixed);
}

// A random nonzero id of a process's incarnation (the device, the clock and
// the pid mixed): a restarted process draws another.
inline uint64_t RandomIncarnation() {
  std::random_device device;
  uint64_t seed = (uint64_t{device()} << 32) ^ device() ^
                  static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count()) ^
                  (static_cast<uint64_t>(getpid()) << 17);
  const uint64_t value = Rng::SplitMix64(seed);
  return value != 0 ? value : 1;
}

}  // namespace imca

#endif  // IMCA_COMMON_BASE_RNG_H_
