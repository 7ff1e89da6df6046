/* dampnet X-macro lists: every name the runtime knows, defined once.
 *
 * Part of the C ABI; include "dampnet/dampnet.h", which includes this. C99 and C++. Only
 * macros: the enums and structs expanded from these lists are in dn_types.h, the functions in
 * dampnet.h. A row that names an enum value or a default (DN_INT_RK4, DN_EVAL_DEFAULT, ...) is
 * expanded where dn_types.h is included too. */
#ifndef DAMPNET_DN_XMACRO_H
#define DAMPNET_DN_XMACRO_H

#include "dampnet/dn_config.h"

/* Registries: every name the runtime knows is defined once, in an X-macro list below, and
 * the C enums, the C++ tables and the Python module's registries (dampnet._core:
 * CONTROLLER_KINDS, INTEGRATORS, FEATURE_NAMES, ...) are all expanded from these lists.
 * An enum list's rows are X(id, value, "name", doc): the value is the ABI (never renumber),
 * "name" is the one spelling Python and model files use. DN_ENUM_ROW_ (dn_types.h) declares them. */

/*---- Status codes ----*/

/* One list, so that the enum and the strings cannot drift apart.
 * Warnings are bit flags and may be OR-ed together; errors are negative. */
#define DN_STATUS_LIST(X)                                                                    \
  X(DN_OK, 0, "ok")                                                                          \
  X(DN_W_SATURATED, 1, "an input was outside its saturation limits and was clamped to them") \
  X(DN_W_NONFINITE_INPUT, 2,                                                                 \
    "an input was NaN and was replaced by the centre of its saturation range")               \
  X(DN_W_ACCEL_UNCONVERGED, 4,                                                               \
    "the implicit acceleration feature did not converge within DN_ACCEL_MAX_EVALS damper "   \
    "evaluations; the iterate with the smallest residual was used")                          \
  X(DN_W_ACCEL_FALLBACK, 8,                                                                  \
    "the linearised acceleration step was ill-conditioned (1 + k dF/da < "                   \
    "DN_ACCEL_LINEAR_MIN_SLOPE: the damper's negative apparent mass -dF/da exceeds half the " \
    "reduced mass m_s m_us / (m_s + m_us)); the explicit value (the force evaluated at the " \
    "explicit acceleration) was used")                                                       \
  X(DN_W_UNREACHABLE, 16,                                                                    \
    "the demanded force is outside [F(u_min), F(u_max)] at this motion (dn_damper_inverse): " \
    "the nearest achievable force and its control (a control limit) were returned")          \
  X(DN_E_NULL, -1, "a required pointer argument was NULL")                                   \
  X(DN_E_SIZE, -2, "a size is out of range (inputs 1..8, layers 1..2, hidden layer 1 up to "   \
                   "this build's DN_MAX_HIDDEN, 64 by default; layer 2, and layer 1 of a two-layer " \
                   "network, up to DN_MAX_HIDDEN2 = 64; or beyond this build's DN_CAP_*)")          \
  X(DN_E_NONFINITE_PARAM, -3, "a model parameter is NaN or infinite")                        \
  X(DN_E_PARAM, -4, "a parameter is out of its valid range")                                 \
  X(DN_E_ACTIVATION, -5, "unknown activation (expected DN_ACT_TANH or DN_ACT_SIGMOID)")     \
  X(DN_E_ALLOC, -6, "out of memory while creating an object")                                \
  X(DN_E_NONFINITE_OUTPUT, -7,                                                               \
    "the output overflowed to a non-finite value; it was replaced by the output offset")     \
  X(DN_E_MISMATCH, -8, "the model does not match the sizes or features it is used with")    \
  X(DN_E_UNKNOWN_NAME, -9, "unknown feature, term, parameter or kind name")                  \
  X(DN_E_NONFINITE_INPUT, -10,                                                               \
    "a step or evaluation input is NaN or infinite; nothing was computed or advanced")       \
  X(DN_E_DIVERGED, -11,                                                                      \
    "the step would produce a non-finite state, acceleration or damper force, or a state beyond " \
    "the physical bounds (DN_PLAUSIBLE_LIST: suspension travel, wheel to road, damper speed, " \
    "body roll and pitch) from finite inputs (unstable: step too large? a damper feeding energy "  \
    "in? a runaway or overflowing road?); state not advanced")

/*---- The MLP ----*/

/* Hidden-layer activations (MlpModel.activation); the output layer is always linear. */
#define DN_ACTIVATION_LIST(X)                                  \
  X(DN_ACT_TANH, 0, "tanh", "tanh(x) (MATLAB's tansig)")       \
  X(DN_ACT_SIGMOID, 1, "sigmoid", "1 / (1 + exp(-x)) (MATLAB's logsig)")

/*---- Damper models ----*/

/* Sign convention (the dyno's): displacement x and velocity v are the damper's
 * relative extension and extension rate (positive in rebound, when sprung and
 * unsprung move apart); the force F is positive when it resists extension
 * (tension). In the quarter car: x = z_s - z_us + x_static, v = dz_s - dz_us. */

/* Constants of derived features (MlpModel.feature_params), by name:
 * X(id, "name", meaning). Unknown names are refused (DN_E_UNKNOWN_NAME). */
#define DN_FEATURE_PARAM_LIST(X)                                                                   \
  X(DN_FPARAM_CONTROL_LAG_TAU_S, "control_lag_tau_s",                                               \
    "time constant of voltage_lag / current_lag [s], > 0")                                         \
  X(DN_FPARAM_VELOCITY_LAG_TAU_S, "velocity_lag_tau_s", "time constant of velocity_lag [s], > 0") \
  X(DN_FPARAM_FRICTION_PRESLIDING_M, "friction_presliding_m",                                       \
    "pre-sliding travel of friction_state [m], > 0")

