/* Every function of the C ABI (dampnet.h) called as a hostile or careless caller would:
 * NULL pointers, zero, negative and huge sizes, NaN/Inf/huge/subnormal parameters and
 * inputs. Each call must return a status code (the one documented where there is one),
 * never crash (ctest runs this under ASan/UBSan), leave *out NULL on a creation error,
 * and give finite outputs whenever it reports success. Table-driven: one row per case. */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "dampnet/dampnet.h"

static int g_failures = 0;
#define FAIL(...)                                  \
  do {                                             \
    fprintf(stderr, "%s:%d: ", __FILE__, __LINE__); \
    fprintf(stderr, __VA_ARGS__);                  \
    fprintf(stderr, "\n");                         \
    ++g_failures;                                  \
  } while (0)

/* A small valid model: 3 inputs (velocity, acceleration, voltage), 4 tanh units. */
static const double W1[12] = {0.5, -0.2, 0.1, -0.3, 0.4, 0.2, 0.7, 0.1, -0.5, 0.2, -0.6, 0.3};
static const double B1[4] = {0.1, -0.1, 0.05, 0.0};
static const double WO[4] = {0.6, -0.4, 0.3, 0.2};
static const double BO[1] = {0.05};
static const double IN_OFF[3] = {-1.0, -10.0, 0.0};
static const double IN_GAIN[3] = {1.0, 0.1, 0.4};
static const double SAT_LO[3] = {-1.0, -10.0, 0.0};
static const double SAT_HI[3] = {1.0, 10.0, 5.0};
static const char* const FEATS[3] = {"velocity", "acceleration", "voltage"};

static dn_mlp_desc valid_desc(void) {
  dn_mlp_desc d;
  memset(&d, 0, sizeof d);
  d.n_inputs = 3;
  d.n_hidden1 = 4;
  d.n_hidden2 = 0;
  d.activation = DN_ACT_TANH;
  d.w1 = W1;
  d.b1 = B1;
  d.w_out = WO;
  d.b_out = BO;
  d.in_offset = IN_OFF;
  d.in_gain = IN_GAIN;
  d.in_ymin = -1.0;
  d.out_offset = -2000.0;
  d.out_gain = 2.0 / 4000.0;
  d.out_ymin = -1.0;
  d.sat_lo = SAT_LO;
  d.sat_hi = SAT_HI;
  return d;
}

static const double WEIRD[] = {NAN, INFINITY, -INFINITY, 1e308, -1e308, 0.0, -0.0, 1e-320, -1.0};
#define N_WEIRD ((int)(sizeof WEIRD / sizeof WEIRD[0]))

/* A creation's contract: an error leaves *out NULL; success sets it. */
static void check_created(const char* what, int st, const void* out) {
  if (st < 0 && out != NULL) FAIL("%s: error %d but *out not NULL", what, st);
  if (st == DN_OK && out == NULL) FAIL("%s: DN_OK but *out NULL", what);
  if (st > 0) FAIL("%s: a creation returned a warning %d", what, st);
}

static int known_status(int st) {
  if (st >= 0) return (st & ~(DN_W_SATURATED | DN_W_NONFINITE_INPUT | DN_W_ACCEL_UNCONVERGED |
                              DN_W_ACCEL_FALLBACK | DN_W_UNREACHABLE)) == 0;
  return st >= DN_E_DIVERGED && st <= DN_E_NULL;
}

static double nan_fn(void* user, const dn_damper_input* in) {
  (void)user;
  (void)in;
  return NAN;
}
static double huge_fn(void* user, const dn_damper_input* in) {
  (void)user;
  return in->v > 0 ? 1e308 : -1e308;
}

