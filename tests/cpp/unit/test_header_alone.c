/* Each public header on its own: included first, alone and twice (its guard), it compiles as
 * C99 and as C++17 with warnings as errors and gives what it promises. DN_HEADER_ALONE picks it
 * (tests/cpp/CMakeLists.txt): 1 dn_config.h, 2 dn_xmacro.h, 3 dn_types.h, 4 dampnet.h. Users
 * include dampnet.h only; the others are its parts, each self-contained. */
#if DN_HEADER_ALONE == 1
#include "dampnet/dn_config.h"
#include "dampnet/dn_config.h"
#elif DN_HEADER_ALONE == 2
#include "dampnet/dn_xmacro.h"
#include "dampnet/dn_xmacro.h"
#elif DN_HEADER_ALONE == 3
#include "dampnet/dn_types.h"
#include "dampnet/dn_types.h"
#elif DN_HEADER_ALONE == 4
#include "dampnet/dampnet.h"
#include "dampnet/dampnet.h"
#else
#error "DN_HEADER_ALONE: 1..4"
#endif

#include <stdio.h>

static int failures = 0;
#define EXPECT(c)                                             \
  do {                                                        \
    if (!(c)) {                                               \
      printf("FAILED line %d: %s\n", __LINE__, #c);           \
      ++failures;                                             \
    }                                                         \
  } while (0)
#define COUNT(a) ((int)(sizeof(a) / sizeof((a)[0])))

/* Every header: the build options (dn_config.h is included by all of them). */
static void config(void) {
  dn_real r = (dn_real)1;
  EXPECT(r == 1);
  EXPECT(sizeof(dn_real) == (DN_LOOP_FLOAT ? sizeof(float) : sizeof(double)));
  EXPECT(DN_CAP_INPUTS >= 1 && DN_CAP_INPUTS <= DN_MAX_INPUTS);
  EXPECT(DN_CAP_HIDDEN >= 1 && DN_CAP_HIDDEN <= DN_MAX_HIDDEN && DN_CAP_HIDDEN2 <= DN_MAX_HIDDEN2);
  EXPECT(DN_CAP_TERMS <= DN_MAX_TERMS && DN_CAP_TABLE_V <= DN_MAX_TABLE_V && DN_CAP_TABLE_U <= DN_MAX_TABLE_U);
  EXPECT(DN_DAMPER_KINDS != 0 && DN_ACCEL_FEATURES != 0 && DN_DAMPER_EVALS != 0);
  EXPECT(DN_DOUBLE_KERNEL == 0 || DN_DOUBLE_KERNEL == 1);
}

#if DN_HEADER_ALONE >= 2
/* dn_xmacro.h and what includes it: every list expands on its own (names and docs). */
#define STATUS_NAME_(id, value, text) #id,
#define ENUM_NAME_(id, value, name, doc) name,
#define INDEX_NAME_(index, name, doc) #name,
#define FIELD_NAME_(type, name, def, doc) #name,
#define OUT_NAME_(name, doc) #name,
static const char* const statuses[] = {DN_STATUS_LIST(STATUS_NAME_)};
static const char* const kinds[] = {DN_DAMPER_KIND_LIST(ENUM_NAME_)};
static const char* const laws[] = {DN_CONTROLLER_KIND_LIST(ENUM_NAME_)};
static const char* const loop_states[] = {DN_LOOP_STATE_LIST(INDEX_NAME_)};
static const char* const vehicle_fields[] = {DN_VEHICLE_FIELDS(FIELD_NAME_)};
static const char* const loop_outs[] = {DN_LOOP_OUT_LIST(OUT_NAME_)};
#define DSTATE_NAME_(id, name, unit, dyn, source, param, doc) #name,
static const char* const damper_states[] = {DN_DAMPER_STATE_LIST(DSTATE_NAME_)};
#if !DN_LOOP_FLOAT
static const char* const fullcar_states[] = {DN_FULLCAR_STATE_LIST(INDEX_NAME_)};
static const char* const corner_states[] = {DN_FULLCAR_CORNER_STATE_LIST(INDEX_NAME_)};
#endif
static void xmacro(void) {
  EXPECT(COUNT(statuses) >= 16 && statuses[0][0] == 'D');
  EXPECT(COUNT(kinds) >= 5 && kinds[3][0] == 'n');
  EXPECT(COUNT(laws) >= 6);
  EXPECT(COUNT(loop_states) == DN_LOOP_DAMPER_BASE && COUNT(damper_states) >= 3);
  EXPECT(COUNT(vehicle_fields) >= 12 && COUNT(loop_outs) >= 7);
#if !DN_LOOP_FLOAT
  EXPECT(DN_FULLCAR_CORNER_BASE == COUNT(fullcar_states) && COUNT(corner_states) == DN_FULLCAR_CORNER_DAMPER);
#else
#ifdef DN_FULLCAR_FIELDS
#error "the full vehicle's lists exist only with DN_LOOP_FLOAT 0"
#endif
#endif
}
#endif

#if DN_HEADER_ALONE >= 3
/* dn_types.h and what includes it: the enums, structs and handles, and a list's defaults (they
 * name enum values) expanded into numbers. */
#define FIELD_DEFAULT_(type, name, def, doc) (double)(def),
static const double vehicle_defaults[] = {DN_VEHICLE_FIELDS(FIELD_DEFAULT_)};
static const double controller_defaults[] = {DN_CONTROLLER_FIELDS(FIELD_DEFAULT_)};
#ifdef DN_ENUM_ROW_
#error "DN_ENUM_ROW_ is dn_types.h's own"
#endif
static void types(void) {
  /* the damper's state block closes the loop's and each full-car corner's state */
  EXPECT(DN_LOOP_STATE_SIZE == DN_LOOP_DAMPER_BASE + DN_DAMPER_STATE_SIZE);
#if !DN_LOOP_FLOAT
  EXPECT(DN_FULLCAR_CORNER_SIZE == DN_FULLCAR_CORNER_DAMPER + DN_DAMPER_STATE_SIZE);
  EXPECT(DN_FULLCAR_STATE_SIZE == DN_FULLCAR_CORNER_BASE + 4 * DN_FULLCAR_CORNER_SIZE);
#endif
  dn_damper_input in;
  dn_loop_out out;
  dn_mlp* m = NULL;
  dn_loop_data* d = NULL;
  EXPECT(DN_OK == 0 && DN_W_ACCEL_FALLBACK == 8 && DN_E_DIVERGED == -11);
  EXPECT(DN_ACT_SIGMOID == 1 && DN_DAMPER_CALLBACK == 4 && DN_CTRL_EXTERNAL == 5);
  EXPECT(DN_N_FEATURES >= 10 && DN_N_FEATURE_PARAMS >= 3 && DN_N_TERM_KINDS >= 2);
  EXPECT(DN_EVAL_DEFAULT == DN_EVAL_PER_STAGE || DN_EVAL_DEFAULT == DN_EVAL_PER_STEP);
  EXPECT(COUNT(vehicle_defaults) == COUNT(vehicle_fields) && vehicle_defaults[0] == 700.0);
  EXPECT(COUNT(controller_defaults) >= 11 && controller_defaults[0] == DN_CTRL_PASSIVE);
  in.x = 0;
  out.n_features = 0;
  EXPECT(in.x == 0 && out.n_features == 0 && m == NULL && d == NULL);
  EXPECT(sizeof(dn_mlp_desc) > 0 && sizeof(dn_mlp_folded_f) > 0 && sizeof(dn_envelope_desc) > 0);
  EXPECT(sizeof(dn_vehicle) > 0 && sizeof(dn_controller) > 0 && sizeof(dn_loop_input) == 3 * sizeof(dn_real));
#if !DN_LOOP_FLOAT
  EXPECT(sizeof(dn_fullcar_params) > 0 && sizeof(dn_fullcar_input) == 13 * sizeof(double));
  EXPECT(sizeof(dn_fullcar_out) > 0 && DN_TYRE_LINEAR == 1 && DN_STEER_DRIVER == 1);
#endif
}
#endif

#if DN_HEADER_ALONE >= 4
/* dampnet.h: the functions are declared (sizeof does not evaluate, so nothing is linked). */
static void functions(void) {
  EXPECT(DN_VERSION_HEADER >= 400);
  EXPECT(sizeof(dn_version()) == sizeof(int) && sizeof(dn_status_str(0)) == sizeof(const char*));
  EXPECT(sizeof(dn_loop_step(NULL, NULL, NULL, NULL)) == sizeof(int));
  EXPECT(sizeof(dn_storage_align()) == sizeof(size_t));
#if !DN_LOOP_FLOAT
  EXPECT(sizeof(dn_fullcar_step(NULL, NULL, NULL, NULL)) == sizeof(int));
#endif
}
#endif

int main(void) {
  config();
#if DN_HEADER_ALONE >= 2
  xmacro();
#endif
#if DN_HEADER_ALONE >= 3
  types();
#endif
#if DN_HEADER_ALONE >= 4
  functions();
#endif
  if (failures) return 1;
  printf("header %d alone (%s, DN_LOOP_FLOAT %d): all checks passed\n", DN_HEADER_ALONE,
#ifdef __cplusplus
         "C++",
#else
         "C",
#endif
         DN_LOOP_FLOAT);
  return 0;
}
