/* Second translation unit including the generated header; main() checks both agree. */
#include <stdio.h>

#include "dampnet/dampnet.h"
#include "dn_model_default.h"

int tu_a_inputs(void);
double tu_a_first_weight(void);

int main(void) {
  dn_mlp_desc d = DN_MODEL_DEFAULT_DESC_INIT;
  int ok = tu_a_inputs() == d.n_inputs && tu_a_first_weight() == dn_model_default_w1[0];
  printf("two C translation units: %s\n", ok ? "consistent" : "INCONSISTENT");
  return ok ? 0 : 1;
}
