/* Consumer of an installed dampnet: one forward pass of the default model. */
#include <math.h>
#include <stdio.h>

#include <dampnet/dampnet.h>
#include <dn_model_default.h>

int main(void) {
  dn_mlp_desc d = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp* m = NULL;
  double x[DN_MODEL_DEFAULT_N_INPUTS] = {0.1, 1.0, 2.0}, y = 0.0;
  int st = dn_mlp_create(&d, &m);
  if (st != DN_OK) {
    fprintf(stderr, "dn_mlp_create: %s\n", dn_status_str(st));
    return 1;
  }
  st = dn_mlp_forward(m, x, &y, NULL);
  printf("dampnet %s: force at v=0.1 m/s, a=1 m/s^2, u=2 V: %.17g N (status %d)\n",
         dn_version_string(), y, st);
  dn_mlp_destroy(m);
  return (st >= 0 && isfinite(y)) ? 0 : 1;
}
