/* A small C controller-side program: the exported model (generated header) run
 * through the dampnet C library as a damper, one force per input line.
 * stdin: lines of the quantities of dn_damper_input a model may read, in struct order
 * (DN_DAMPER_INPUT_FIELDS' roles QTY and QTY_OPT: x v a u u_lag temperature v_lag z_fric ...,
 * in m, m/s, m/s^2, V, V, degC, m/s, - ...; dampnet.demo.cprogram.ROW_FIELDS);
 * stdout: the force [N] per line. Built by `dampnet demo` with
 *   cc -std=c99 -I<dampnet include> -I<model dir> controller.c -ldampnet */
#include <stdio.h>

#include "dampnet/dampnet.h"
#include "model.h"

/* One line of quantities into `in`: 1 when every one was read. */
static int read_line(dn_damper_input* in) {
  int want = 0, got = 0;
#define CTRL_READ_(name) \
  ++want;                \
  if (got + 1 == want && scanf("%lf", &in->name) == 1) ++got;
#define CTRL_ROLE_QTY(name) CTRL_READ_(name)
#define CTRL_ROLE_QTY_OPT(name) CTRL_READ_(name)
#define CTRL_ROLE_CTX(name)
#define CTRL_FIELD_(type, name, role, doc) CTRL_ROLE_##role(name)
  DN_DAMPER_INPUT_FIELDS(CTRL_FIELD_)
#undef CTRL_FIELD_
  return want > 0 && got == want;
}

int main(void) {
  dn_mlp_desc desc = DN_MODEL_DESC_INIT;
  dn_mlp* mlp = NULL;
  dn_damper* damper = NULL;
  dn_damper_input in = {0};
  double force = 0.0;
  int st = dn_mlp_create(&desc, &mlp);
#ifndef DN_MODEL_N_FEATURE_PARAMS
#error "model.h predates dampnet 0.2 (no DN_MODEL_N_FEATURE_PARAMS): export the model again"
#endif
#if DN_MODEL_N_FEATURE_PARAMS > 0
  const char* const* pnames = dn_model_feature_param_names;
  const double* pvalues = dn_model_feature_param_values;
  const int n_params = DN_MODEL_N_FEATURE_PARAMS;
#else
  const char* const* pnames = NULL;
  const double* pvalues = NULL;
  const int n_params = 0;
#endif
  if (st == DN_OK)
    st = dn_damper_create_neural(mlp, dn_model_feature_names, DN_MODEL_N_INPUTS, pnames, pvalues,
                                 n_params, DN_PRECISION_DOUBLE, &damper);
#if DN_MODEL_N_TERMS > 0
  for (int k = 0; st == DN_OK && k < DN_MODEL_N_TERMS; ++k)
    st = dn_damper_add_term(damper, dn_model_term_kinds[k], &dn_model_term_params[k * DN_MODEL_TERM_PARAMS],
                            dn_model_term_n_params[k]);
#endif
  if (st != DN_OK) {
    fprintf(stderr, "controller: %s\n", dn_status_str(st));
    return 1;
  }
  while (read_line(&in)) {
    st = dn_damper_force(damper, &in, &force, NULL);
    if (st < 0) {
      fprintf(stderr, "controller: %s\n", dn_status_str(st));
      return 1;
    }
    printf("%.17g\n", force);
  }
  dn_damper_destroy(damper);
  dn_mlp_destroy(mlp);
  return 0;
}