/* What a damper model is evaluated on: the loop's state at one evaluation,
 * X(type, name, role, doc) in struct order. role: QTY, a quantity a model may read
 * (an argument of the Python Damper.forces); QTY_OPT, a quantity appended after 0.1
 * (a Damper.forces argument that defaults to NaN: a model reading it must be given it);
 * CTX, the evaluation's context for callback dampers. Fields are only ever appended
 * (the ABI keeps every offset). */
#define DN_DAMPER_INPUT_FIELDS(X)                                                              \
  X(dn_real, x, QTY, "relative displacement, extension positive, from the mid position [m]")  \
  X(dn_real, v, QTY, "relative velocity, extension positive [m/s]")                          \
  X(dn_real, a, QTY, "relative acceleration, extension positive [m/s^2] (see the loop)")     \
  X(dn_real, u, QTY, "control, held over the step [V or A]")             \
  X(dn_real, u_lag, QTY, "control after a first-order lag of the model's control_lag_tau_s [V or A]") \
  X(dn_real, temperature, QTY, "damper temperature [degC]")                                   \
  X(dn_real, t, CTX, "time of this evaluation [s] (callback dampers)")                        \
  X(dn_real, dt, CTX, "step size of the loop [s] (callback dampers); 0 outside a loop")      \
  X(int, stage, CTX, "integrator stage of this evaluation, 0..3 [-] (callback dampers)")     \
  /* since 0.2 (appended: the fields above keep their 0.1 offsets) */                         \
  X(dn_real, v_lag, QTY_OPT,                                                                  \
    "velocity after a first-order lag of the model's velocity_lag_tau_s [m/s]")             \
  X(dn_real, z_fric, QTY_OPT,                                                                 \
    "Dahl friction state in [-1, 1]: follows sgn(v) over a travel of a few "                \
    "friction_presliding_m after each reversal [-]")

/* The neural features, one per line: X(id, "name" (MlpModel.features), field of
 * dn_damper_input it reads, dn_feature_param it needs or DN_FPARAM_NONE). Values are
 * positions in the list (ABI: append only).
 *
 * Recipe: a new stateful feature (a lag, a friction or valve state) touches four places, all
 * in this header, and nothing else: every host (the quarter-car loop, the full car, the damper
 * and quarter-car FMUs in co-simulation and model exchange, the Cortex-M firmware), the C ABI's
 * state lists, dampnet._core's registries, DamperInput and Damper.forces, and Python's feature
 * registry, reference loop and training columns are expanded from these lists.
 *  1. DN_FEATURE_PARAM_LIST: its constant, e.g.
 *       X(DN_FPARAM_DISPLACEMENT_LAG_TAU_S, "displacement_lag_tau_s",
 *         "time constant of displacement_lag [s], > 0")
 *  2. DN_DAMPER_INPUT_FIELDS: append the field holding its value (role QTY_OPT: appended
 *     fields keep the ABI, and Damper.forces gets it as an argument defaulting to NaN), e.g.
 *       X(dn_real, x_lag, QTY_OPT, "relative displacement after a first-order lag [m]")
 *  3. DN_FEATURE_LIST: append its line (field and parameter from steps 1-2), e.g.
 *       X(DN_FEAT_DISPLACEMENT_LAG, "displacement_lag", x_lag, DN_FPARAM_DISPLACEMENT_LAG_TAU_S)
 *  4. DN_DAMPER_STATE_LIST: append its state (named as its field; its dynamics one of
 *     DN_STATE_DYNAMICS_LIST, its source x, v or u), e.g.
 *       X(DN_DS_X_LAG, x_lag, "m", DN_DYN_LAG_RAMP, x, DN_FPARAM_DISPLACEMENT_LAG_TAU_S,
 *         "relative displacement after displacement_lag's lag")
 * Then rebuild (`bash python/env.sh true`: about 1.5 min on 2 cores) and rewrite the typed stub,
 * `python tests/python/core_stub.py` (DamperInput and Damper.forces in python/dampnet/_core.pyi;
 * tests/python/test_core_stub.py fails naming that command until it is run).
 * A new kind of dynamics is a row of DN_STATE_DYNAMICS_LIST and its three formulas in
 * cpp/include/dampnet/damper_state.hpp (and python/dampnet/features.py's twin).
 * tests/python/test_state_recipe.py proves the recipe as written: it appends the four example
 * rows above to a copy of the tree, rebuilds it, rewrites its stub, passes its registry tests and
 * runs the feature through every host. */
#define DN_FEATURE_LIST(X)                                                                \
  X(DN_FEAT_VELOCITY, "velocity", v, DN_FPARAM_NONE)                                      \
  X(DN_FEAT_ACCELERATION, "acceleration", a, DN_FPARAM_NONE)                              \
  X(DN_FEAT_DISPLACEMENT, "displacement", x, DN_FPARAM_NONE)                              \
  X(DN_FEAT_VOLTAGE, "voltage", u, DN_FPARAM_NONE)                                        \
  X(DN_FEAT_CURRENT, "current", u, DN_FPARAM_NONE)                                        \
  X(DN_FEAT_VOLTAGE_LAG, "voltage_lag", u_lag, DN_FPARAM_CONTROL_LAG_TAU_S)               \
  X(DN_FEAT_CURRENT_LAG, "current_lag", u_lag, DN_FPARAM_CONTROL_LAG_TAU_S)               \
  X(DN_FEAT_TEMPERATURE, "temperature", temperature, DN_FPARAM_NONE)                      \
  X(DN_FEAT_VELOCITY_LAG, "velocity_lag", v_lag, DN_FPARAM_VELOCITY_LAG_TAU_S)            \
  X(DN_FEAT_FRICTION_STATE, "friction_state", z_fric, DN_FPARAM_FRICTION_PRESLIDING_M)

