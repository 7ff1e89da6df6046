/* Caller-provided storage (dn_*_size / dn_*_init, "Caller-provided storage" in dampnet.h): every
 * object built by init in the caller's memory behaves exactly as the one create allocates
 * (bit-identical outputs and loop states), init refuses memory that is too small, misaligned or
 * NULL with *out = NULL, and invalid arguments give the same status as create. C99. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "dampnet/dampnet.h"
#include "dn_model_default.h"

#include "expect.h"

/* Memory aligned as dn_storage_align() says, from a pool freed at the end. */
static void* pool[64];
static int n_pool;
static void* aligned(size_t bytes) {
  const size_t a = dn_storage_align();
  unsigned char* raw = (unsigned char*)malloc(bytes + a);
  pool[n_pool++] = raw;
  return raw + (a - (size_t)((uintptr_t)raw % a)) % a;
}

static int same_bits(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }

static void sizes_and_refusals(void) {
  const size_t a = dn_storage_align();
  EXPECT(a >= 1 && a <= DN_STORAGE_ALIGN && (a & (a - 1)) == 0);
  EXPECT(dn_mlp_size() > 0 && dn_damper_size() > 0 && dn_loop_model_size() > 0 && dn_loop_data_size() > 0);
  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  void* mem = aligned(dn_mlp_size() + 1);
  dn_mlp* m = (dn_mlp*)&m; /* not NULL: init must clear it on every error */
  EXPECT(dn_mlp_init(&desc, mem, dn_mlp_size() - 1, &m) == DN_E_SIZE && m == NULL);
  m = (dn_mlp*)&m;
  EXPECT(dn_mlp_init(&desc, NULL, dn_mlp_size(), &m) == DN_E_NULL && m == NULL);
  EXPECT(dn_mlp_init(&desc, mem, dn_mlp_size(), NULL) == DN_E_NULL);
  if (a > 1) {
    m = (dn_mlp*)&m;
    EXPECT(dn_mlp_init(&desc, (unsigned char*)mem + 1, dn_mlp_size(), &m) == DN_E_PARAM && m == NULL);
  }
  /* an invalid model: the same status as create */
  dn_mlp_desc bad = desc;
  bad.out_gain = 0.0;
  dn_mlp* c = NULL;
  EXPECT(dn_mlp_create(&bad, &c) == DN_E_PARAM && c == NULL);
  EXPECT(dn_mlp_init(&bad, mem, dn_mlp_size(), &m) == DN_E_PARAM && m == NULL);
  bad = desc;
  bad.n_hidden1 = DN_MAX_HIDDEN + 1;
  EXPECT(dn_mlp_init(&bad, mem, dn_mlp_size(), &m) == dn_mlp_create(&bad, &c) && m == NULL && c == NULL);
  /* dampers and loops */
  dn_damper* d = (dn_damper*)&d;
  void* dmem = aligned(dn_damper_size());
  EXPECT(dn_damper_init_linear(NAN, dmem, dn_damper_size(), &d) == DN_E_NONFINITE_PARAM && d == NULL);
  EXPECT(dn_damper_init_linear(1000.0, dmem, dn_damper_size() / 2, &d) == DN_E_SIZE && d == NULL);
  EXPECT(dn_damper_init_neural(NULL, dn_model_default_feature_names, 3, NULL, NULL, 0, DN_PRECISION_FLOAT,
                               dmem, dn_damper_size(), &d) == DN_E_NULL && d == NULL);
  EXPECT(dn_damper_init_linear(1000.0, dmem, dn_damper_size(), &d) == DN_OK && d != NULL);
  dn_vehicle veh;
  dn_vehicle_default(&veh);
  veh.dt = 0.0;
  dn_loop_model* lm = (dn_loop_model*)&lm;
  void* lmem = aligned(dn_loop_model_size());
  EXPECT(dn_loop_model_init(&veh, d, NULL, lmem, dn_loop_model_size(), &lm) == DN_E_PARAM && lm == NULL);
  dn_vehicle_default(&veh);
  EXPECT(dn_loop_model_init(&veh, d, NULL, lmem, 8, &lm) == DN_E_SIZE && lm == NULL);
  dn_loop_data* ld = (dn_loop_data*)&ld;
  EXPECT(dn_loop_data_init(NULL, aligned(dn_loop_data_size()), dn_loop_data_size(), &ld) == DN_E_NULL && ld == NULL);
}

