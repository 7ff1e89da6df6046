/* A plain C99 program against the C ABI and the default model's generated header:
 * creates the model, checks version and status strings, evaluates in float and
 * double, and checks the input policy. Prints the outputs for the Python tests. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "dampnet/dampnet.h"
#include "dn_model_default.h"

#include "expect.h"

int main(void) {
  dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp* m = NULL;
  double x[DN_MODEL_DEFAULT_N_INPUTS], y = 0.0, mid[DN_MODEL_DEFAULT_N_INPUTS];
  float xf[DN_MODEL_DEFAULT_N_INPUTS], yf = 0.0f;
  uint32_t mask = 0;
  int i, k, st;

  EXPECT(dn_version() == DN_VERSION_HEADER);
  EXPECT(strlen(dn_version_string()) >= 5);
  EXPECT(strstr(dn_status_str(DN_E_NULL), "NULL") != NULL);
  EXPECT(dn_mlp_create(NULL, &m) == DN_E_NULL);
  EXPECT(dn_mlp_create(&desc, &m) == DN_OK);
  EXPECT(m != NULL);
  EXPECT(dn_mlp_n_inputs(m) == DN_MODEL_DEFAULT_N_INPUTS);

  for (i = 0; i < DN_MODEL_DEFAULT_N_INPUTS; ++i)
    mid[i] = 0.5 * (dn_model_default_sat_lo[i] + dn_model_default_sat_hi[i]);

  /* A sweep through the training range: float agrees with double. */
  for (k = 0; k <= 20; ++k) {
    for (i = 0; i < DN_MODEL_DEFAULT_N_INPUTS; ++i) {
      double lo = dn_model_default_sat_lo[i], hi = dn_model_default_sat_hi[i];
      x[i] = lo + (hi - lo) * (double)((k * (i + 3)) % 21) / 21.0;
      xf[i] = (float)x[i];
    }
    EXPECT(dn_mlp_forward(m, x, &y, &mask) == DN_OK);
    EXPECT(dn_mlp_forward_f(m, xf, &yf, NULL) == DN_OK);
    EXPECT(fabs((double)yf - y) <= 1e-5 * 2.0 / DN_MODEL_DEFAULT_OUT_GAIN);
    printf("%.17g %.9g\n", y, (double)yf);
  }

  /* NaN and Inf: finite output, documented status and mask. */
  memcpy(x, mid, sizeof x);
  x[0] = NAN;
  st = dn_mlp_forward(m, x, &y, &mask);
  EXPECT(st == DN_W_NONFINITE_INPUT && mask == 1u && isfinite(y));
  x[0] = INFINITY;
  st = dn_mlp_forward(m, x, &y, &mask);
  EXPECT(st == DN_W_SATURATED && mask == 1u && isfinite(y));
  EXPECT(dn_mlp_forward(NULL, x, &y, NULL) == DN_E_NULL);

  dn_mlp_destroy(m);
  dn_mlp_destroy(NULL);
  if (failures) fprintf(stderr, "%d expectation(s) failed\n", failures);
  return failures ? 1 : 0;
}