/* How a damper state moves: X(id, value, "name", meaning). A host steps the state over an
 * interval of T seconds from a start where the source was src0 to now (src), holding it for
 * DN_DYN_LAG_HELD; cpp/include/dampnet/damper_state.hpp has the formulas. */
#define DN_STATE_DYNAMICS_LIST(X)                                                                \
  X(DN_DYN_LAG_HELD, 0, "lag_held",                                                              \
    "first-order lag of a source held over each step (the control): s = src0 + (s0 - src0) "    \
    "exp(-T/tau); ds/dt = (src - s) / tau; without its parameter s = src")                     \
  X(DN_DYN_LAG_RAMP, 1, "lag_ramp",                                                              \
    "first-order lag of a source moving as a ramp over each step (a motion quantity), exact: "  \
    "s = A s0 + (1 - A) src0 + (src - src0) (1 - tau (1 - A) / T), A = exp(-T/tau); "          \
    "ds/dt = (src - s) / tau; without its parameter s = src")                                  \
  X(DN_DYN_DAHL, 2, "dahl",                                                                      \
    "Dahl state along the source's travel dx = src - src0 (the step's net travel): s = sg + "   \
    "(s0 - sg) exp(-|dx| / x_c), sg = sgn(dx); ds/dt = (v - |v| s) / x_c; without its "         \
    "parameter s stays")

/* The damper's own states: X(id, name, unit, dynamics, source, parameter, meaning). Each
 * state fills the dn_damper_input field of its name; its source (x, v or u: what every host
 * knows over a step) and parameter (dn_feature_param: a time constant or a length) drive its
 * dynamics; a state whose parameter the model does not set follows its dynamics' default
 * (a lag: its source). The damper owns the update (Damper::span, advance, fill, rest, rates in
 * damper_state.hpp); a host only keeps the block of DN_DAMPER_STATE_SIZE values. */
#define DN_DAMPER_STATE_LIST(X)                                                                 \
  X(DN_DS_U_LAG, u_lag, "V", DN_DYN_LAG_HELD, u, DN_FPARAM_CONTROL_LAG_TAU_S,              \
    "control after the control lag (voltage_lag / current_lag; the model's control unit)")                                \
  X(DN_DS_V_LAG, v_lag, "m/s", DN_DYN_LAG_RAMP, v, DN_FPARAM_VELOCITY_LAG_TAU_S,                \
    "relative velocity after the velocity_lag feature's lag")                                   \
  X(DN_DS_Z_FRIC, z_fric, "-", DN_DYN_DAHL, x, DN_FPARAM_FRICTION_PRESLIDING_M,                 \
    "Dahl friction state of the friction_state feature, in [-1, 1]")

/* Physics terms added to any damper model's force (hybrid = neural + terms):
 * X(id, value, "kind" (MlpModel.terms[i]["kind"]), number of params, formula).
 * Each term's force is positive when it resists extension, like the damper's.
 * The same formulas in numpy: python/dampnet/terms.py. To add a kind add one
 * line here and its force/validation in cpp/include/dampnet/terms.hpp. */
#define DN_TERM_LIST(X)                                                                  \
  X(DN_TERM_POSITION_POLY, 0, "position_poly", 4,                                        \
    "F = p0 + p1 x + p2 x^2 + p3 x^3 (p in N, N/m, N/m^2, N/m^3); gas charge: p0 < 0")   \
  X(DN_TERM_BUMP_STOP, 1, "bump_stop", 3,                                                \
    "F = sgn(x) k (|x| - x_free)^n for |x| > x_free, else 0 (params x_free [m] >= 0, "   \
    "k [N/m^n] >= 0, n > 0)")                                                              \
  X(DN_TERM_VALVE, 2, "valve", 10,                                                       \
    "bleed orifice and preloaded blow-off valve, per direction: F = sgn(v) s(u) g_d(|v|), " \
    "d = ext for v > 0, comp for v < 0; g_d(w) = c_b w^2 for w <= v_k, else c_b v_k^2 + "  \
    "c_v z + (2 c_b v_k - c_v) v_k (1 - exp(-z / v_k)), z = ln(1 + k_d (w - v_k)) / k_d "  \
    "(w - v_k at k_d = 0: a straight blow-off line; k_d > 0 digressive, slope c_v / (1 + " \
    "k_d (w - v_k))): C1 at the knee v_k; s(u) = (1 + g_num u) / (1 + g_den u) with u "    \
    "clamped to [0, DN_TERM_VALVE_U_MAX]; |v| clamped to DN_TERM_VALVE_V_MAX_M_S; NaN v "   \
    "gives 0, NaN u is u = 0 (params v_k_ext [m/s] > 0, c_b_ext [N s^2/m^2] >= 0, c_v_ext " \
    "[N s/m] >= 0, v_k_comp [m/s] > 0, c_b_comp [N s^2/m^2] >= 0, c_v_comp [N s/m] >= 0, " \
    "g_num [1/u] >= 0, g_den [1/u] >= 0, 0 <= k_d_ext [s/m] <= 1e6, 0 <= k_d_comp [s/m] "  \
    "<= 1e6; 8 params: k_d_ext = k_d_comp = 0, a valve written before the digression)")

/* The valve term's bounds: |v| beyond the plausible damper speed and a control beyond
 * DN_TERM_VALVE_U_MAX [V or A] are clamped, so its force is finite for any input; its
 * digressions k_d [s/m] are validated within [0, DN_TERM_VALVE_K_D_MAX_S_M] (so k_d (|v| - v_k)
 * stays finite in float). */
#define DN_TERM_VALVE_V_MAX_M_S 50.0
#define DN_TERM_VALVE_U_MAX 1000.0
#define DN_TERM_VALVE_K_D_MAX_S_M 1e6