/*---- the MLP ----*/
static void mlp_cases(void) {
  dn_mlp_desc d = valid_desc();
  dn_mlp* m = (dn_mlp*)&d; /* poison: must become NULL on error */
  struct {
    const char* what;
    int field; /* which change */
    int expect;
  } rows[] = {
      {"desc NULL", 0, DN_E_NULL},        {"w1 NULL", 1, DN_E_NULL},
      {"b1 NULL", 2, DN_E_NULL},          {"w_out NULL", 3, DN_E_NULL},
      {"b_out NULL", 4, DN_E_NULL},       {"in_offset NULL", 5, DN_E_NULL},
      {"in_gain NULL", 6, DN_E_NULL},     {"sat_lo NULL", 7, DN_E_NULL},
      {"sat_hi NULL", 8, DN_E_NULL},      {"n_inputs 0", 9, DN_E_SIZE},
      {"n_inputs -1", 10, DN_E_SIZE},     {"n_inputs INT_MAX", 11, DN_E_SIZE},
      {"n_hidden1 0", 12, DN_E_SIZE},     {"n_hidden1 65", 13, DN_E_SIZE},
      {"n_hidden2 -1", 14, DN_E_SIZE},    {"n_hidden2 INT_MAX", 15, DN_E_SIZE},
      {"n_hidden2 4, w2 NULL", 16, DN_E_NULL}, {"activation 7", 17, DN_E_ACTIVATION},
      {"activation -1", 18, DN_E_ACTIVATION},  {"out_gain 0", 19, DN_E_PARAM},
      {"out_gain NaN", 20, DN_E_NONFINITE_PARAM}, {"out_offset Inf", 21, DN_E_NONFINITE_PARAM},
      {"in_ymin NaN", 22, DN_E_NONFINITE_PARAM},  {"out_offset 1e39 (float overflow)", 23, DN_E_PARAM},
      {"out_gain 1e-300 (overflows)", 24, DN_E_PARAM}, {"sat_lo > sat_hi", 25, DN_E_PARAM},
      {"w1 NaN", 26, DN_E_NONFINITE_PARAM}, {"sat_hi Inf", 27, DN_E_NONFINITE_PARAM},
      {"valid", 99, DN_OK},
  };
  double w1nan[12], satbad[3], satinf[3];
  memcpy(w1nan, W1, sizeof W1);
  w1nan[5] = NAN;
  memcpy(satbad, SAT_LO, sizeof SAT_LO);
  satbad[1] = 11.0;
  memcpy(satinf, SAT_HI, sizeof SAT_HI);
  satinf[2] = INFINITY;
  for (size_t r = 0; r < sizeof rows / sizeof rows[0]; ++r) {
    d = valid_desc();
    switch (rows[r].field) {
      case 1: d.w1 = NULL; break;
      case 2: d.b1 = NULL; break;
      case 3: d.w_out = NULL; break;
      case 4: d.b_out = NULL; break;
      case 5: d.in_offset = NULL; break;
      case 6: d.in_gain = NULL; break;
      case 7: d.sat_lo = NULL; break;
      case 8: d.sat_hi = NULL; break;
      case 9: d.n_inputs = 0; break;
      case 10: d.n_inputs = -1; break;
      case 11: d.n_inputs = INT_MAX; break;
      case 12: d.n_hidden1 = 0; break;
      case 13: d.n_hidden1 = DN_MAX_HIDDEN + 1; break;
      case 14: d.n_hidden2 = -1; break;
      case 15: d.n_hidden2 = INT_MAX; break;
      case 16: d.n_hidden2 = 4; break;
      case 17: d.activation = 7; break;
      case 18: d.activation = -1; break;
      case 19: d.out_gain = 0.0; break;
      case 20: d.out_gain = NAN; break;
      case 21: d.out_offset = INFINITY; break;
      case 22: d.in_ymin = NAN; break;
      case 23: d.out_offset = 1e39; break;
      case 24: d.out_gain = 1e-300; break;
      case 25: d.sat_lo = satbad; break;
      case 26: d.w1 = w1nan; break;
      case 27: d.sat_hi = satinf; break;
      default: break;
    }
    m = (dn_mlp*)&d;
    const int st = dn_mlp_create(rows[r].field == 0 ? NULL : &d, &m);
    if (st != rows[r].expect) FAIL("dn_mlp_create(%s): %d, expected %d", rows[r].what, st, rows[r].expect);
    check_created(rows[r].what, st, m);
    dn_mlp_destroy(m);
  }
  d = valid_desc();
  if (dn_mlp_create(&d, NULL) != DN_E_NULL) FAIL("dn_mlp_create(out NULL)");
  dn_mlp_destroy(NULL);
  if (dn_mlp_n_inputs(NULL) != DN_E_NULL) FAIL("dn_mlp_n_inputs(NULL)");

  m = NULL;
  if (dn_mlp_create(&d, &m) != DN_OK) {
    FAIL("valid model refused");
    return;
  }
  if (dn_mlp_n_inputs(m) != 3) FAIL("dn_mlp_n_inputs");
  double x[3] = {0, 0, 0}, y = 0;
  float xf[3] = {0, 0, 0}, yf = 0;
  uint32_t mask = 0;
  if (dn_mlp_forward(NULL, x, &y, &mask) != DN_E_NULL) FAIL("forward(NULL model)");
  if (dn_mlp_forward(m, NULL, &y, &mask) != DN_E_NULL) FAIL("forward(NULL x)");
  if (dn_mlp_forward(m, x, NULL, &mask) != DN_E_NULL) FAIL("forward(NULL y)");
  if (dn_mlp_forward_f(NULL, xf, &yf, NULL) != DN_E_NULL) FAIL("forward_f(NULL model)");
  if (dn_mlp_forward_f(m, NULL, &yf, NULL) != DN_E_NULL) FAIL("forward_f(NULL x)");
  if (dn_mlp_forward_f(m, xf, NULL, NULL) != DN_E_NULL) FAIL("forward_f(NULL y)");
  for (int i = 0; i < N_WEIRD; ++i)
    for (int j = 0; j < N_WEIRD; ++j)
      for (int k = 0; k < N_WEIRD; ++k) {
        x[0] = WEIRD[i], x[1] = WEIRD[j], x[2] = WEIRD[k];
        xf[0] = (float)WEIRD[i], xf[1] = (float)WEIRD[j], xf[2] = (float)WEIRD[k];
        int st = dn_mlp_forward(m, x, &y, NULL);
        if (st < 0 || !known_status(st) || !isfinite(y)) FAIL("forward(%g, %g, %g): %d, y %g", x[0], x[1], x[2], st, y);
        st = dn_mlp_forward_f(m, xf, &yf, &mask);
        if (st < 0 || !known_status(st) || !isfinite(yf)) FAIL("forward_f(%g, %g, %g): %d", x[0], x[1], x[2], st);
      }
  dn_mlp_destroy(m);
}