/* Two loops over the same 2,000-step road: the same statuses, forces, acceleration features,
 * clamped masks, final states (bit for bit) and evaluation counts; the car moved. */
static void same_runs(const dn_loop_model* ma, dn_loop_data* da, const dn_loop_model* mb, dn_loop_data* db,
                      double dt) {
  for (int k = 1; k <= 2000; ++k) {
    const double t = k * dt;
    const dn_loop_input in = {0.02 * sin(7.0 * t) + 0.004 * sin(40.0 * t), 0.14 * cos(7.0 * t) + 0.16 * cos(40.0 * t), 0.0};
    dn_loop_out oa, ob;
    EXPECT(dn_loop_step(ma, da, &in, &oa) == dn_loop_step(mb, db, &in, &ob));
    EXPECT(same_bits(oa.force, ob.force) && same_bits(oa.a, ob.a) && oa.clamped_mask == ob.clamped_mask);
  }
  double sa[DN_LOOP_STATE_SIZE], sb[DN_LOOP_STATE_SIZE];
  dn_loop_get_state(da, sa);
  dn_loop_get_state(db, sb);
  for (int i = 0; i < DN_LOOP_STATE_SIZE; ++i) EXPECT(same_bits(sa[i], sb[i]));
  EXPECT(fabs(sa[1]) > 1e-4); /* the car moved */
  EXPECT(dn_loop_damper_evals(da) == dn_loop_damper_evals(db));
}

/* The default model: init and create give the same forward, damper force and loop run. */
static void identical_to_create(int precision) {
  const dn_mlp_desc desc = DN_MODEL_DEFAULT_DESC_INIT;
  dn_mlp *mc = NULL, *mi = NULL;
  EXPECT(dn_mlp_create(&desc, &mc) == DN_OK);
  EXPECT(dn_mlp_init(&desc, aligned(dn_mlp_size()), dn_mlp_size(), &mi) == DN_OK && mi != NULL);
  for (int k = 0; k < 2000; ++k) { /* a grid in and beyond the saturation ranges */
    double x[3];
    float xf[3];
    for (int i = 0; i < 3; ++i) {
      const double lo = dn_model_default_sat_lo[i], hi = dn_model_default_sat_hi[i];
      x[i] = lo - 0.3 * (hi - lo) + 1.6 * (hi - lo) * (double)((k * (7 + 4 * i)) % 101) / 100.0;
      xf[i] = (float)x[i];
    }
    double yc = 0, yi = 1;
    float fc = 0, fi = 1;
    uint32_t kc = 9, ki = 8;
    EXPECT(dn_mlp_forward(mc, x, &yc, &kc) == dn_mlp_forward(mi, x, &yi, &ki) && same_bits(yc, yi) && kc == ki);
    EXPECT(dn_mlp_forward_f(mc, xf, &fc, &kc) == dn_mlp_forward_f(mi, xf, &fi, &ki) && fc == fi && kc == ki);
  }
  dn_damper *dc = NULL, *di = NULL;
  EXPECT(dn_damper_create_neural(mc, dn_model_default_feature_names, 3, NULL, NULL, 0, precision, &dc) == DN_OK);
  EXPECT(dn_damper_init_neural(mi, dn_model_default_feature_names, 3, NULL, NULL, 0, precision,
                               aligned(dn_damper_size()), dn_damper_size(), &di) == DN_OK);
  dn_mlp_destroy(mc); /* the dampers hold copies */
  dn_controller ctrl;
  dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
  ctrl.u_tau_s = 0.005;
  dn_vehicle veh;
  dn_vehicle_default(&veh);
  dn_loop_model *lc = NULL, *li = NULL;
  dn_loop_data *ddc = NULL, *ddi = NULL;
  EXPECT(dn_loop_model_create(&veh, dc, &ctrl, &lc) == DN_OK);
  EXPECT(dn_loop_model_init(&veh, di, &ctrl, aligned(dn_loop_model_size()), dn_loop_model_size(), &li) == DN_OK);
  dn_damper_destroy(dc);
  memset(di, 0xA5, dn_damper_size()); /* the loop model copied it: its memory may be reused */
  EXPECT(dn_loop_data_create(lc, &ddc) == DN_OK);
  EXPECT(dn_loop_data_init(li, aligned(dn_loop_data_size()), dn_loop_data_size(), &ddi) == DN_OK);
  same_runs(lc, ddc, li, ddi, veh.dt);
  dn_loop_data_destroy(ddc);
  dn_loop_model_destroy(lc);
}