/* Damper model kinds. */
#define DN_DAMPER_KIND_LIST(X)                                                                \
  X(DN_DAMPER_LINEAR, 0, "linear", "F = c v")                                                 \
  X(DN_DAMPER_PARAMETRIC, 1, "parametric", "the thesis's eq. 1-3 (dn_parametric_params)")     \
  X(DN_DAMPER_TABLE, 2, "table", "force against velocity for a set of controls, bilinear")    \
  X(DN_DAMPER_NEURAL, 3, "neural", "the MLP on named features")                               \
  X(DN_DAMPER_CALLBACK, 4, "callback",                                                        \
    "a user function (slow path; e.g. a truth model or a real damper)")

/* Precision of a neural damper's MLP evaluation (the loop's state is dn_real). */
#define DN_PRECISION_LIST(X)                                          \
  X(DN_PRECISION_DOUBLE, 0, "double", "double-precision kernel")     \
  X(DN_PRECISION_FLOAT, 1, "float", "single-precision kernel")

/*---- Controllers ----*/

/* Control laws. v = dz_s - dz_us (extension rate), v_s, v_us the absolute
 * velocities. A "damping demand" d in [0, 1] maps to u = u_soft + d (u_hard - u_soft),
 * u_soft/u_hard being the controls of the least/most damping (for the thesis's
 * damper V = 0 is the hardest). The result is clamped to [u_min, u_max].
 *   PASSIVE:             u = u_passive
 *   SKYHOOK_ONOFF:       d = 1 if v_s v > 0 else 0
 *   SKYHOOK_CONTINUOUS:  if v_s v > 0: d = clamp((c_sky v_s / v - c_min) / (c_max - c_min), 0, 1)
 *                        else d = 0
 *   GROUNDHOOK_ONOFF:    d = 1 if -v_us v > 0 else 0
 *   GROUNDHOOK_CONTINUOUS: if -v_us v > 0: d = clamp((-c_gnd v_us / v - c_min) / (c_max - c_min), 0, 1)
 *                        else d = 0
 *   EXTERNAL:            u = dn_loop_input.u (the caller's controller)
 * Force-tracking laws demand a damper force F_d [N] (positive resisting extension, as the
 * damper's force) and command the control the damper's inverse gives for f_static + F_d at the
 * step start's damper input (dn_damper_inverse: the nearest achievable force when F_d is not).
 * A damper can only dissipate: F_d is 0 unless F_d v > 0, and F_d = 0 commands u_soft, the least
 * damping (not the control whose force is nearest 0 N: a damper whose force lags its velocity
 * has none near a reversal, and the hard setting there would push the body).
 *   SKYHOOK_FORCE:       F_d = c_sky v_s
 *   GROUNDHOOK_FORCE:    F_d = -c_gnd v_us
 *   HYBRID_FORCE:        F_d = alpha (c_sky v_s, if v_s v > 0) + (1 - alpha) (-c_gnd v_us, if -v_us v > 0)
 *   CLIPPED_OPTIMAL:     F_d = k_travel (z_s - z_us) + k_vs v_s + k_tyre (z_us - z_r) + k_vus v_us
 *                        (an LQR state feedback, clipped to the dissipative; Dyke et al. 1996)
 * A damper without a control (dn_damper_control_range: DN_E_MISMATCH) is refused with them.
 * Command filter (every law but EXTERNAL): with u_tau_s > 0 the law's control passes a
 * first-order low-pass before it reaches the damper, sampled at the step start and held
 * over the step: u_k = u_law + (u_{k-1} - u_law) exp(-dt / u_tau_s), u_{k-1} being the
 * state u_cmd. It stands for the command smoothing of a real semi-active controller (a
 * switching law's jumps in damper force jolt the body: "jerk"); 0 = unfiltered. */
#define DN_CONTROLLER_KIND_LIST(X)                                                              \
  X(DN_CTRL_PASSIVE, 0, "passive", "u = u_passive")                                             \
  X(DN_CTRL_SKYHOOK_ONOFF, 1, "skyhook_onoff", "on-off skyhook: d = 1 if v_s v > 0 else 0")     \
  X(DN_CTRL_SKYHOOK_CONTINUOUS, 2, "skyhook_continuous",                                        \
    "continuous skyhook: d = clamp((c_sky v_s / v - c_min) / (c_max - c_min), 0, 1) if v_s v > 0") \
  X(DN_CTRL_GROUNDHOOK_ONOFF, 3, "groundhook_onoff",                                            \
    "on-off groundhook: d = 1 if -v_us v > 0 else 0")                                           \
  X(DN_CTRL_GROUNDHOOK_CONTINUOUS, 4, "groundhook_continuous",                                  \
    "continuous groundhook: d = clamp((-c_gnd v_us / v - c_min) / (c_max - c_min), 0, 1) if "   \
    "-v_us v > 0")                                                                              \
  X(DN_CTRL_EXTERNAL, 5, "external", "u = dn_loop_input.u (the caller's controller)")           \
  X(DN_CTRL_SKYHOOK_FORCE, 6, "skyhook_force",                                                  \
    "skyhook as a force through the inverse: F_d = c_sky v_s if v_s v > 0 else 0")              \
  X(DN_CTRL_GROUNDHOOK_FORCE, 7, "groundhook_force",                                            \
    "groundhook as a force through the inverse: F_d = -c_gnd v_us if -v_us v > 0 else 0")       \
  X(DN_CTRL_HYBRID_FORCE, 8, "hybrid_force",                                                    \
    "hybrid through the inverse: F_d = alpha (skyhook_force's) + (1 - alpha) (groundhook_force's)") \
  X(DN_CTRL_CLIPPED_OPTIMAL, 9, "clipped_optimal",                                              \
    "clipped-optimal through the inverse: F_d = k_travel (z_s - z_us) + k_vs v_s + k_tyre (z_us - z_r) " \
    "+ k_vus v_us if F_d v > 0 else 0")