/*---- dampers ----*/
static void damper_cases(const dn_mlp* mlp) {
  dn_damper* d = (dn_damper*)&d;
  int st;
  /* linear */
  for (int i = 0; i < N_WEIRD; ++i) {
    d = (dn_damper*)&d;
    st = dn_damper_create_linear(WEIRD[i], &d);
    /* negative damping feeds energy in: DN_E_PARAM (issue 29) */
    const int want = !isfinite(WEIRD[i]) ? DN_E_NONFINITE_PARAM : WEIRD[i] < 0 ? DN_E_PARAM : DN_OK;
    if (st != want) FAIL("create_linear(%g): %d", WEIRD[i], st);
    check_created("create_linear", st, d);
    dn_damper_destroy(d);
  }
  if (dn_damper_create_linear(1.0, NULL) != DN_E_NULL) FAIL("create_linear(out NULL)");
  /* parametric: each field weird */
  {
    const dn_parametric_params ok = {400, 3500, 1800, 40, 5, 0.01};
    d = (dn_damper*)&d;
    if (dn_damper_create_parametric(NULL, &d) != DN_E_NULL) FAIL("create_parametric(NULL)");
    check_created("create_parametric(NULL)", DN_E_NULL, d);
    if (dn_damper_create_parametric(&ok, NULL) != DN_E_NULL) FAIL("create_parametric(out NULL)");
    for (int f = 0; f < 6; ++f)
      for (int i = 0; i < N_WEIRD; ++i) {
        dn_parametric_params p = ok;
        double* fields[6] = {&p.c_min, &p.c_max, &p.gamma, &p.f0, &p.v_max, &p.v_smooth};
        *fields[f] = WEIRD[i];
        d = (dn_damper*)&d;
        st = dn_damper_create_parametric(&p, &d);
        if (!isfinite(WEIRD[i]) && st != DN_E_NONFINITE_PARAM) FAIL("create_parametric field %d = %g: %d", f, WEIRD[i], st);
        if (!known_status(st) || st > 0) FAIL("create_parametric: status %d", st);
        check_created("create_parametric", st, d);
        dn_damper_destroy(d);
      }
  }
  /* table */
  {
    const double v[3] = {-1, 0, 1}, u[2] = {0, 5}, f[6] = {-100, 0, 100, -50, 0, 50};
    const double vdesc[3] = {1, 0, -1}, vnan[3] = {-1, NAN, 1};
    struct {
      const double *v, *u, *f;
      int n_v, n_u, expect;
    } rows[] = {
        {NULL, u, f, 3, 2, DN_E_NULL}, {v, NULL, f, 3, 2, DN_E_NULL}, {v, u, NULL, 3, 2, DN_E_NULL},
        {v, u, f, 1, 2, DN_E_SIZE},    {v, u, f, 0, 2, DN_E_SIZE},    {v, u, f, -3, 2, DN_E_SIZE},
        {v, u, f, 3, 0, DN_E_SIZE},    {v, u, f, INT_MAX, 2, DN_E_SIZE}, {v, u, f, 3, INT_MIN, DN_E_SIZE},
        {vdesc, u, f, 3, 2, DN_E_PARAM}, {vnan, u, f, 3, 2, DN_E_NONFINITE_PARAM}, {v, u, f, 3, 2, DN_OK},
    };
    for (size_t r = 0; r < sizeof rows / sizeof rows[0]; ++r) {
      d = (dn_damper*)&d;
      st = dn_damper_create_table(rows[r].v, rows[r].n_v, rows[r].u, rows[r].n_u, rows[r].f, &d);
      if (st != rows[r].expect) FAIL("create_table row %d: %d, expected %d", (int)r, st, rows[r].expect);
      check_created("create_table", st, d);
      dn_damper_destroy(d);
    }
    if (dn_damper_create_table(v, 3, u, 2, f, NULL) != DN_E_NULL) FAIL("create_table(out NULL)");
  }
  /* neural */
  {
    const char* bad_names[3] = {"velocity", NULL, "voltage"};
    const char* unknown[3] = {"velocity", "speed", "voltage"};
    const char* lagged[3] = {"velocity", "acceleration", "voltage_lag"};
    const char* pn[1] = {"control_lag_tau_s"};
    const char* pn_null[1] = {NULL};
    const double pv[1] = {0.03}, pv_nan[1] = {NAN}, pv_neg[1] = {-1.0};
    struct {
      const dn_mlp* m;
      const char* const* f;
      int n;
      const char* const* pn;
      const double* pv;
      int np, prec, expect;
    } rows[] = {
        {NULL, FEATS, 3, NULL, NULL, 0, 0, DN_E_NULL},
        {mlp, NULL, 3, NULL, NULL, 0, 0, DN_E_NULL},
        {mlp, FEATS, 0, NULL, NULL, 0, 0, DN_E_SIZE},
        {mlp, FEATS, -1, NULL, NULL, 0, 0, DN_E_SIZE},
        {mlp, FEATS, INT_MAX, NULL, NULL, 0, 0, DN_E_SIZE},
        {mlp, FEATS, 2, NULL, NULL, 0, 0, DN_E_MISMATCH},
        {mlp, bad_names, 3, NULL, NULL, 0, 0, DN_E_UNKNOWN_NAME},
        {mlp, unknown, 3, NULL, NULL, 0, 0, DN_E_UNKNOWN_NAME},
        {mlp, FEATS, 3, NULL, pv, 1, 0, DN_E_NULL},
        {mlp, FEATS, 3, pn, NULL, 1, 0, DN_E_NULL},
        {mlp, FEATS, 3, pn_null, pv, 1, 0, DN_E_UNKNOWN_NAME},
        {mlp, FEATS, 3, pn, pv, -1, 0, DN_E_SIZE},
        {mlp, FEATS, 3, pn, pv_nan, 1, 0, DN_E_NONFINITE_PARAM},
        {mlp, FEATS, 3, pn, pv_neg, 1, 0, DN_E_PARAM},
        {mlp, lagged, 3, NULL, NULL, 0, 0, DN_E_PARAM},
        {mlp, FEATS, 3, NULL, NULL, 0, 2, DN_E_PARAM},
        {mlp, FEATS, 3, NULL, NULL, 0, -1, DN_E_PARAM},
        {mlp, lagged, 3, pn, pv, 1, DN_PRECISION_FLOAT, DN_OK},
    };
    for (size_t r = 0; r < sizeof rows / sizeof rows[0]; ++r) {
      d = (dn_damper*)&d;
      st = dn_damper_create_neural(rows[r].m, rows[r].f, rows[r].n, rows[r].pn, rows[r].pv,
                                   rows[r].np, rows[r].prec, &d);
      if (st != rows[r].expect) FAIL("create_neural row %d: %d, expected %d", (int)r, st, rows[r].expect);
      check_created("create_neural", st, d);
      dn_damper_destroy(d);
    }
    if (dn_damper_create_neural(mlp, FEATS, 3, NULL, NULL, 0, 0, NULL) != DN_E_NULL) FAIL("create_neural(out NULL)");
  }
  /* callback */
  d = (dn_damper*)&d;
  if (dn_damper_create_callback(NULL, NULL, &d) != DN_E_NULL) FAIL("create_callback(NULL fn)");
  check_created("create_callback", DN_E_NULL, d);
  if (dn_damper_create_callback(nan_fn, NULL, NULL) != DN_E_NULL) FAIL("create_callback(out NULL)");
  /* terms */
  {
    dn_damper* lin = NULL;
    if (dn_damper_create_linear(1000.0, &lin) != DN_OK) {
      FAIL("linear");
      return;
    }
    const double p4[4] = {-150, 3000, 0, 0}, p3[3] = {0.05, 2e6, 1.5}, p3nan[3] = {0.05, NAN, 1.5};
    const double p3neg[3] = {-0.05, 2e6, 1.5};
    struct {
      dn_damper* d;
      const char* kind;
      const double* p;
      int n, expect;
    } rows[] = {
        {NULL, "bump_stop", p3, 3, DN_E_NULL},  {lin, NULL, p3, 3, DN_E_NULL},
        {lin, "bump_stop", NULL, 3, DN_E_NULL}, {lin, "bump_stop", p3, 0, DN_E_SIZE},
        {lin, "bump_stop", p3, -1, DN_E_SIZE},  {lin, "bump_stop", p3, INT_MAX, DN_E_SIZE},
        {lin, "nope", p3, 3, DN_E_UNKNOWN_NAME}, {lin, "", p3, 3, DN_E_UNKNOWN_NAME},
        {lin, "bump_stop", p3nan, 3, DN_E_NONFINITE_PARAM}, {lin, "bump_stop", p3neg, 3, DN_E_PARAM},
        {lin, "position_poly", p4, 4, DN_OK},
    };
    for (size_t r = 0; r < sizeof rows / sizeof rows[0]; ++r) {
      st = dn_damper_add_term(rows[r].d, rows[r].kind, rows[r].p, rows[r].n);
      if (st != rows[r].expect) FAIL("add_term row %d: %d, expected %d", (int)r, st, rows[r].expect);
    }
    int n_ok = 1;
    while (dn_damper_add_term(lin, "position_poly", p4, 4) == DN_OK) ++n_ok;
    if (n_ok != DN_MAX_TERMS) FAIL("add_term accepted %d terms", n_ok);
    if (dn_damper_add_term(lin, "position_poly", p4, 4) != DN_E_SIZE) FAIL("add_term beyond DN_MAX_TERMS");
    /* kind_of, force */
    if (dn_damper_kind_of(NULL) != DN_E_NULL) FAIL("kind_of(NULL)");
    if (dn_damper_kind_of(lin) != DN_DAMPER_LINEAR) FAIL("kind_of(linear)");
    dn_damper_input in;
    memset(&in, 0, sizeof in);
    double f = 0;
    if (dn_damper_force(NULL, &in, &f, NULL) != DN_E_NULL) FAIL("force(NULL damper)");
    if (dn_damper_force(lin, NULL, &f, NULL) != DN_E_NULL) FAIL("force(NULL in)");
    if (dn_damper_force(lin, &in, NULL, NULL) != DN_E_NULL) FAIL("force(NULL force)");
    dn_damper_destroy(lin);
    dn_damper_destroy(NULL);
  }
}

