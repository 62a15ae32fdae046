#ifndef IMCA_COMMON_BASE_HASH_H_
#define IMCA_COMMON_BASE_HASH_H_

#include <cstdint>
#include <string_view>

namespace imca {

// 64-bit FNV-1a of `data`: the same in every process and on every platform
// (unlike std::hash), for checksums and seeds derived from names.
inline uint64_t Fnv1a(std::string_view data) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : data) h = (h ^ c) * 0x100000001b3ULL;
  return h;
}

}  // namespace imca

#endif  // IMCA_COMMON_BASE_HASH_H_
