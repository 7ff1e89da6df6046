// A counting allocator for the no-allocation tests: include in exactly one
// translation unit of a test program. Every allocation entry point increments
// g_allocs while g_counting is set. Without sanitizers malloc/calloc/realloc are
// interposed (glibc's __libc_* do the work); under ASan, which owns malloc,
// operator new (plain, array and nothrow) is counted.
#pragma once

#include <cstdlib>
#include <new>

static long g_allocs = 0;
static bool g_counting = false;

#if !defined(__SANITIZE_ADDRESS__)
extern "C" void* __libc_malloc(size_t);
extern "C" void* __libc_calloc(size_t, size_t);
extern "C" void* __libc_realloc(void*, size_t);
extern "C" void* malloc(size_t n) {
  if (g_counting) ++g_allocs;
  return __libc_malloc(n);
}
extern "C" void* calloc(size_t a, size_t b) {
  if (g_counting) ++g_allocs;
  return __libc_calloc(a, b);
}
extern "C" void* realloc(void* p, size_t n) {
  if (g_counting) ++g_allocs;
  return __libc_realloc(p, n);
}
#endif

// The replacements pair new with malloc and delete with free on purpose.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

static void* dn_counted_alloc(std::size_t n) noexcept {
  if (g_counting) ++g_allocs;
  return std::malloc(n ? n : 1);
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
// the C ABI creates objects with new (std::nothrow): replaced too, so that new
// and delete stay a matching pair (ASan checks)
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return dn_counted_alloc(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return dn_counted_alloc(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
