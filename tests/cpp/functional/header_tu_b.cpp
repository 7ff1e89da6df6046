// Second C++ translation unit: the compile-time and run-time paths agree exactly.
#include <cstdio>

#include "dampnet/mlp.hpp"
#include "dn_model_default.h"

float tu_a_forward_mid();

int main() {
  dampnet::Mlp<float> m;
  const dn_mlp_desc d = DN_MODEL_DEFAULT_DESC_INIT;
  if (m.load(&d) != DN_OK) return 1;
  float x[DN_MODEL_DEFAULT_N_INPUTS], y = 0.0f;
  for (int i = 0; i < DN_MODEL_DEFAULT_N_INPUTS; ++i)
    x[i] = static_cast<float>(0.5 * (dn_model_default_sat_lo[i] + dn_model_default_sat_hi[i]));
  m.forward(x, &y);
  const bool ok = y == tu_a_forward_mid();
  std::printf("two C++ translation units: static %g, run-time %g: %s\n", tu_a_forward_mid(), y,
              ok ? "equal" : "DIFFERENT");
  return ok ? 0 : 1;
}