/* Controller parameters: X(type, name, default, doc). */
#define DN_CONTROLLER_FIELDS(X)                                                     \
  X(int, kind, DN_CTRL_PASSIVE, "dn_controller_kind")                               \
  X(dn_real, u_passive, 0.0, "control of the passive law [V]")                       \
  X(dn_real, u_soft, 5.0, "control giving the least damping [V]")                    \
  X(dn_real, u_hard, 0.0, "control giving the most damping [V]")                     \
  X(dn_real, u_min, 0.0, "lower control limit [V], <= u_max")                                  \
  X(dn_real, u_max, 5.0, "upper control limit [V], >= u_min")                                  \
  X(dn_real, c_sky, 2500.0, "skyhook damping [N s/m], >= 0")                         \
  X(dn_real, c_gnd, 2500.0, "groundhook damping [N s/m], >= 0")                      \
  X(dn_real, c_min, 500.0, "damping at u_soft [N s/m] (continuous laws: < c_max)")            \
  X(dn_real, c_max, 4000.0, "damping at u_hard [N s/m] (continuous laws), > c_min")           \
  X(dn_real, u_tau_s, 0.0, "command filter time constant [s], >= 0; 0 = none (not EXTERNAL)") \
  X(dn_real, alpha, 0.5, "hybrid_force's skyhook share [-], in [0, 1]")                     \
  X(dn_real, k_travel, 0.0, "clipped_optimal's gain on the travel z_s - z_us [N/m]")         \
  X(dn_real, k_vs, 0.0, "clipped_optimal's gain on the body velocity v_s [N s/m]")           \
  X(dn_real, k_tyre, 0.0, "clipped_optimal's gain on the tyre deflection z_us - z_r [N/m]")  \
  X(dn_real, k_vus, 0.0, "clipped_optimal's gain on the wheel velocity v_us [N s/m]")

/*---- The quarter-car loop ----*/

/* Integrators. */
#define DN_INTEGRATOR_LIST(X)                                                     \
  X(DN_INT_RK4, 0, "rk4", "classical 4th-order Runge-Kutta")                      \
  X(DN_INT_SEMI_EULER, 1, "semi_euler",                                           \
    "semi-implicit (symplectic) Euler: v first, then z with the new v")

/* When the damper is evaluated within an RK4 step. */
#define DN_DAMPER_EVAL_LIST(X)                                                          \
  X(DN_EVAL_PER_STAGE, 0, "per_stage",                                                  \
    "at each of the 4 stages (4th order; 4 evaluations per step)")                      \
  X(DN_EVAL_PER_STEP, 1, "per_step",                                                    \
    "once at the step start, force held over the step (1 evaluation; 1st order)")

/* How the loop computes the acceleration feature a (the relative acceleration
 * z_s'' - z_us'') of a neural damper that uses "acceleration". a and the force
 * are coupled: a = a_free - k (F(a) - f_static), k = 1/m_s + 1/m_us, a_free the
 * relative acceleration with the damper carrying f_static.
 * IMPLICIT solves g(a) = a - a_free + k (F(a) - f_static) = 0 at every damper
 * evaluation (each RK4 stage, or the step start): safeguarded Newton starting
 * from the explicit value with the MLP's analytic slope dF/da (forward-mode;
 * 0 where a is outside the MLP's saturation range), bisection once a sign
 * change is bracketed and a step leaves it, at
 * most DN_ACCEL_MAX_EVALS damper evaluations; converged when
 * |g| <= 1e-7 (1 + |a_free|) + k eps (1 + |F|) [m/s^2] (eps = 1e-12 for a
 * double MLP, 1e-5 float). Not converged: the iterate with the smallest |g|
 * (never worse than the explicit value, which is the first iterate) and
 * DN_W_ACCEL_UNCONVERGED. Stable for any dF/da >= 0.
 * LINEAR (linearly implicit, as in Rosenbrock methods): one evaluation with the
 * slope, one Newton step a1 = a0 - g(a0) / g'(a0) from the explicit value a0,
 * and the force linearised there, F0 + dF/da (a1 - a0); no second evaluation.
 * Exact for a force linear in a; otherwise its error is second order in the
 * Newton step. The step changes the force by -dF/da g(a0) / g'(a0), and
 * |g(a0)| / k = |F0 - f_last|: with g' = 1 + k dF/da >= DN_ACCEL_LINEAR_MIN_SLOPE
 * (1/2) that change is at most |F0 - f_last| (the force change since the last
 * evaluation). Stability region: dF/da >= -1 / (2 k), i.e. a negative apparent
 * mass at most half the reduced mass 1/k = m_s m_us / (m_s + m_us), including
 * every dF/da >= 0. Outside it (g' < 1/2, or g' <= 0 where the coupling has no
 * unique solution) the correction grows as 1/g' without bound, so the step is
 * not taken: the evaluation's own force F0 at the explicit acceleration a0 is
 * used (the explicit scheme for that evaluation, bounded by the model's output
 * range) and DN_W_ACCEL_FALLBACK is reported. One evaluation either way: the
 * real-time choice.
 * EXPLICIT uses the force of the most recent evaluation (f_last): one
 * evaluation, no iteration, stable only while |dF/da| k < 1.
 * Dampers whose force does not read a (all but neural-with-acceleration) and
 * callback dampers (possibly stateful: never re-evaluated) always use EXPLICIT. */
#define DN_ACCEL_FEATURE_LIST(X)                                                      \
  X(DN_ACCEL_IMPLICIT, 0, "implicit", "solve the coupling per evaluation (default)")  \
  X(DN_ACCEL_EXPLICIT, 1, "explicit", "a from f_last: one evaluation, no iteration")  \
  X(DN_ACCEL_LINEAR, 2, "linear", "one evaluation with its slope, one linearised Newton step")