/* Every damper kind's force with every field of the input weird: a status, and a finite
 * force when it succeeds (0 on an error). */
static void damper_force_cases(dn_damper* const* dampers, int n) {
  for (int k = 0; k < n; ++k) {
    const int kind = dn_damper_kind_of(dampers[k]);
    for (int field = 0; field < 9; ++field)
      for (int i = 0; i < N_WEIRD; ++i) {
        dn_damper_input in;
        memset(&in, 0, sizeof in);
        in.v = 0.1, in.u = 2.0, in.temperature = 20.0, in.dt = 1e-3;
        double* fields[9] = {&in.x, &in.v, &in.a, &in.u, &in.u_lag, &in.temperature, &in.t, &in.v_lag, &in.z_fric};
        *fields[field] = WEIRD[i];
        double f = 12345.0;
        uint32_t mask = 0;
        const int st = dn_damper_force(dampers[k], &in, &f, &mask);
        if (!known_status(st)) FAIL("damper %d force: unknown status %d", kind, st);
        if (st >= 0 && !isfinite(f)) FAIL("damper %d field %d = %g: status %d, force %g", kind, field, WEIRD[i], st, f);
        if (st < 0 && kind != DN_DAMPER_CALLBACK && f != 0.0) FAIL("damper %d: error %d, force %g not 0", kind, st, f);
      }
  }
}

/* Every damper kind's inverse with every field of the input and the demand weird: a known
 * status, finite u and force; the kinds without a control refused (DN_E_MISMATCH); an error's
 * force 0; NULL arguments DN_E_NULL. */
