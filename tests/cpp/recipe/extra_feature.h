/* A test-only stateful feature, added to the runtime through the four DN_EXTRA_* hooks of
 * dampnet.h alone: exactly the recipe's example above DN_FEATURE_LIST (displacement_lag, a
 * first-order lag of the displacement x with its time constant displacement_lag_tau_s, kept in
 * dn_damper_input.x_lag, state DN_DS_X_LAG of dynamics lag_ramp with source x).
 *
 * Force-included (`-include tests/cpp/recipe/extra_feature.h`) into every translation unit of a
 * test build; no other file changes. tests/python/test_state_recipe.py builds the quarter car and
 * the full car (recipe_hosts.c with the C ABI sources of cpp/src), the damper FMU (cpp/fmu) and the Cortex-M
 * firmware (cpp/embedded) with it and compares each with a numpy reference. */
#ifndef DN_TEST_EXTRA_FEATURE_H
#define DN_TEST_EXTRA_FEATURE_H

/* 1. DN_FEATURE_PARAM_LIST: its constant */
#define DN_EXTRA_FEATURE_PARAMS(X)                                       \
  X(DN_FPARAM_DISPLACEMENT_LAG_TAU_S, "displacement_lag_tau_s",          \
    "time constant of displacement_lag [s], > 0")
/* 2. DN_DAMPER_INPUT_FIELDS: the field holding its value (appended, QTY_OPT) */
#define DN_EXTRA_INPUT_FIELDS(X) \
  X(dn_real, x_lag, QTY_OPT, "relative displacement after a first-order lag [m]")
/* 3. DN_FEATURE_LIST: the feature */
#define DN_EXTRA_FEATURES(X) \
  X(DN_FEAT_DISPLACEMENT_LAG, "displacement_lag", x_lag, DN_FPARAM_DISPLACEMENT_LAG_TAU_S)
/* 4. DN_DAMPER_STATE_LIST: its state */
#define DN_EXTRA_DAMPER_STATES(X)                                                      \
  X(DN_DS_X_LAG, x_lag, "m", DN_DYN_LAG_RAMP, x, DN_FPARAM_DISPLACEMENT_LAG_TAU_S, \
    "relative displacement after displacement_lag's lag")

#endif