/* The step's stability limit: dt w_hop <= DN_STABLE_WDT_RK4 (DN_INT_RK4) or
 * DN_STABLE_WDT_SEMI_EULER (DN_INT_SEMI_EULER), w_hop = sqrt(k_s / m_s + (k_s + k_t) / m_us)
 * [rad/s] (a bound on the wheel-hop mode's frequency; the full car: sqrt((k_s + 2 k_arb + k_t) /
 * m_us) of its stiffer axle, RK4). Measured on the Table 5 car (w_hop 73.5 rad/s: dt <= 20 ms
 * RK4, 13.6 ms semi-implicit Euler) with linear dampers up to 3 kN s/m: stable; beyond these
 * the step runs away. A stronger damper lowers the limit further (RK4 diverges at 6 kN s/m and
 * dt = 13.6 ms): such a run stops with DN_E_DIVERGED (DN_PLAUSIBLE_LIST). */
#define DN_STABLE_WDT_RK4 1.5
#define DN_STABLE_WDT_SEMI_EULER 1.0
#define DN_DOC_STR_(x) #x
#define DN_DOC_XSTR_(x) DN_DOC_STR_(x)

/* Vehicle and loop parameters (thesis Table 5 defaults): X(type, name, default, doc).
 * Equations (z from static equilibrium, up positive; F_a = F - f_static):
 *   m_s  z_s''  = -k_s (z_s - z_us) - F_a
 *   m_us z_us'' =  k_s (z_s - z_us) + F_a - k_t (z_us - z_r) - c_t (z_us' - z_r') */
#define DN_VEHICLE_FIELDS(X)                                                               \
  X(dn_real, m_s, 700.0, "sprung mass [kg], > 0")                                           \
  X(dn_real, m_us, 40.0, "unsprung mass [kg], > 0")                                         \
  X(dn_real, k_s, 15000.0, "suspension spring stiffness [N/m], >= 0")                       \
  X(dn_real, k_t, 200000.0, "tyre stiffness [N/m], > 0")                                    \
  X(dn_real, c_t, 0.0, "tyre damping [N s/m], >= 0")                                        \
  X(dn_real, dt, 0.001,                                                                    \
    "step [s], 1e-9 <= dt <= 0.1; stable: dt w_hop <= " DN_DOC_XSTR_(DN_STABLE_WDT_RK4) " with rk4 " \
    "and " DN_DOC_XSTR_(DN_STABLE_WDT_SEMI_EULER) " with semi_euler, w_hop^2 = k_s/m_s + "          \
    "k_s/m_us + k_t/m_us: 20 ms with rk4 for Table 5")                                       \
  X(int, integrator, DN_INT_RK4, "dn_integrator")                                          \
  X(int, damper_eval, DN_EVAL_DEFAULT, "dn_damper_eval (RK4 only)")                      \
  X(dn_real, x_static, 0.0, "damper displacement at static equilibrium, from mid [m]")      \
  X(dn_real, f_static, 0.0, "damper force carried at static equilibrium [N] (e.g. gas)")    \
  X(dn_real, temperature, 20.0, "damper temperature at reset [degC]")                       \
  X(int, accel_feature, DN_ACCEL_DEFAULT, "dn_accel_feature (neural dampers reading a)")

/* Physical plausibility, X(name, value, doc): a step whose new state leaves any of these fails
 * with DN_E_DIVERGED and is not taken, like a step that overflows. They lie far beyond any road
 * vehicle (long-travel off-road suspensions move about 0.9 m; a body rolled 57 degrees has
 * overturned), so only a runaway reaches them: a damper that feeds energy in (a negative-slope
 * table, a callback), a step beyond the stability limit, a road far beyond ISO 8608 class H's at
 * speed. The quarter car and the full car check them at every step (and the Python reference
 * loop, dampnet.sim.quarter_car.reference_loop). */
#define DN_PLAUSIBLE_TRAVEL_M 2.0
#define DN_PLAUSIBLE_WHEEL_ROAD_M 5.0
#define DN_PLAUSIBLE_DAMPER_SPEED_M_S 50.0
#define DN_PLAUSIBLE_ANGLE_RAD 1.0
#define DN_PLAUSIBLE_LIST(X)                                                                    \
  X(DN_PLAUSIBLE_TRAVEL_M, "suspension travel from static equilibrium |z_s - z_us| [m]")        \
  X(DN_PLAUSIBLE_WHEEL_ROAD_M,                                                                  \
    "wheel to road |z_us - z_r| [m]: tyre compression, or the wheel's height in the air")       \
  X(DN_PLAUSIBLE_DAMPER_SPEED_M_S, "damper velocity |v_s - v_us| [m/s]")                        \
  X(DN_PLAUSIBLE_ANGLE_RAD, "full car: body roll |phi| and pitch |theta| [rad]")

/* The loop's state, a flat array of dn_real: the loop's own X(index, name, doc), then the
 * damper's state block (DN_DAMPER_STATE_LIST) at DN_LOOP_DAMPER_BASE + its id. */
#define DN_LOOP_STATE_LIST(X)                                                         \
  X(0, t, "time [s]")                                                                 \
  X(1, z_s, "sprung-mass displacement from static equilibrium [m]")                   \
  X(2, v_s, "sprung-mass velocity [m/s]")                                             \
  X(3, z_us, "unsprung-mass displacement from static equilibrium [m]")                \
  X(4, v_us, "unsprung-mass velocity [m/s]")                                          \
  X(5, z_r, "road displacement at t [m]")                                             \
  X(6, v_r, "road rate at t [m/s]")                                                   \
  X(7, f_last, "force of the most recent damper evaluation [N] (acceleration start value)") \
  X(8, temperature, "damper temperature [degC]")                                      \
  X(9, u_cmd, "control applied over the last step, after the command filter [V]")