static void damper_inverse_cases(dn_damper* const* dampers, int n) {
  for (int k = 0; k < n; ++k) {
    const int kind = dn_damper_kind_of(dampers[k]);
    double lo = 0, hi = 0;
    const int has_range = dn_damper_control_range(dampers[k], &lo, &hi) == DN_OK;
    if (has_range != (kind == DN_DAMPER_PARAMETRIC || kind == DN_DAMPER_TABLE || kind == DN_DAMPER_NEURAL))
      FAIL("damper %d: control_range", kind);
    for (int field = 0; field < 10; ++field)
      for (int i = 0; i < N_WEIRD; ++i) {
        dn_damper_input in;
        memset(&in, 0, sizeof in);
        in.v = 0.1, in.u = 2.0, in.temperature = 20.0, in.dt = 1e-3;
        double demand = 300.0;
        double* fields[10] = {&in.x, &in.v, &in.a, &in.u, &in.u_lag, &in.temperature, &in.t, &in.v_lag, &in.z_fric, &demand};
        *fields[field] = WEIRD[i];
        double u = 12345.0, f = 12345.0;
        int evals = -1;
        const int st = dn_damper_inverse(dampers[k], &in, demand, &u, &f, &evals);
        if (!known_status(st)) FAIL("damper %d inverse: unknown status %d", kind, st);
        if (!isfinite(u) || !isfinite(f)) FAIL("damper %d inverse field %d = %g: status %d, u %g, force %g", kind, field, WEIRD[i], st, u, f);
        if (evals < 0 || evals > DN_INVERSE_WARM_EVALS + 2 + DN_INVERSE_MAX_ITERS) FAIL("damper %d inverse: %d evaluations", kind, evals);
        if (!has_range && st != DN_E_MISMATCH) FAIL("damper %d inverse without a control: status %d", kind, st);
        if (st < 0 && f != 0.0) FAIL("damper %d inverse: error %d, force %g not 0", kind, st, f);
        if (st >= 0 && (u < lo || u > hi)) FAIL("damper %d inverse: u %g outside [%g, %g]", kind, u, lo, hi);
        /* from a start: the same field weird, and the start itself weird */
        for (int s = 0; s < 2; ++s) {
          u = f = 12345.0;
          evals = -1;
          const double start = s == 0 ? 1.0 : WEIRD[i];
          const int sn = dn_damper_inverse_near(dampers[k], &in, demand, start, &u, &f, &evals);
          if (!known_status(sn)) FAIL("damper %d inverse_near: unknown status %d", kind, sn);
          if (!isfinite(u) || !isfinite(f)) FAIL("damper %d inverse_near field %d = %g, start %g: status %d, u %g, force %g", kind, field, WEIRD[i], start, sn, u, f);
          if (evals < 0 || evals > DN_INVERSE_WARM_EVALS + 2 + DN_INVERSE_MAX_ITERS) FAIL("damper %d inverse_near: %d evaluations", kind, evals);
          if (!has_range && sn != DN_E_MISMATCH) FAIL("damper %d inverse_near without a control: status %d", kind, sn);
          if (sn < 0 && f != 0.0) FAIL("damper %d inverse_near: error %d, force %g not 0", kind, sn, f);
          if (sn >= 0 && (u < lo || u > hi)) FAIL("damper %d inverse_near: u %g outside [%g, %g]", kind, u, lo, hi);
        }
      }
    dn_damper_input in;
    memset(&in, 0, sizeof in);
    double u = 0, f = 0;
    if (dn_damper_inverse(NULL, &in, 0.0, &u, &f, NULL) != DN_E_NULL) FAIL("inverse(NULL damper)");
    if (dn_damper_inverse(dampers[k], NULL, 0.0, &u, &f, NULL) != DN_E_NULL) FAIL("inverse(NULL in)");
    if (dn_damper_inverse(dampers[k], &in, 0.0, NULL, &f, NULL) != DN_E_NULL) FAIL("inverse(NULL u)");
    if (dn_damper_inverse(dampers[k], &in, 0.0, &u, NULL, NULL) != DN_E_NULL) FAIL("inverse(NULL force)");
    if (dn_damper_inverse_near(NULL, &in, 0.0, 1.0, &u, &f, NULL) != DN_E_NULL) FAIL("inverse_near(NULL damper)");
    if (dn_damper_inverse_near(dampers[k], NULL, 0.0, 1.0, &u, &f, NULL) != DN_E_NULL) FAIL("inverse_near(NULL in)");
    if (dn_damper_inverse_near(dampers[k], &in, 0.0, 1.0, NULL, &f, NULL) != DN_E_NULL) FAIL("inverse_near(NULL u)");
    if (dn_damper_inverse_near(dampers[k], &in, 0.0, 1.0, &u, NULL, NULL) != DN_E_NULL) FAIL("inverse_near(NULL force)");
    if (dn_damper_control_range(dampers[k], NULL, &hi) != DN_E_NULL) FAIL("control_range(NULL)");
  }
}

/*---- the loop ----*/
#define VEH_OFFSET_(type, name, def, doc) offsetof(dn_vehicle, name),
#define VEH_IS_DOUBLE_(type, name, def, doc) (sizeof(type) == sizeof(double)),
static const size_t VEH_OFF[] = {DN_VEHICLE_FIELDS(VEH_OFFSET_)};
static const int VEH_DBL[] = {DN_VEHICLE_FIELDS(VEH_IS_DOUBLE_)};
#define CTRL_OFFSET_(type, name, def, doc) offsetof(dn_controller, name),
#define CTRL_IS_DOUBLE_(type, name, def, doc) (sizeof(type) == sizeof(double)),
static const size_t CTRL_OFF[] = {DN_CONTROLLER_FIELDS(CTRL_OFFSET_)};
static const int CTRL_DBL[] = {DN_CONTROLLER_FIELDS(CTRL_IS_DOUBLE_)};
static const int WEIRD_INT[] = {-1, 2, 3, 6, 100, INT_MAX, INT_MIN};

/* Create a loop from (veh, damper, ctrl); when accepted run a few steps of a bumpy road:
 * statuses known, errors only DN_E_DIVERGED (finite inputs), state finite throughout. */
