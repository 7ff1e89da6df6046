// The float tanh approximation against std::tanh over [-10, 10], every 128th
// float bit pattern (about 1.7e7 values, dense near 0 where floats are), and
// the sigmoid identity. Prints the worst errors that the docs state.
#include <cmath>
#include <cstdint>
#include <cstring>

#include "check.hpp"
#include "dampnet/activation.hpp"

int main() {
  double worst_tanh = 0.0, worst_at = 0.0;
  // Walk the float bit patterns from -10 to 10 (positive and negative halves).
  float x = -10.0f;
  while (x <= 10.0f) {
    const double err = std::fabs(double(dampnet::fast_tanh(x)) - std::tanh(double(x)));
    if (err > worst_tanh) {
      worst_tanh = err;
      worst_at = x;
    }
    uint32_t b;
    std::memcpy(&b, &x, 4);
    b = (b & 0x80000000u) ? (b > 0x80000080u ? b - 128u : 0u) : b + 128u;  // 128 ulps towards +10
    std::memcpy(&x, &b, 4);
  }
  std::printf("float fast_tanh: worst |error| vs std::tanh on [-10, 10] (every 128th float) = %.3g at x = %.9g\n",
              worst_tanh, worst_at);
  CHECK(worst_tanh < 5e-7);  // the bound stated in activation.hpp and the docs

  double worst_sig = 0.0;
  for (int i = -200000; i <= 200000; ++i) {
    const float xf = float(i) * 1e-4f;
    const double ref = 1.0 / (1.0 + std::exp(-double(xf)));
    const double got = dampnet::activate(dampnet::Activation::sigmoid, xf);
    worst_sig = std::fmax(worst_sig, std::fabs(got - ref));
  }
  std::printf("float sigmoid via tanh: worst |error| on [-20, 20] = %.3g\n", worst_sig);
  CHECK(worst_sig < 3e-7);

  // Non-finite arguments stay bounded.
  CHECK(dampnet::fast_tanh(INFINITY) == 1.0f || std::fabs(dampnet::fast_tanh(INFINITY) - 1.0f) < 1e-6f);
  CHECK(std::fabs(dampnet::fast_tanh(-INFINITY) + 1.0f) < 1e-6f);

  // double: std::tanh, exact to the last bits.
  for (double xd = -20.0; xd <= 20.0; xd += 0.01)
    CHECK(dampnet::activate(dampnet::Activation::tanh, xd) == std::tanh(xd));
  TEST_MAIN_RETURN();
}
