// The generated header from C++ translation units, with the compile-time-size kernel.
#include "dampnet/mlp.hpp"
#include "dn_model_default.h"

using DefaultModel = dampnet::StaticMlp<float, DN_MODEL_DEFAULT_N_INPUTS, DN_MODEL_DEFAULT_N_HIDDEN1,
                                        DN_MODEL_DEFAULT_N_HIDDEN2>;

float tu_a_forward_mid() {
  static DefaultModel m;
  const dn_mlp_desc d = DN_MODEL_DEFAULT_DESC_INIT;
  if (m.load(&d) != DN_OK) return -1.0f;
  float x[DN_MODEL_DEFAULT_N_INPUTS], y = 0.0f;
  for (int i = 0; i < DN_MODEL_DEFAULT_N_INPUTS; ++i)
    x[i] = static_cast<float>(0.5 * (dn_model_default_sat_lo[i] + dn_model_default_sat_hi[i]));
  m.forward(x, &y);
  return y;
}