#define DN_LOOP_DAMPER_BASE 10
#define DN_LOOP_STATE_SIZE (DN_LOOP_DAMPER_BASE + DN_DAMPER_STATE_SIZE)

/* What a step reports, all at the step's START time t (before advancing): its scalar
 * quantities X(name, doc), in struct order, then the neural inputs. (Python's step report
 * and Loop.simulate's arrays are generated from this list.) */
#define DN_LOOP_OUT_LIST(X)                                                               \
  X(force, "damper force of the first evaluation [N] (model plus terms)")                 \
  X(u, "control applied over the step (after limits) [V]")                               \
  X(x, "damper displacement [m]")                                                          \
  X(v, "damper velocity [m/s]")                                                            \
  X(a, "relative acceleration fed to the damper (the acceleration feature) [m/s^2]")      \
  X(acc_s, "sprung-mass acceleration with this force [m/s^2]")                             \
  X(acc_us, "unsprung-mass acceleration with this force [m/s^2]")

/*---- The full vehicle ----*/
#if !DN_LOOP_FLOAT /* the full vehicle is built with double only (DN_LOOP_FLOAT: dn_config.h) */
#define DN_TYRE_MODEL_LIST(X)                                                               \
  X(DN_TYRE_MAGIC_FORMULA, 0, "magic_formula",                                              \
    "Fy = D sin(C atan(B alpha - E (B alpha - atan(B alpha)))), D and B from the load")     \
  X(DN_TYRE_LINEAR, 1, "linear", "Fy = K(N0) alpha: the static load's cornering stiffness")
#define DN_STEER_MODE_LIST(X)                                                           \
  X(DN_STEER_OPEN_LOOP, 0, "open_loop", "road-wheel angle from dn_fullcar_input.steer")  \
  X(DN_STEER_DRIVER, 1, "driver", "preview driver following the model's path")
/* Full-vehicle parameters: X(type, name, default, doc). Defaults: a compact-pickup-class
 * vehicle whose front corner is the thesis's Table 5 quarter car (700 kg sprung, 40 kg
 * unsprung, 15 kN/m, 200 kN/m); sources of the other figures in docs/full-vehicle.md. */
#define DN_FULLCAR_FIELDS(X)                                                                   \
  X(double, m_s, 2600.0, "sprung mass [kg], > 0")                                              \
  X(double, i_xx, 900.0, "sprung-mass roll inertia about the roll axis [kg m^2], > 0")          \
  X(double, i_yy, 3900.0, "sprung-mass pitch inertia [kg m^2], > 0")                           \
  X(double, i_zz, 4800.0, "vehicle yaw inertia [kg m^2], > 0")                                 \
  X(double, a, 1.5, "sprung-mass CG to front axle [m], > 0")                                   \
  X(double, b, 1.75, "sprung-mass CG to rear axle [m], > 0")                                   \
  X(double, t_f, 1.6, "front track [m], > 0")                                                  \
  X(double, t_r, 1.6, "rear track [m], > 0")                                                   \
  X(double, h_cg, 0.75, "sprung-mass CG height above the road [m], > 0")                      \
  X(double, h_rc_f, 0.10, "front roll-centre height [m], 0 <= h_rc_f < h_cg")                 \
  X(double, h_rc_r, 0.35, "rear roll-centre height [m], 0 <= h_rc_r < h_cg")                  \
  X(double, m_us_f, 40.0, "front unsprung mass per wheel [kg], > 0")                           \
  X(double, m_us_r, 40.0, "rear unsprung mass per wheel [kg], > 0")                            \
  X(double, k_s_f, 15000.0, "front spring rate at the wheel [N/m], >= 0")                      \
  X(double, k_s_r, 15000.0, "rear spring rate at the wheel [N/m], >= 0")                       \
  X(double, k_arb_f, 40000.0,                                                                  \
    "front anti-roll bar rate at the wheel [N/m] (per metre of left-right deflection "          \
    "difference), >= 0")                                                                       \
  X(double, k_arb_r, 15000.0, "rear anti-roll bar rate at the wheel [N/m], >= 0")               \
  X(double, k_t, 200000.0, "tyre vertical stiffness [N/m], > 0")                               \
  X(double, c_t, 0.0, "tyre vertical damping [N s/m], >= 0")                                   \
  X(int, tyre_model, DN_TYRE_MAGIC_FORMULA, "dn_tyre_model")                                   \
  X(double, tyre_fz0, 7000.0, "tyre nominal load Fz0 [N], > 0")                                \
  X(double, tyre_pky1, 18.0,                                                                   \
    "cornering stiffness factor: K = pky1 Fz0 sin(2 atan(N / (pky2 Fz0))) [1/rad], > 0")      \
  X(double, tyre_pky2, 2.0, "load of peak cornering stiffness / Fz0 [-], > 0")                 \
  X(double, tyre_mu0, 0.95, "peak friction at Fz0 [-], > 0")                                   \
  X(double, tyre_pdy2, -0.1,                                                                   \
    "friction load sensitivity: mu = mu0 (1 + pdy2 (N - Fz0) / Fz0) [-], -1 < pdy2 < 1")       \
  X(double, tyre_c, 1.3, "Magic-Formula shape factor C [-], 1 < C <= 2")                       \
  X(double, tyre_e, -0.5, "Magic-Formula curvature factor E [-], -10 <= E <= 1")               \
  X(double, speed, 33.333333333333336,                                                         \
    "forward speed [m/s], 0 <= speed <= 100 (0: lateral dynamics frozen)")                     \
  X(double, g, 9.81, "gravity [m/s^2], >= 0")                                                  \
  X(int, steer_mode, DN_STEER_OPEN_LOOP, "dn_steer_mode")                                      \
  X(double, steer_max, 0.5, "road-wheel angle limit [rad], > 0")                               \
  X(double, driver_preview_s, 0.5, "driver preview time T [s], > 0")                           \
  X(double, driver_preview_min_m, 5.0, "driver shortest preview distance [m], > 0")            \
  X(double, driver_gain, 1.0,                                                                  \
    "driver gain on the optimal-preview command [-], > 0 (1: the preview point reached)")      \
  X(double, driver_tau_s, 0.05, "steering lag time constant [s], >= 0 (0: none)")              \
  X(double, driver_rate_max, 1.0,                                                              \
    "driver's road-wheel steering rate limit [rad/s], > 0 (1 rad/s: ~1000 deg/s at the "       \
    "steering wheel with a 17:1 ratio)")                                                       \
  X(double, dt, 0.001,                                                                         \
    "step [s], 1e-9 <= dt <= 0.1; stable: dt w_hop <= " DN_DOC_XSTR_(DN_STABLE_WDT_RK4) " with "     \
    "w_hop^2 = k/m_us of the stiffer axle, k = k_s + 2 k_arb + k_t: 17.5 ms for the defaults")  \
  X(int, damper_eval, DN_EVAL_PER_STAGE, "dn_damper_eval")                                     \
  X(int, accel_feature, DN_ACCEL_LINEAR, "dn_accel_feature (neural dampers reading a)")        \
  X(double, x_static_f, 0.0, "front damper displacement at static equilibrium [m]")            \
  X(double, x_static_r, 0.0, "rear damper displacement at static equilibrium [m]")             \
  X(double, f_static_f, 0.0, "front damper force at static equilibrium [N]")                   \
  X(double, f_static_r, 0.0, "rear damper force at static equilibrium [N]")                    \
  X(double, temperature, 20.0, "damper temperature at reset [degC]")
