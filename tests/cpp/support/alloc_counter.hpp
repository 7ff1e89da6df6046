// A counting allocator for the no-allocation tests: include in exactly one
// translation unit of a test program. Every heap allocation made while g_counting
// is set increments g_allocs, whatever its entry point:
//  - plain build: malloc, calloc, realloc, aligned_alloc, posix_memalign, memalign,
//    valloc and pvalloc are interposed (glibc's __libc_* do the work), and every
//    operator new (plain, array, nothrow, aligned, aligned nothrow) is replaced;
//  - under ASan, which owns malloc and cannot be interposed, the sanitizer's own
//    allocation hook (__sanitizer_install_malloc_and_free_hooks) is called by its
//    allocator for every one of those entry points, operator new included.
// dn_alloc_counter_self_test() checks that each entry point is seen (a counter that
// misses one would pass a test that allocates).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <malloc.h>
#include <new>

#if defined(__SANITIZE_ADDRESS__)
#define DN_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define DN_TEST_ASAN 1
#endif
#endif

// volatile: the compiler knows malloc & co. as builtins that touch no user memory and
// would otherwise keep g_allocs in a register across them (a read after an allocation
// could see the value from before it: a counter that never counts).
static volatile long g_allocs = 0;
static volatile bool g_counting = false;

#if defined(DN_TEST_ASAN)
extern "C" int __sanitizer_install_malloc_and_free_hooks(
    void (*malloc_hook)(const volatile void*, std::size_t), void (*free_hook)(const volatile void*));
static void dn_count_hook(const volatile void*, std::size_t) {
  if (g_counting) g_allocs = g_allocs + 1;
}
static void dn_free_hook(const volatile void*) {}
// Installed before main (a static initialiser): the hook counts only while g_counting.
static const int dn_hooks_installed = __sanitizer_install_malloc_and_free_hooks(dn_count_hook, dn_free_hook);
#define DN_COUNT() ((void)0)  // the hook counts
#else
extern "C" void* __libc_malloc(size_t);
extern "C" void* __libc_calloc(size_t, size_t);
extern "C" void* __libc_realloc(void*, size_t);
extern "C" void* __libc_memalign(size_t, size_t);
extern "C" void* __libc_valloc(size_t);
extern "C" void* __libc_pvalloc(size_t);
#define DN_COUNT() (g_counting ? (void)(g_allocs = g_allocs + 1) : (void)0)
extern "C" void* malloc(size_t n) {
  DN_COUNT();
  return __libc_malloc(n);
}
extern "C" void* calloc(size_t a, size_t b) {
  DN_COUNT();
  return __libc_calloc(a, b);
}
extern "C" void* realloc(void* p, size_t n) {
  DN_COUNT();
  return __libc_realloc(p, n);
}
extern "C" void* aligned_alloc(size_t align, size_t n) {
  DN_COUNT();
  return __libc_memalign(align, n);
}
extern "C" void* memalign(size_t align, size_t n) {
  DN_COUNT();
  return __libc_memalign(align, n);
}
extern "C" int posix_memalign(void** out, size_t align, size_t n) {
  DN_COUNT();
  if (align < sizeof(void*) || (align & (align - 1)) != 0) return 22;  // EINVAL
  void* p = __libc_memalign(align, n);
  if (!p) return 12;  // ENOMEM
  *out = p;
  return 0;
}
extern "C" void* valloc(size_t n) {
  DN_COUNT();
  return __libc_valloc(n);
}
extern "C" void* pvalloc(size_t n) {
  DN_COUNT();
  return __libc_pvalloc(n);
}
#endif

// Every operator new, so that each form is counted once (in the plain build; under
// ASan the sanitizer's own operator new reaches its allocator and the hook).
#if !defined(DN_TEST_ASAN)
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
static void* dn_counted_alloc(std::size_t n) noexcept {
  DN_COUNT();
  const bool was = g_counting;
  g_counting = false;  // malloc below is the same allocation: count it once
  void* p = std::malloc(n ? n : 1);
  g_counting = was;
  return p;
}
static void* dn_counted_aligned(std::size_t n, std::align_val_t al) noexcept {
  DN_COUNT();
  const bool was = g_counting;
  g_counting = false;
  std::size_t a = static_cast<std::size_t>(al);
  if (a < sizeof(void*)) a = sizeof(void*);
  void* p = nullptr;
  if (posix_memalign(&p, a, n ? n : 1) != 0) p = nullptr;
  g_counting = was;
  return p;
}
void* operator new(std::size_t n) {
  void* p = dn_counted_alloc(n);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t n) {
  void* p = dn_counted_alloc(n);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return dn_counted_alloc(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return dn_counted_alloc(n); }
void* operator new(std::size_t n, std::align_val_t al) {
  void* p = dn_counted_aligned(n, al);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t n, std::align_val_t al) {
  void* p = dn_counted_aligned(n, al);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new(std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return dn_counted_aligned(n, al);
}
void* operator new[](std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return dn_counted_aligned(n, al);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
#endif  // !DN_TEST_ASAN

// The counter's own test: each entry point, called once while counting, must add at
// least one (a volatile sink keeps the compiler from eliding the allocations). Returns
// the number of entry points it missed (0 = every one seen).
struct alignas(64) DnOverAligned {
  char c[64];
};
static int dn_alloc_counter_self_test(bool verbose) {
  void* volatile sink = nullptr;
  int missed = 0;
  auto expect = [&](const char* name, auto&& alloc, auto&& release) {
    g_allocs = 0;
    g_counting = true;
    sink = alloc();
    g_counting = false;
    const long seen = g_allocs;
    release(sink);
    g_allocs = 0;
    if (seen < 1) {
      ++missed;
      std::printf("alloc counter: %s was NOT counted\n", name);
    } else if (verbose) {
      std::printf("alloc counter: %s counted\n", name);
    }
  };
  auto c_free = [](void* p) { std::free(p); };
  expect("malloc", [] { return std::malloc(24); }, c_free);
  expect("calloc", [] { return std::calloc(3, 8); }, c_free);
  void* base = std::malloc(8);
  expect("realloc", [&] { return std::realloc(base, 4096); }, c_free);
  expect("aligned_alloc", [] { return aligned_alloc(64, 128); }, c_free);
  expect("posix_memalign", [] { void* p = nullptr; return posix_memalign(&p, 64, 128) == 0 ? p : nullptr; }, c_free);
  expect("memalign", [] { return memalign(64, 128); }, c_free);
  expect("operator new", [] { return static_cast<void*>(new char); },
         [](void* p) { delete static_cast<char*>(p); });
  expect("operator new[]", [] { return static_cast<void*>(new char[16]); },
         [](void* p) { delete[] static_cast<char*>(p); });
  expect("operator new(nothrow)", [] { return static_cast<void*>(new (std::nothrow) char); },
         [](void* p) { delete static_cast<char*>(p); });
  expect("operator new[](nothrow)", [] { return static_cast<void*>(new (std::nothrow) char[16]); },
         [](void* p) { delete[] static_cast<char*>(p); });
  expect("operator new(align_val_t)", [] { return static_cast<void*>(new DnOverAligned); },
         [](void* p) { delete static_cast<DnOverAligned*>(p); });
  expect("operator new[](align_val_t)", [] { return static_cast<void*>(new DnOverAligned[2]); },
         [](void* p) { delete[] static_cast<DnOverAligned*>(p); });
  expect("operator new(align_val_t, nothrow)",
         [] { return static_cast<void*>(new (std::nothrow) DnOverAligned); },
         [](void* p) { delete static_cast<DnOverAligned*>(p); });
  return missed;
}
