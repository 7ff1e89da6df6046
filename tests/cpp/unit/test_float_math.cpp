// dampnet::fmath's float log1p and expm1 (the valve term's float builds) against the double
// std::log1p and std::expm1: every 64th float bit pattern over their ranges (log1p_f on
// [0, 1e8], expm1_neg_f on [0, 200]), relative error at most 4 float epsilons (the bound
// float_math.hpp states); exact edges. Prints the worst errors.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "check.hpp"
#include "dampnet/float_math.hpp"

namespace {

float next_ulps(float x, uint32_t n) {  // n ulps towards +inf from x >= 0
  uint32_t b;
  std::memcpy(&b, &x, 4);
  b += n;
  std::memcpy(&x, &b, 4);
  return x;
}

template <class F, class Ref>
double worst_relative(F f, Ref ref, float lo, float hi, double* at) {
  double worst = 0;
  for (float x = lo; x <= hi; x = next_ulps(x, 64)) {
    const double r = ref(double(x));
    const double err = r == 0 ? std::fabs(double(f(x))) : std::fabs(double(f(x)) - r) / std::fabs(r);
    if (err > worst) worst = err, *at = x;
  }
  return worst;
}

}  // namespace

int main() {
  using dampnet::fmath::expm1_neg_f;
  using dampnet::fmath::log1p_f;
  const double eps = 1.1920928955078125e-07;
  double at = 0;
  // (from the smallest normal float up: 1e-38 .. 1e8, and 0)
  const double wl = worst_relative(log1p_f, [](double x) { return std::log1p(x); }, 1.2e-38f, 1e8f, &at);
  std::printf("log1p_f: worst relative error vs std::log1p over [1.2e-38, 1e8] = %.3g (%.2f eps) at x = %.9g\n",
              wl, wl / eps, at);
  CHECK(wl <= 4 * eps);
  CHECK(log1p_f(0.0f) == 0.0f);
  const double we = worst_relative(expm1_neg_f, [](double t) { return std::expm1(-t); }, 1.2e-38f, 200.0f, &at);
  std::printf("expm1_neg_f: worst relative error vs std::expm1(-t) over [1.2e-38, 200] = %.3g (%.2f eps) at t = %.9g\n",
              we, we / eps, at);
  CHECK(we <= 4 * eps);
  CHECK(expm1_neg_f(0.0f) == 0.0f);
  CHECK(expm1_neg_f(87.4f) == -1.0f && expm1_neg_f(1e30f) == -1.0f && expm1_neg_f(INFINITY) == -1.0f);
  CHECK(std::isnan(expm1_neg_f(NAN)));
  // either side of the branch at ln2 / 2: no step beyond the tolerance
  const float b = 0.34657359f;
  CHECK_NEAR(expm1_neg_f(b), std::expm1(-double(b)), 4 * eps * 0.3);
  CHECK_NEAR(expm1_neg_f(next_ulps(b, 1)), std::expm1(-double(next_ulps(b, 1))), 4 * eps * 0.3);
  TEST_MAIN_RETURN();
}