static void run_loop(const char* what, const dn_vehicle* veh, const dn_damper* damper,
                     const dn_controller* ctrl) {
  dn_loop_model* m = (dn_loop_model*)&m;
  int st = dn_loop_model_create(veh, damper, ctrl, &m);
  if (!known_status(st) || st > 0) FAIL("%s: model_create status %d", what, st);
  {  /* dn_vehicle_check / dn_controller_check give creation's verdict (vehicle first); a
      * force-tracking law on a damper without a control: DN_E_MISMATCH (no inverse) */
    const int vc = dn_vehicle_check(veh), cc = ctrl ? dn_controller_check(ctrl) : DN_OK;
    dn_real lo, hi;
    const int force_law = ctrl && ctrl->kind >= DN_CTRL_SKYHOOK_FORCE && ctrl->kind <= DN_CTRL_CLIPPED_OPTIMAL;
    const int expect = vc < 0 ? vc : cc < 0 ? cc
                     : force_law && dn_damper_control_range(damper, &lo, &hi) != DN_OK ? DN_E_MISMATCH : DN_OK;
    if (st != expect) FAIL("%s: create %d, vehicle_check %d, controller_check %d", what, st, vc, cc);
  }
  check_created(what, st, m);
  if (st != DN_OK) return;
  dn_loop_data* d = NULL;
  if (dn_loop_data_create(m, &d) != DN_OK) FAIL("%s: data_create", what);
  double s[DN_LOOP_STATE_SIZE];
  for (int k = 0; k < 60 && d; ++k) {
    dn_loop_input in = {0.05 * (k % 7 == 3), 0.0, 2.5};
    dn_loop_out out;
    st = dn_loop_step(m, d, &in, &out);
    if (!known_status(st)) FAIL("%s: step status %d", what, st);
    if (st < 0 && st != DN_E_DIVERGED && st != DN_E_NONFINITE_OUTPUT) FAIL("%s: step error %d on finite input", what, st);
    if (st >= 0 && !(isfinite(out.force) && isfinite(out.a) && isfinite(out.acc_s) && isfinite(out.acc_us)))
      FAIL("%s: step ok with a non-finite report", what);
    dn_loop_get_state(d, s);
    for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i)
      if (!isfinite(s[i])) FAIL("%s: state[%d] non-finite", what, i);
    if (st < 0) break;
  }
  dn_loop_data_destroy(d);
  dn_loop_model_destroy(m);
}

