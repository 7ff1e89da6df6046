// A minimal test harness: CHECK counts failures and prints where; main returns their count.
#pragma once
#include <cmath>
#include <cstdio>

namespace dn_test {
inline int& failures() {
  static int n = 0;
  return n;
}
}  // namespace dn_test

#define CHECK(cond)                                                          \
  do {                                                                       \
    if (!(cond)) {                                                           \
      std::fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
      ++dn_test::failures();                                                 \
    }                                                                        \
  } while (0)

#define CHECK_NEAR(a, b, tol)                                                            \
  do {                                                                                   \
    const double a_ = (a), b_ = (b), t_ = (tol);                                         \
    if (!(std::fabs(a_ - b_) <= t_)) {                                                   \
      std::fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.17g, %s = %.17g, tol %.3g\n", \
                   __FILE__, __LINE__, #a, a_, #b, b_, t_);                              \
      ++dn_test::failures();                                                             \
    }                                                                                    \
  } while (0)

#define TEST_MAIN_RETURN()                                                   \
  do {                                                                       \
    if (dn_test::failures()) std::fprintf(stderr, "%d check(s) failed\n", dn_test::failures()); \
    else std::printf("all checks passed\n");                                 \
    return dn_test::failures() ? 1 : 0;                                      \
  } while (0)