/* dn_loop_model_init_neural (the damper built inside the loop model from the folded floats) is
 * the three-call set-up bit for bit over 2,000 steps, and refuses what those calls refuse. */
static void neural_in_place(void) {
  const dn_mlp_folded_f folded = DN_MODEL_DEFAULT_FOLDED_INIT;
  dn_mlp* mlp = NULL;
  dn_damper* damper = NULL;
  EXPECT(dn_mlp_init_folded(&folded, aligned(dn_mlp_size()), dn_mlp_size(), &mlp) == DN_OK);
  EXPECT(dn_damper_init_neural(mlp, dn_model_default_feature_names, 3, NULL, NULL, 0, DN_PRECISION_FLOAT,
                               aligned(dn_damper_size()), dn_damper_size(), &damper) == DN_OK);
  dn_controller ctrl;
  dn_controller_default(&ctrl, DN_CTRL_SKYHOOK_ONOFF);
  dn_vehicle veh;
  dn_vehicle_default(&veh);
  veh.damper_eval = DN_EVAL_PER_STEP;
  veh.accel_feature = DN_ACCEL_LINEAR;
  dn_loop_model *l3 = NULL, *l1 = NULL;
  EXPECT(dn_loop_model_init(&veh, damper, &ctrl, aligned(dn_loop_model_size()), dn_loop_model_size(), &l3) == DN_OK);
  void* mem = aligned(dn_loop_model_size());
  memset(mem, 0x5A, dn_loop_model_size()); /* no reliance on zeroed memory */
  EXPECT(dn_loop_model_init_neural(&veh, &ctrl, &folded, dn_model_default_feature_names, 3, NULL, NULL, 0, mem,
                                   dn_loop_model_size(), &l1) == DN_OK && l1 != NULL);
  dn_loop_data *d3 = NULL, *d1 = NULL;
  EXPECT(dn_loop_data_init(l3, aligned(dn_loop_data_size()), dn_loop_data_size(), &d3) == DN_OK);
  EXPECT(dn_loop_data_init(l1, aligned(dn_loop_data_size()), dn_loop_data_size(), &d1) == DN_OK);
  same_runs(l3, d3, l1, d1, veh.dt);
  /* refusals, *out cleared on each */
  dn_loop_model* r = (dn_loop_model*)&r;
  const char* unknown[3] = {"velocity", "acceleration", "no_such_feature"};
  EXPECT(dn_loop_model_init_neural(&veh, &ctrl, &folded, unknown, 3, NULL, NULL, 0, mem, dn_loop_model_size(), &r) ==
             DN_E_UNKNOWN_NAME && r == NULL);
  EXPECT(dn_loop_model_init_neural(&veh, &ctrl, &folded, dn_model_default_feature_names, 2, NULL, NULL, 0, mem,
                                   dn_loop_model_size(), &r) == DN_E_MISMATCH && r == NULL);
  EXPECT(dn_loop_model_init_neural(NULL, &ctrl, &folded, dn_model_default_feature_names, 3, NULL, NULL, 0, mem,
                                   dn_loop_model_size(), &r) == DN_E_NULL && r == NULL);
  EXPECT(dn_loop_model_init_neural(&veh, &ctrl, NULL, dn_model_default_feature_names, 3, NULL, NULL, 0, mem,
                                   dn_loop_model_size(), &r) == DN_E_NULL && r == NULL);
  EXPECT(dn_loop_model_init_neural(&veh, &ctrl, &folded, dn_model_default_feature_names, 3, NULL, NULL, 0, mem,
                                   dn_loop_model_size() - 1, &r) == DN_E_SIZE && r == NULL);
  dn_mlp_folded_f bad = folded;
  float w1[DN_MODEL_DEFAULT_N_HIDDEN1 * 3];
  memcpy(w1, folded.w1, sizeof w1);
  w1[4] = NAN;
  bad.w1 = w1;
  EXPECT(dn_loop_model_init_neural(&veh, &ctrl, &bad, dn_model_default_feature_names, 3, NULL, NULL, 0, mem,
                                   dn_loop_model_size(), &r) == DN_E_NONFINITE_PARAM && r == NULL);
  dn_vehicle bad_veh = veh;
  bad_veh.m_s = -1.0;
  EXPECT(dn_loop_model_init_neural(&bad_veh, &ctrl, &folded, dn_model_default_feature_names, 3, NULL, NULL, 0, mem,
                                   dn_loop_model_size(), &r) == DN_E_PARAM && r == NULL);
}