static void loop_cases(dn_damper* const* dampers, int n_dampers) {
  dn_vehicle veh;
  dn_controller ctrl;
  dn_vehicle_default(NULL);
  dn_controller_default(NULL, DN_CTRL_PASSIVE);
  if (dn_vehicle_check(NULL) != DN_E_NULL) FAIL("vehicle_check(NULL)");
  if (dn_controller_check(NULL) != DN_E_NULL) FAIL("controller_check(NULL)");
  dn_vehicle_default(&veh);
  dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
  dn_loop_model* m = (dn_loop_model*)&m;
  if (dn_loop_model_create(NULL, dampers[0], &ctrl, &m) != DN_E_NULL) FAIL("model_create(NULL veh)");
  check_created("model_create(NULL veh)", DN_E_NULL, m);
  m = (dn_loop_model*)&m;
  if (dn_loop_model_create(&veh, NULL, &ctrl, &m) != DN_E_NULL) FAIL("model_create(NULL damper)");
  check_created("model_create(NULL damper)", DN_E_NULL, m);
  if (dn_loop_model_create(&veh, dampers[0], &ctrl, NULL) != DN_E_NULL) FAIL("model_create(out NULL)");
  run_loop("ctrl NULL", &veh, dampers[0], NULL);
  {  /* absurd but positive values are refused at creation, not run into overflow */
    const double tiny[] = {1e-320, 4.9e-324};
    for (int i = 0; i < 2; ++i) {
      dn_vehicle v = veh;
      v.m_s = tiny[i];
      m = NULL;
      if (dn_loop_model_create(&v, dampers[0], &ctrl, &m) != DN_E_PARAM) FAIL("m_s %g accepted", tiny[i]);
      dn_loop_model_destroy(m);
      v = veh;
      v.m_us = tiny[i];
      m = NULL;
      if (dn_loop_model_create(&v, dampers[0], &ctrl, &m) != DN_E_PARAM) FAIL("m_us %g accepted", tiny[i]);
      dn_loop_model_destroy(m);
      v = veh;
      v.dt = tiny[i];
      m = NULL;
      if (dn_loop_model_create(&v, dampers[0], &ctrl, &m) != DN_E_PARAM) FAIL("dt %g accepted", tiny[i]);
      dn_loop_model_destroy(m);
    }
  }
  for (int kind = -2; kind <= DN_CTRL_CLIPPED_OPTIMAL + 3; ++kind) {  /* a law out of range is refused */
    dn_controller c;
    dn_controller_default(&c, kind);
    m = NULL;
    const int st = dn_loop_model_create(&veh, dampers[0], &c, &m);
    if ((kind < DN_CTRL_PASSIVE || kind > DN_CTRL_CLIPPED_OPTIMAL) != (st == DN_E_PARAM)) FAIL("law %d: %d", kind, st);
    dn_loop_model_destroy(m);
  }
  /* every force-tracking law on every damper (refused without a control), and one of them with
   * every controller field weird: the inverse in the step stays bounded and finite */
  for (int k = 0; k < n_dampers; ++k) {
    char what[96];
    for (int kind = DN_CTRL_SKYHOOK_FORCE; kind <= DN_CTRL_CLIPPED_OPTIMAL; ++kind) {
      dn_controller c;
      dn_controller_default(&c, kind);
      c.k_travel = -13000.0, c.k_vs = 1400.0, c.k_tyre = 500.0, c.k_vus = -200.0;
      snprintf(what, sizeof what, "damper %d force law %d", k, kind);
      run_loop(what, &veh, dampers[k], &c);
    }
    for (size_t f = 0; f < sizeof CTRL_OFF / sizeof CTRL_OFF[0]; ++f) {
      const int n = CTRL_DBL[f] ? N_WEIRD : (int)(sizeof WEIRD_INT / sizeof WEIRD_INT[0]);
      for (int i = 0; i < n; ++i) {
        dn_controller c;
        dn_controller_default(&c, DN_CTRL_CLIPPED_OPTIMAL);
        char* p = (char*)&c + CTRL_OFF[f];
        if (CTRL_DBL[f]) memcpy(p, &WEIRD[i], sizeof(double));
        else memcpy(p, &WEIRD_INT[i], sizeof(int));
        snprintf(what, sizeof what, "damper %d clipped_optimal field %d value %d", k, (int)f, i);
        run_loop(what, &veh, dampers[k], &c);
      }
    }
  }
  /* every vehicle and controller field weird, with every damper */
  for (int k = 0; k < n_dampers; ++k) {
    char what[96];
    for (size_t f = 0; f < sizeof VEH_OFF / sizeof VEH_OFF[0]; ++f) {
      const int n = VEH_DBL[f] ? N_WEIRD : (int)(sizeof WEIRD_INT / sizeof WEIRD_INT[0]);
      for (int i = 0; i < n; ++i) {
        dn_vehicle v = veh;
        char* p = (char*)&v + VEH_OFF[f];
        if (VEH_DBL[f]) memcpy(p, &WEIRD[i], sizeof(double));
        else memcpy(p, &WEIRD_INT[i], sizeof(int));
        snprintf(what, sizeof what, "damper %d vehicle field %d value %d", k, (int)f, i);
        run_loop(what, &v, dampers[k], &ctrl);
      }
    }
    for (size_t f = 0; f < sizeof CTRL_OFF / sizeof CTRL_OFF[0]; ++f) {
      const int n = CTRL_DBL[f] ? N_WEIRD : (int)(sizeof WEIRD_INT / sizeof WEIRD_INT[0]);
      for (int i = 0; i < n; ++i) {
        dn_controller c = ctrl;
        char* p = (char*)&c + CTRL_OFF[f];
        if (CTRL_DBL[f]) memcpy(p, &WEIRD[i], sizeof(double));
        else memcpy(p, &WEIRD_INT[i], sizeof(int));
        snprintf(what, sizeof what, "damper %d controller field %d value %d", k, (int)f, i);
        run_loop(what, &veh, dampers[k], &c);
      }
    }
  }

  /* data, state, step and forward with NULLs and weird inputs */
  m = NULL;
  if (dn_loop_model_create(&veh, dampers[0], &ctrl, &m) != DN_OK) {
    FAIL("valid loop refused");
    return;
  }
  dn_loop_data* d = (dn_loop_data*)&d;
  if (dn_loop_data_create(NULL, &d) != DN_E_NULL) FAIL("data_create(NULL model)");
  check_created("data_create(NULL)", DN_E_NULL, d);
  if (dn_loop_data_create(m, NULL) != DN_E_NULL) FAIL("data_create(out NULL)");
  d = NULL;
  if (dn_loop_data_create(m, &d) != DN_OK) FAIL("data_create");
  double s[DN_LOOP_STATE_SIZE], s2[DN_LOOP_STATE_SIZE];
  dn_loop_input in = {0, 0, 0};
  dn_loop_out out;
  if (dn_loop_reset(NULL, d) != DN_E_NULL || dn_loop_reset(m, NULL) != DN_E_NULL) FAIL("reset(NULL)");
  if (dn_loop_state_size() != DN_LOOP_STATE_SIZE) FAIL("state_size");
  if (dn_loop_get_state(NULL, s) != DN_E_NULL || dn_loop_get_state(d, NULL) != DN_E_NULL) FAIL("get_state(NULL)");
  if (dn_loop_set_state(NULL, s) != DN_E_NULL || dn_loop_set_state(d, NULL) != DN_E_NULL) FAIL("set_state(NULL)");
  if (dn_loop_damper_evals(NULL) != DN_E_NULL) FAIL("damper_evals(NULL)");
  if (dn_loop_step(NULL, d, &in, &out) != DN_E_NULL || dn_loop_step(m, NULL, &in, &out) != DN_E_NULL ||
      dn_loop_step(m, d, NULL, &out) != DN_E_NULL)
    FAIL("step(NULL)");
  if (dn_loop_forward(NULL, d, &in, &out) != DN_E_NULL || dn_loop_forward(m, NULL, &in, &out) != DN_E_NULL ||
      dn_loop_forward(m, d, NULL, &out) != DN_E_NULL)
    FAIL("forward(NULL)");
  if (dn_loop_step(m, d, &in, NULL) < 0) FAIL("step(out NULL) is allowed");
  if (dn_loop_forward(m, d, &in, NULL) < 0) FAIL("forward(out NULL) is allowed");
  /* each state entry weird: non-finite refused with the state kept, finite accepted; then
   * a step reports a status and leaves a finite state */
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i)
    for (int w = 0; w < N_WEIRD; ++w) {
      dn_loop_reset(m, d);
      dn_loop_get_state(d, s);
      s[i] = WEIRD[w];
      const int st = dn_loop_set_state(d, s);
      if (isfinite(WEIRD[w]) != (st == DN_OK)) FAIL("set_state[%d] = %g: %d", i, WEIRD[w], st);
      if (st != DN_OK) {
        dn_loop_get_state(d, s2);
        for (int j = 0; j < DN_LOOP_STATE_SIZE; ++j)
          if (!isfinite(s2[j])) FAIL("set_state refused but wrote");
        continue;
      }
      int stf = dn_loop_forward(m, d, &in, &out);
      int sts = dn_loop_step(m, d, &in, &out);
      if (!known_status(stf) || !known_status(sts)) FAIL("state[%d] = %g: statuses %d %d", i, WEIRD[w], stf, sts);
      if (sts < 0 && sts != DN_E_DIVERGED) FAIL("state[%d] = %g: step error %d", i, WEIRD[w], sts);
      if (sts >= 0 && !(isfinite(out.force) && isfinite(out.a) && isfinite(out.x) && isfinite(out.acc_s)))
        FAIL("state[%d] = %g: success with a non-finite report", i, WEIRD[w]);
      dn_loop_get_state(d, s2);
      for (int j = 0; j < DN_LOOP_STATE_SIZE; ++j)
        if (!isfinite(s2[j])) FAIL("state[%d] = %g: state %d non-finite after a step", i, WEIRD[w], j);
    }
  /* step inputs weird: the caller's NaN/Inf is DN_E_NONFINITE_INPUT, finite overflow
   * DN_E_DIVERGED, and a refused step keeps the state */
  dn_controller ext;
  dn_controller_default(&ext, DN_CTRL_EXTERNAL);
  dn_loop_model* me = NULL;
  if (dn_loop_model_create(&veh, dampers[0], &ext, &me) != DN_OK) FAIL("external law");
  for (int a = 0; a < N_WEIRD && me; ++a)
    for (int b = 0; b < N_WEIRD; ++b)
      for (int c = 0; c < N_WEIRD; ++c) {
        dn_loop_reset(me, d);
        dn_loop_input w = {WEIRD[a], WEIRD[b], WEIRD[c]};
        dn_loop_get_state(d, s);
        const int st = dn_loop_step(me, d, &w, &out);
        const int nonfinite = !isfinite(w.z_r) || !isfinite(w.v_r) || !isfinite(w.u);
        if (nonfinite && st != DN_E_NONFINITE_INPUT) FAIL("step(%g, %g, %g): %d", w.z_r, w.v_r, w.u, st);
        if (!nonfinite && st < 0 && st != DN_E_DIVERGED) FAIL("step(%g, %g, %g): %d", w.z_r, w.v_r, w.u, st);
        if (st < 0) {
          dn_loop_get_state(d, s2);
          if (memcmp(s, s2, sizeof s) != 0) FAIL("a refused step changed the state");
        }
        const int stf = dn_loop_forward(me, d, &w, &out);
        if (!known_status(stf)) FAIL("forward status %d", stf);
      }
  dn_loop_model_destroy(me);
  dn_loop_data_destroy(d);
  dn_loop_data_destroy(NULL);
  dn_loop_model_destroy(m);
  dn_loop_model_destroy(NULL);
}

