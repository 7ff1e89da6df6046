// Huge-page backed result arrays for Loop.simulate: see huge_pages.hpp for why.
#include "huge_pages.hpp"

#include <cstdint>

#ifdef __linux__
#include <sys/mman.h>
#endif

namespace dnpy {

void* map_huge_pages(std::size_t bytes, py::object* owner) {
#ifdef __linux__
  constexpr std::size_t kHuge = std::size_t(2) << 20;
  if (bytes < 2 * kHuge) return nullptr;
  const std::size_t len = (bytes + kHuge - 1) / kHuge * kHuge;
  void* raw = mmap(nullptr, len + kHuge, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) return nullptr;
  char* base = static_cast<char*>(raw);
  char* p = reinterpret_cast<char*>((reinterpret_cast<std::uintptr_t>(base) + kHuge - 1) & ~(kHuge - 1));
  if (p > base) munmap(base, std::size_t(p - base));  // the slack before
  if (base + len + kHuge > p + len) munmap(p + len, std::size_t(base + len + kHuge - (p + len)));  // after
  madvise(p, len, MADV_HUGEPAGE);
  struct Mapping {
    void* p;
    std::size_t len;
  };
  *owner = py::capsule(new Mapping{p, len}, [](void* m) {
    auto* mp = static_cast<Mapping*>(m);
    munmap(mp->p, mp->len);
    delete mp;
  });
  return p;
#else
  (void)bytes;
  (void)owner;
  return nullptr;
#endif
}

}  // namespace dnpy