static void other_dampers(void) {
  const dn_parametric_params p = {400.0, 3500.0, 1800.0, 40.0, 5.0, 0.0};
  const double v[5] = {-1.0, -0.2, 0.0, 0.2, 1.0}, u[2] = {0.0, 5.0};
  const double f[10] = {-3000, -900, 0, 1000, 3500, -800, -300, 0, 400, 1200};
  dn_damper *c[3] = {NULL, NULL, NULL}, *i[3] = {NULL, NULL, NULL};
  EXPECT(dn_damper_create_parametric(&p, &c[0]) == DN_OK);
  EXPECT(dn_damper_init_parametric(&p, aligned(dn_damper_size()), dn_damper_size(), &i[0]) == DN_OK);
  EXPECT(dn_damper_create_table(v, 5, u, 2, f, &c[1]) == DN_OK);
  EXPECT(dn_damper_init_table(v, 5, u, 2, f, aligned(dn_damper_size()), dn_damper_size(), &i[1]) == DN_OK);
  EXPECT(dn_damper_create_linear(1500.0, &c[2]) == DN_OK);
  EXPECT(dn_damper_init_linear(1500.0, aligned(dn_damper_size()), dn_damper_size(), &i[2]) == DN_OK);
  for (int k = 0; k < 3; ++k) {
    EXPECT(dn_damper_kind_of(c[k]) == dn_damper_kind_of(i[k]));
    for (int j = -50; j <= 50; ++j) {
      dn_damper_input in;
      memset(&in, 0, sizeof in);
      in.v = 0.03 * j;
      in.u = 0.05 * (j + 50);
      double fc = 0, fi = 1;
      EXPECT(dn_damper_force(c[k], &in, &fc, NULL) == dn_damper_force(i[k], &in, &fi, NULL) && same_bits(fc, fi));
    }
    dn_damper_destroy(c[k]);
  }
}

int main(void) {
  sizes_and_refusals();
  identical_to_create(DN_PRECISION_FLOAT);
  identical_to_create(DN_PRECISION_DOUBLE);
  neural_in_place();
  other_dampers();
  for (int k = 0; k < n_pool; ++k) free(pool[k]);
  if (failures) {
    fprintf(stderr, "%d failures\n", failures);
    return 1;
  }
  printf("test_storage: all checks passed (sizes: mlp %zu, damper %zu, loop model %zu, loop data %zu, align %zu)\n",
         dn_mlp_size(), dn_damper_size(), dn_loop_model_size(), dn_loop_data_size(), dn_storage_align());
  return 0;
}