int main(void) {
  if (dn_version() != DN_VERSION_HEADER) FAIL("dn_version");
  if (!dn_version_string() || !dn_version_string()[0]) FAIL("dn_version_string");
  const int codes[] = {INT_MIN, -1000, -12, -11, -1, 0, 1, 3, 7, 8, 15, 16, 31, 1 << 30, INT_MAX};
  for (size_t i = 0; i < sizeof codes / sizeof codes[0]; ++i) {
    const char* s = dn_status_str(codes[i]);
    if (!s || !s[0]) FAIL("dn_status_str(%d) empty", codes[i]);
  }
  if (!strstr(dn_status_str(DN_W_SATURATED | DN_W_ACCEL_FALLBACK), "DN_W_ACCEL_FALLBACK")) FAIL("status_str OR");
  if (!strstr(dn_status_str(32), "unknown")) FAIL("status_str(32) should be unknown");
  if (!strstr(dn_status_str(DN_W_UNREACHABLE), "DN_W_UNREACHABLE")) FAIL("status_str(DN_W_UNREACHABLE)");

  mlp_cases();

  dn_mlp_desc desc = valid_desc();
  dn_mlp* mlp = NULL;
  if (dn_mlp_create(&desc, &mlp) != DN_OK) {
    FAIL("valid model");
    return 1;
  }
  damper_cases(mlp);

  /* one damper of every kind, each with a stiff term, for the force and loop tables */
  dn_damper* dampers[7] = {NULL, NULL, NULL, NULL, NULL, NULL, NULL};
  const dn_parametric_params par = {400, 3500, 1800, 40, 5, 0.01};
  const double tv[3] = {-1, 0, 1}, tu[2] = {0, 5}, tf[6] = {-1000, 0, 1000, -500, 0, 500};
  const double bump[3] = {0.05, 2e6, 1.5};
  int st = dn_damper_create_linear(1500.0, &dampers[0]);
  st |= dn_damper_create_parametric(&par, &dampers[1]);
  st |= dn_damper_create_table(tv, 3, tu, 2, tf, &dampers[2]);
  st |= dn_damper_create_neural(mlp, FEATS, 3, NULL, NULL, 0, DN_PRECISION_FLOAT, &dampers[3]);
  st |= dn_damper_create_neural(mlp, FEATS, 3, NULL, NULL, 0, DN_PRECISION_DOUBLE, &dampers[4]);
  st |= dn_damper_create_callback(nan_fn, NULL, &dampers[5]);
  st |= dn_damper_create_callback(huge_fn, NULL, &dampers[6]);
  if (st != DN_OK) FAIL("dampers");
  for (int k = 0; k < 5; ++k)
    if (dn_damper_add_term(dampers[k], "bump_stop", bump, 3) != DN_OK) FAIL("bump_stop");
  damper_force_cases(dampers, 7);
  damper_inverse_cases(dampers, 7);
  loop_cases(dampers, 7);
  for (int k = 0; k < 7; ++k) dn_damper_destroy(dampers[k]);
  dn_mlp_destroy(mlp);
  if (g_failures) fprintf(stderr, "%d check(s) failed\n", g_failures);
  else printf("all checks passed\n");
  return g_failures ? 1 : 0;
}