/* The state, a flat array of doubles: the vehicle's X(index, name, doc), then per corner
 * i = 0..3 the corner's X(offset, name, doc) and its damper's state block at DN_FULLCAR_CORNER_BASE + i *
 * DN_FULLCAR_CORNER_SIZE + offset (Python names: name + "_fl" / "_fr" / "_rl" / "_rr"). */
#define DN_FULLCAR_STATE_LIST(X)                                                    \
  X(0, t, "time [s]")                                                               \
  X(1, z, "body heave at the CG, from static equilibrium [m]")                      \
  X(2, vz, "body heave velocity [m/s]")                                             \
  X(3, phi, "body roll angle, left side up positive [rad]")                         \
  X(4, p, "roll rate [rad/s]")                                                      \
  X(5, theta, "body pitch angle, nose down positive [rad]")                         \
  X(6, q, "pitch rate [rad/s]")                                                     \
  X(7, vy, "lateral velocity of the CG, body frame, left positive [m/s]")           \
  X(8, r, "yaw rate, left positive [rad/s]")                                        \
  X(9, psi, "yaw angle [rad]")                                                      \
  X(10, x_pos, "CG position X along the initial heading [m]")                             \
  X(11, y_pos, "CG position Y, left of the initial heading [m]")                          \
  X(12, steer, "road-wheel angle applied over the last step (after the lag) [rad]")
#define DN_FULLCAR_CORNER_BASE 13
#define DN_FULLCAR_CORNER_STATE_LIST(X)                                                  \
  X(0, z_us, "wheel displacement from static equilibrium [m]")                           \
  X(1, v_us, "wheel velocity [m/s]")                                                     \
  X(2, z_r, "road under the wheel at t [m]")                                             \
  X(3, v_r, "road rate under the wheel at t [m/s]")                                      \
  X(4, f_last, "force of the most recent damper evaluation [N]")                         \
  X(5, u_cmd, "control applied over the last step, after the command filter [V]")        \
  X(6, temperature, "damper temperature [degC]")
/* then the corner's damper state block (DN_DAMPER_STATE_LIST) at offset DN_FULLCAR_CORNER_DAMPER */
#define DN_FULLCAR_CORNER_DAMPER 7
#define DN_FULLCAR_CORNER_SIZE (DN_FULLCAR_CORNER_DAMPER + DN_DAMPER_STATE_SIZE)
#define DN_FULLCAR_STATE_SIZE (DN_FULLCAR_CORNER_BASE + DN_FULLCAR_CORNERS * DN_FULLCAR_CORNER_SIZE)
/* What a step reports, at the step's START time: per-corner quantities X(name, doc)
 * (arrays of DN_FULLCAR_CORNERS) and vehicle quantities X(name, doc). */
#define DN_FULLCAR_OUT_CORNER_LIST(X)                                                  \
  X(force, "damper force of the first evaluation [N]")                                  \
  X(u, "control applied over the step [V]")                                             \
  X(x, "damper displacement [m]")                                                       \
  X(v, "damper velocity [m/s]")                                                         \
  X(a, "relative acceleration fed to the damper [m/s^2]")                               \
  X(acc_s, "body vertical acceleration above the wheel [m/s^2]")                        \
  X(acc_us, "wheel vertical acceleration [m/s^2]")                                      \
  X(tyre_load, "tyre vertical load, static included, >= 0 [N]")                         \
  X(tyre_fy, "tyre lateral force, left positive [N]")
#define DN_FULLCAR_OUT_LIST(X)                                                          \
  X(acc_z, "body heave acceleration at the CG [m/s^2]")                                 \
  X(acc_phi, "roll acceleration [rad/s^2]")                                             \
  X(acc_theta, "pitch acceleration [rad/s^2]")                                          \
  X(a_y, "lateral acceleration of the CG, left positive [m/s^2]")                       \
  X(steer, "road-wheel angle applied over the step [rad]")                              \
  X(slip_f, "front axle slip angle [rad]")                                              \
  X(slip_r, "rear axle slip angle [rad]")                                               \
  X(beta, "side-slip angle of the CG, atan(vy / speed) [rad]")
#endif /* !DN_LOOP_FLOAT */

#endif /* DAMPNET_DN_XMACRO_H */
