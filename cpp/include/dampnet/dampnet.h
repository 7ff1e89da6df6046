/* dampnet C ABI: neural damper models for real-time use.
 *
 * One header, C99 and C++. Every symbol is prefixed dn_ / DN_. Functions
 * return an int status: DN_OK (0) on success, a positive warning (a bit set
 * of DN_W_* flags) when the call succeeded but clamped an input, or a
 * negative DN_E_* error. dn_status_str() explains any of them.
 *
 * Real-time contract: functions marked [RT] do no allocation, locking, I/O
 * or exception throwing, run in bounded time, and return finite outputs for
 * any input (see "Non-finite and out-of-range inputs" below). Functions that
 * create objects allocate and belong in set-up code.
 *
 * Units: every physical quantity is SI (m, m/s, m/s^2, N, V, A, s, degC for
 * temperature) unless a comment states otherwise.
 *
 * Threading contract:
 *  - Models (dn_mlp, dn_damper once handed to a loop model, dn_loop_model) are
 *    immutable after creation (dn_damper_add_term is set-up, before any use) and
 *    may be shared by any number of threads calling the const functions on them
 *    (dn_mlp_forward[_f], dn_damper_force, dn_loop_step/forward with distinct data).
 *  - Anything with state is single-thread: one dn_loop_data per thread (or guarded
 *    by the caller). Two threads stepping the same dn_loop_data race and give
 *    wrong results without an error; the C ABI does not detect it.
 *  - A callback damper is as thread-safe as its user function (dn_damper_fn and
 *    its user pointer): with a stateful callback, one loop model per thread.
 *  - Create/destroy functions allocate and free: never destroy an object while
 *    another thread uses it.
 */
#ifndef DAMPNET_H
#define DAMPNET_H

#include <stddef.h>
#include <stdint.h>

#include "dampnet/dn_config.h"
#include "dampnet/dn_types.h"
#include "dampnet/dn_xmacro.h"

#if defined(DN_STATIC)
#define DN_API
#elif defined(_WIN32)
#if defined(DN_BUILDING_LIBRARY)
#define DN_API __declspec(dllexport)
#else
#define DN_API __declspec(dllimport)
#endif
#else
#define DN_API __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
extern "C" {
#endif

/*---- Version ----*/

#define DN_VERSION_MAJOR 0
#define DN_VERSION_MINOR 7 /* 0.7: force-tracking control laws (DN_CTRL_SKYHOOK_FORCE ... DN_CTRL_CLIPPED_OPTIMAL; dn_controller.alpha, k_travel, k_vs, k_tyre, k_vus); 0.6: the full car's MacAdam driver (dn_fullcar_params.driver_rate_max, driver_preview_s 0.5 s); 0.5: the damper owns its state (DN_DAMPER_STATE_LIST; the loop and full-car states keep it as one block); 0.4: the full vehicle dn_fullcar_* (0.3: dn_controller.u_tau_s, 13 loop states; 0.2: dn_damper_input.v_lag/z_fric) */
#define DN_VERSION_PATCH 0
/* Version of this header as major*10000 + minor*100 + patch. */
#define DN_VERSION_HEADER (DN_VERSION_MAJOR * 10000 + DN_VERSION_MINOR * 100 + DN_VERSION_PATCH)

/* Version of the linked library as major*10000 + minor*100 + patch; compare with DN_VERSION_HEADER. */
DN_API int dn_version(void);

/* Version of the linked library as a string, e.g. "0.1.0". */
DN_API const char* dn_version_string(void);

/*---- Status codes ----*/

/* A human-readable explanation of a status (an OR of warnings is explained too). Never NULL. */
DN_API const char* dn_status_str(int status);

/*---- The MLP ----*/

/* Caller-provided storage (no heap): every object that dn_*_create allocates can instead be
 * placed in memory the caller owns by the matching dn_*_init, MuJoCo-arena style, e.g. static
 * arrays on a microcontroller. dn_*_size() is the number of bytes an object needs in this build
 * (it depends on the DN_CAP_* capacities, not on the model); the memory must be aligned to
 * dn_storage_align() (at most DN_STORAGE_ALIGN). init validates exactly as create does and
 * returns the same statuses, plus DN_E_SIZE when bytes < dn_*_size() and DN_E_PARAM when mem is
 * misaligned (*out = NULL on every error, the memory's content then unspecified). An object
 * from init is never passed to dn_*_destroy: it lives as long as its memory, which the caller
 * may reuse once no object using it is needed (a loop model copies its damper and a damper its
 * MLP, so their memory is free again after the copy). create is init on memory from the heap.
 * Set-up only: init is not [RT]. */
#define DN_STORAGE_ALIGN 64
/* The alignment every dn_*_init needs in this build (a power of two <= DN_STORAGE_ALIGN). */
DN_API size_t dn_storage_align(void);

/* Validate a description and create a model. Allocates; set-up only.
 * The model holds a float and a double copy with the scalings folded into the
 * weights: a description whose folded parameters overflow float (|x| > 3.4e38,
 * e.g. out_offset = 1e39 or out_gain = 1e-40) is refused with DN_E_PARAM.
 * return DN_OK and *out set, or a DN_E_* error with *out = NULL. */
DN_API int dn_mlp_create(const dn_mlp_desc* desc, dn_mlp** out);

/* Destroy a model. Nullable: m. */
DN_API void dn_mlp_destroy(dn_mlp* m);

/* Bytes of a dn_mlp, and dn_mlp_create in caller memory (see "Caller-provided storage"). */
DN_API size_t dn_mlp_size(void);
DN_API int dn_mlp_init(const dn_mlp_desc* desc, void* mem, size_t bytes, dn_mlp** out);

/* dn_mlp_init from a folded description (caller memory, see "Caller-provided storage"; no heap).
 * Validated in float: DN_E_NULL (a NULL array), DN_E_SIZE (sizes beyond DN_MAX_* or this build's
 * DN_CAP_*), DN_E_NONFINITE_PARAM (a NaN or infinite value), DN_E_PARAM (offsets_folded not 0/1,
 * sat_lo > sat_hi, sat_mid outside them). The double copy (DN_DOUBLE_KERNEL 1) holds the same
 * float values widened: dn_mlp_forward evaluates the float weights in double. Set-up only. */
DN_API int dn_mlp_init_folded(const dn_mlp_folded_f* folded, void* mem, size_t bytes, dn_mlp** out);

/* Number of inputs of a model, or DN_E_NULL. */
DN_API int dn_mlp_n_inputs(const dn_mlp* m);

/* [RT] Evaluate the double kernel on one sample.
 * x: [n_inputs] in input units; y: the output (force [N] for a damper model).
 * Non-finite and out-of-range inputs: a value below sat_lo or above sat_hi
 * (including -Inf and +Inf) is clamped to the limit (DN_W_SATURATED); NaN is
 * replaced by the centre of the saturation range (DN_W_NONFINITE_INPUT).
 * Bit i of *clamped_mask is set when input i was clamped or replaced.
 * The output is always finite. Nullable: clamped_mask. */
DN_API int dn_mlp_forward(const dn_mlp* m, const double* x, double* y, uint32_t* clamped_mask);

/* [RT] Evaluate the float kernel on one sample; as dn_mlp_forward. */
DN_API int dn_mlp_forward_f(const dn_mlp* m, const float* x, float* y, uint32_t* clamped_mask);

/*---- Training envelope: a bounded-time "is the model guessing here?" flag ----*/

/* Validate and copy a description: DN_E_NULL, DN_E_SIZE (n_inputs), DN_E_NONFINITE_PARAM
 * (lo, hi), DN_E_PARAM (hi < lo, or hi - lo beyond double). create allocates; init uses caller
 * memory. */
DN_API int dn_envelope_create(const dn_envelope_desc* desc, dn_envelope** out);
DN_API void dn_envelope_destroy(dn_envelope* e);
DN_API size_t dn_envelope_size(void);
DN_API int dn_envelope_init(const dn_envelope_desc* desc, void* mem, size_t bytes, dn_envelope** out);
DN_API int dn_envelope_n_inputs(const dn_envelope* e);

/* [RT] Where a point x [n_inputs] (the model's inputs before saturation, feature units: e.g. a
 * loop step's dn_loop_out.features) lies: *flags = 0 inside, else DN_ENV_OUTSIDE_* bits. A
 * bounded loop over the pairs (at most 28 word reads); any input, NaN and Inf included, gives a
 * defined result. Returns DN_OK or DN_E_NULL. */
DN_API int dn_envelope_check(const dn_envelope* e, const double* x, uint32_t* flags);
DN_API int dn_envelope_check_f(const dn_envelope* e, const float* x, uint32_t* flags);

/*---- Damper models ----*/

/* Create F = c v; c [N s/m] finite (else DN_E_NONFINITE_PARAM) and >= 0 (else DN_E_PARAM).
 * Allocates. */
DN_API int dn_damper_create_linear(double c, dn_damper** out);

/* Create the parametric model; params validated (DN_E_PARAM, DN_E_NONFINITE_PARAM). Allocates. */
DN_API int dn_damper_create_parametric(const dn_parametric_params* p, dn_damper** out);

/* Create a lookup table: velocities [n_v] (m/s, strictly increasing, 2..DN_MAX_TABLE_V),
 * controls [n_u] (V or A, strictly increasing, 1..DN_MAX_TABLE_U), forces [n_u][n_v] [N]
 * row-major. Evaluation is bilinear in (v, u); outside the grid v and u are clamped
 * to its edges (the force saturates; DN_W_SATURATED). Allocates. */
DN_API int dn_damper_create_table(const double* velocities, int n_v, const double* controls,
                                  int n_u, const double* forces, dn_damper** out);

/* Create a neural damper from an MLP (copied) and the names of its inputs in order
 * (DN_FEATURE_LIST); param_names/param_values give MlpModel.feature_params
 * (DN_FEATURE_PARAM_LIST). precision: dn_precision of the MLP evaluation.
 * Unknown feature or parameter name: DN_E_UNKNOWN_NAME; n_features != inputs of
 * the MLP: DN_E_MISMATCH; a derived feature without its parameter (voltage_lag /
 * current_lag: control_lag_tau_s, velocity_lag: velocity_lag_tau_s, friction_state:
 * friction_presliding_m), or any parameter <= 0: DN_E_PARAM.
 * Nullable: param_names and param_values when n_params == 0. Allocates. */
DN_API int dn_damper_create_neural(const dn_mlp* mlp, const char* const* features, int n_features,
                                   const char* const* param_names, const double* param_values,
                                   int n_params, int precision, dn_damper** out);

/* Create a damper that calls fn (see dn_damper_fn). Nullable: user. Allocates. */
DN_API int dn_damper_create_callback(dn_damper_fn fn, void* user, dn_damper** out);

/* Add a physics term (DN_TERM_LIST kind name) to a damper; set-up only.
 * Unknown kind: DN_E_UNKNOWN_NAME; wrong parameter count: DN_E_SIZE; more than
 * DN_MAX_TERMS: DN_E_SIZE; invalid values: DN_E_PARAM / DN_E_NONFINITE_PARAM. */
DN_API int dn_damper_add_term(dn_damper* d, const char* kind, const double* params, int n_params);

/* Destroy a damper. Nullable: d. */
DN_API void dn_damper_destroy(dn_damper* d);

/* Bytes of a dn_damper (any kind), and each dn_damper_create_* in caller memory (see
 * "Caller-provided storage"): the same arguments, then the memory. */
DN_API size_t dn_damper_size(void);
DN_API int dn_damper_init_linear(double c, void* mem, size_t bytes, dn_damper** out);
DN_API int dn_damper_init_parametric(const dn_parametric_params* p, void* mem, size_t bytes,
                                     dn_damper** out);
DN_API int dn_damper_init_table(const double* velocities, int n_v, const double* controls, int n_u,
                                const double* forces, void* mem, size_t bytes, dn_damper** out);
DN_API int dn_damper_init_neural(const dn_mlp* mlp, const char* const* features, int n_features,
                                 const char* const* param_names, const double* param_values,
                                 int n_params, int precision, void* mem, size_t bytes,
                                 dn_damper** out);
DN_API int dn_damper_init_callback(dn_damper_fn fn, void* user, void* mem, size_t bytes,
                                   dn_damper** out);

/* The dn_damper_kind of a damper, or DN_E_NULL. */
DN_API int dn_damper_kind_of(const dn_damper* d);

/* [RT] (except callback dampers) The force [N] of a damper (model plus terms) for one input.
 * A non-finite field of *in that the model uses: DN_E_NONFINITE_INPUT, *force = 0.
 * Warnings (OR-ed): DN_W_SATURATED (MLP input or table clamped),
 * DN_W_NONFINITE_INPUT. Nullable: clamped_mask (neural: bit i = input i clamped). */
DN_API int dn_damper_force(const dn_damper* d, const dn_damper_input* in, dn_real* force,
                           uint32_t* clamped_mask);

/* [RT] The sum of a damper's physics terms alone (DN_TERM_LIST; 0 without terms) at one input
 * [N], and its derivatives grad[3] = {dF/dx [N/m], dF/dv [N s/m], dF/du [N per control unit]}
 * (dF/da is 0: no term reads the acceleration). A non-finite input a term reads (x; v and u
 * for a valve): DN_E_NONFINITE_INPUT with *force and grad 0. Nullable: grad. */
DN_API int dn_damper_terms_grad(const dn_damper* d, const dn_damper_input* in, dn_real* force,
                                dn_real* grad);

/* The control range [u_min, u_max] of a damper [V or A, as dn_damper_input.u]: a neural
 * damper's saturation limits of its input reading u (voltage or current), a parametric
 * damper's [0, v_max], a lookup table's first and last control. DN_E_MISMATCH (both 0) when
 * the force does not depend on u (linear, a neural damper without a voltage/current input or
 * with two) or its range is unknown (callback); DN_E_NULL. */
DN_API int dn_damper_control_range(const dn_damper* d, dn_real* u_min, dn_real* u_max);

/* [RT] The inverse: the control *u [V or A] in [u_min, u_max] (dn_damper_control_range) at
 * which the damper's force at the input *in (every field but u: velocity [m/s], acceleration
 * [m/s^2], displacement [m], the states, temperature [degC]; in->u is ignored) equals
 * force_demand [N]; *force is the force [N] at *u. A neural damper starts where its
 * first-iterate grid puts the answer (DN_CAP_INVERSE_V x DN_CAP_INVERSE_U forces over velocity x
 * control, built at set-up): dn_damper_inverse_near from there, so that a reachable demand
 * usually costs two evaluations and neither limit. Without a grid (other kinds, a build
 * without), and where those steps do not settle it, the forces at both limits are evaluated:
 * a demand outside [min, max] of those two (+-Inf included) gets the limit of the nearer
 * force and DN_W_UNREACHABLE (the nearest achievable force and its control). Inside, the sign
 * change of F(u) - force_demand is narrowed by safeguarded Newton steps (dF/du analytic for a
 * neural damper, the bracket's secant for the others; Halley's step where d2F/du2 is known too,
 * a neural damper of one hidden layer, its physics terms' too (the valve's); bisection when a step leaves the bracket,
 * or is not under half the previous step while the bracket has not halved in two steps): at
 * most DN_INVERSE_MAX_ITERS more evaluations, stopping once the bracket, a step or the Newton
 * step the last evaluation asks for is below DN_INVERSE_TOL_REL of the control range, or the
 * force equals the demand to its rounding (dn_types.h);
 * the evaluated control with the smallest |F - force_demand| is returned. A model that is not
 * monotone in u still gets a control giving the demand (one of them: with a grid, the one found
 * near its first iterate, even where the limits' forces do not straddle the demand), or the
 * nearer limit.
 * Errors (*u the centre of the range, 0 without one; *force = 0): DN_E_MISMATCH (no control
 * input, or a callback damper), DN_E_NONFINITE_INPUT (a NaN demand or a NaN/Inf input field
 * the model reads), DN_E_NONFINITE_OUTPUT, DN_E_NULL. Warnings of the evaluations
 * (DN_W_SATURATED: a motion input outside the model's range) are OR-ed in.
 * Nullable: n_evals (every force evaluation made, the limits' included: at most
 * DN_INVERSE_WARM_EVALS + 2 + DN_INVERSE_MAX_ITERS). */
DN_API int dn_damper_inverse(const dn_damper* d, const dn_damper_input* in, dn_real force_demand,
                             dn_real* u, dn_real* force, int* n_evals);

/* [RT] dn_damper_inverse from a control near the answer, u_start [V or A] (a controller's last
 * command: the quarter car's and the full car's force-tracking laws pass theirs): Newton steps
 * from u_start on a neural damper's analytic dF/du, up to DN_INVERSE_WARM_EVALS of them before
 * any limit is evaluated. They stop as dn_damper_inverse's do; once two straddle the demand its
 * bracketed steps go on between those two. A step that would leave the control range through a
 * limit L evaluates F(L) (unless it starts at L): a demand between is bracketed there. Else
 * (the demand may be unreachable), dF/du 0 or not finite, or the warm steps spent:
 * dn_damper_inverse, reusing the limits already evaluated (a start at a limit, as a saturated
 * command's, is not evaluated twice). For a model monotone in u the answer is
 * dn_damper_inverse's (to its tolerance); for one that is not, a control giving the demand
 * found near u_start is returned even where dn_damper_inverse finds it outside the limits'
 * forces. u_start NaN or outside the range: dn_damper_inverse (from its grid's first iterate);
 * a damper without an analytic dF/du (parametric, table): the search from the limits. Nullable: n_evals (every force evaluation made, the limits' included:
 * at most DN_INVERSE_WARM_EVALS + 2 + DN_INVERSE_MAX_ITERS). */
DN_API int dn_damper_inverse_near(const dn_damper* d, const dn_damper_input* in, dn_real force_demand,
                                  dn_real u_start, dn_real* u, dn_real* force, int* n_evals);

/* Set-up (bounded: n_v (n_u + 1) force evaluations; no allocation): is the force monotone in
 * the control? F is scanned on n_v velocities evenly over [v_min, v_max] [m/s] x n_u controls
 * over dn_damper_control_range, the other inputs as in *at (its v and u ignored). At each
 * velocity the direction is that of F(u_max) - F(u_min) (the inverse's bracket); the reversal
 * is the largest fall [N] of F against it after a rise over the controls. *report: the number of
 * velocities with a reversal beyond tol_N [N], and the largest one: its velocity, the controls
 * between which F turns back and by how much (all 0 when none exceeds tol_N: monotone, the
 * inverse unique). A model that is not monotone keeps a defined inverse (dn_damper_inverse).
 * Statuses: DN_OK; DN_E_MISMATCH (no control, as dn_damper_control_range); DN_E_SIZE (n_v < 1,
 * n_u < 2, either beyond DN_MONOTONICITY_MAX_GRID); DN_E_PARAM (v_min > v_max, tol_N < 0);
 * DN_E_NONFINITE_PARAM; a force's error (report zeroed); DN_E_NULL. */
DN_API int dn_damper_control_monotonicity(const dn_damper* d, const dn_damper_input* at,
                                          dn_real v_min, dn_real v_max, int n_v, int n_u,
                                          dn_real tol_N, dn_monotonicity* report);

/*---- The quarter-car loop ----*/

/* Fill with the defaults of DN_VEHICLE_FIELDS. Nullable: nothing. */
DN_API void dn_vehicle_default(dn_vehicle* v);
/* Fill with the defaults of DN_CONTROLLER_FIELDS for a law (kind). */
DN_API void dn_controller_default(dn_controller* c, int kind);

/* Validate a vehicle / a controller as dn_loop_model_create does (the same checks):
 * DN_OK, DN_E_NONFINITE_PARAM (a NaN or infinite field), DN_E_PARAM (a field out of the
 * range its DN_VEHICLE_FIELDS / DN_CONTROLLER_FIELDS doc states, or an enum field that is
 * no value of its list), DN_E_NULL. */
DN_API int dn_vehicle_check(const dn_vehicle* v);
DN_API int dn_controller_check(const dn_controller* c);

/* Validate and create a loop model (copies the damper). Nonsensical values:
 * DN_E_NONFINITE_PARAM (NaN/Inf), DN_E_PARAM (mass <= 0, dt < 1e-9 or > 0.1, ...).
 * Nullable: ctrl (passive at u = 0). Allocates. */
DN_API int dn_loop_model_create(const dn_vehicle* veh, const dn_damper* damper,
                                const dn_controller* ctrl, dn_loop_model** out);
/* Destroy a loop model (after its data). Nullable: m. */
DN_API void dn_loop_model_destroy(dn_loop_model* m);

/* Create data for a model, reset to rest. Allocates. */
DN_API int dn_loop_data_create(const dn_loop_model* m, dn_loop_data** out);
/* Destroy data. Nullable: d. */
DN_API void dn_loop_data_destroy(dn_loop_data* d);

/* Bytes of a dn_loop_model / dn_loop_data, and their create in caller memory (see
 * "Caller-provided storage"). */
DN_API size_t dn_loop_model_size(void);
DN_API int dn_loop_model_init(const dn_vehicle* veh, const dn_damper* damper,
                              const dn_controller* ctrl, void* mem, size_t bytes,
                              dn_loop_model** out);
DN_API size_t dn_loop_data_size(void);
DN_API int dn_loop_data_init(const dn_loop_model* m, void* mem, size_t bytes, dn_loop_data** out);

/* A loop model with a neural damper built in place, in the model's own memory, from a folded
 * float description (dn_mlp_folded_f, e.g. a generated header's P_FOLDED_INIT): the result of
 * dn_mlp_init_folded + dn_damper_init_neural(..., DN_PRECISION_FLOAT, ...) + dn_loop_model_init,
 * bit for bit, without the separate MLP and damper. Those hold the network twice at set-up (the
 * damper's copy and the loop model's); this holds it once, which on a microcontroller is the
 * peak RAM. Statuses: those of the three calls (DN_E_NULL for
 * a NULL veh or folded). Nullable: ctrl (passive at u = 0), param_names / param_values when
 * n_params == 0. Set-up only. */
DN_API int dn_loop_model_init_neural(const dn_vehicle* veh, const dn_controller* ctrl,
                                     const dn_mlp_folded_f* folded, const char* const* features,
                                     int n_features, const char* const* param_names,
                                     const double* param_values, int n_params, void* mem,
                                     size_t bytes, dn_loop_model** out);

/* [RT] Reset to rest: zero displacements, velocities, road and time; u_cmd = the control
 * the controller gives at rest (external: 0); f_last = f_static; temperature from the
 * vehicle; the damper's states at their rest with that control (a lag at its source: the
 * control lag at u_cmd, the velocity lag at 0; the Dahl state 0, no friction direction). */
DN_API int dn_loop_reset(const dn_loop_model* m, dn_loop_data* d);

/* Number of dn_real in the flat state (DN_LOOP_STATE_SIZE). */
DN_API int dn_loop_state_size(void);
/* [RT] Copy the state out (DN_LOOP_STATE_SIZE dn_real, DN_LOOP_STATE_LIST order). */
DN_API int dn_loop_get_state(const dn_loop_data* d, dn_real* state);
/* [RT] Set the state; a non-finite value: DN_E_NONFINITE_INPUT, state unchanged.
 * (An u_cmd outside [u_min, u_max] is clamped when the filter next uses it.) */
DN_API int dn_loop_set_state(dn_loop_data* d, const dn_real* state);
/* Damper evaluations since creation (for tests of the evaluation count). */
DN_API int64_t dn_loop_damper_evals(const dn_loop_data* d);

/* [RT] One step of dt: controller, damper, integrator. Reports at the step start
 * into *out. A NaN or infinite step input (road, external control):
 * DN_E_NONFINITE_INPUT. Finite inputs whose step would produce a non-finite value
 * anywhere (state, accelerations, a damper input or force: a road of 1e308, an
 * unstable step, a runaway): DN_E_DIVERGED (a callback damper's own non-finite
 * force: DN_E_NONFINITE_OUTPUT). In every error case the state is unchanged.
 * Warnings from the damper (DN_W_*) are OR-ed. Nullable: out. */
DN_API int dn_loop_step(const dn_loop_model* m, dn_loop_data* d, const dn_loop_input* in,
                        dn_loop_out* out);

/* [RT] What the next step would report at the current state, without advancing.
 * It evaluates the damper once (a stateful callback damper sees that call). */
DN_API int dn_loop_forward(const dn_loop_model* m, const dn_loop_data* d, const dn_loop_input* in,
                           dn_loop_out* out);

/*---- The full vehicle ----*/
#if !DN_LOOP_FLOAT /* the full vehicle is built with double only (DN_LOOP_FLOAT: dn_config.h) */
/* A ride-and-handling vehicle model beside the quarter car, built the same way (constant
 * model, flat state, allocation-free [RT] step): body heave z, roll phi, pitch theta, lateral
 * velocity vy and yaw rate r at a constant forward speed, yaw angle psi and position X, Y,
 * four wheels' vertical motion; at each corner a spring, any dn_damper with its own
 * dn_controller, anti-roll bars front and rear; tyres with a vertical spring (+ damping) that
 * lifts off (load never negative) and a load-sensitive Magic-Formula lateral force; an
 * open-loop steering input or a preview driver following a path. Equations, signs and the
 * coupled acceleration feature: cpp/include/dampnet/fullcar.hpp. Corners 0 FL, 1 FR, 2 RL,
 * 3 RR; frame ISO 8855 (x forward, y left, z up; roll positive lifts the left side, pitch
 * positive pushes the nose down, yaw positive to the left). */
/* Fill with the defaults of DN_FULLCAR_FIELDS. */
DN_API void dn_fullcar_default(dn_fullcar_params* p);
/* Validate as dn_fullcar_model_create does: DN_OK, DN_E_NONFINITE_PARAM, DN_E_PARAM (a field
 * out of its documented range, an unknown enum value), DN_E_NULL. */
DN_API int dn_fullcar_check(const dn_fullcar_params* p);
/* Validate and create a model (copies the four dampers). dampers: 4 (FL, FR, RL, RR), none
 * NULL; ctrls: 4 controllers or NULL (passive at u = 0 everywhere). The driver's path
 * Y(X) (path_x strictly increasing, 2..DN_FULLCAR_MAX_PATH points, piecewise linear, ends
 * held) is required for DN_STEER_DRIVER (n_path 0 otherwise: DN_E_PARAM with the driver).
 * Allocates. */
DN_API int dn_fullcar_model_create(const dn_fullcar_params* p, const dn_damper* const* dampers,
                                   const dn_controller* ctrls, const double* path_x,
                                   const double* path_y, int n_path, dn_fullcar_model** out);
/* Destroy a model (after its data). Nullable: m. */
DN_API void dn_fullcar_model_destroy(dn_fullcar_model* m);
/* Create data for a model, reset to rest. Allocates. */
DN_API int dn_fullcar_data_create(const dn_fullcar_model* m, dn_fullcar_data** out);
/* Destroy data. Nullable: d. */
DN_API void dn_fullcar_data_destroy(dn_fullcar_data* d);
/* [RT] Reset to rest (every corner as dn_loop_reset; body, heading, position, steer 0). */
DN_API int dn_fullcar_reset(const dn_fullcar_model* m, dn_fullcar_data* d);
/* Number of doubles in the flat state (DN_FULLCAR_STATE_SIZE). */
DN_API int dn_fullcar_state_size(void);
/* [RT] Copy the state out / set it (a non-finite value: DN_E_NONFINITE_INPUT, unchanged). */
DN_API int dn_fullcar_get_state(const dn_fullcar_data* d, double* state);
DN_API int dn_fullcar_set_state(dn_fullcar_data* d, const double* state);
/* Damper evaluations since creation, all corners together. */
DN_API int64_t dn_fullcar_damper_evals(const dn_fullcar_data* d);
/* [RT] One step of dt; statuses as dn_loop_step (a NaN/Inf road, steer or external control:
 * DN_E_NONFINITE_INPUT; a runaway: DN_E_DIVERGED; the state is unchanged on error; damper
 * warnings OR-ed over the corners). Nullable: out. */
DN_API int dn_fullcar_step(const dn_fullcar_model* m, dn_fullcar_data* d,
                           const dn_fullcar_input* in, dn_fullcar_out* out);
/* [RT] What the next step would report at the current state, without advancing. */
DN_API int dn_fullcar_forward(const dn_fullcar_model* m, const dn_fullcar_data* d,
                              const dn_fullcar_input* in, dn_fullcar_out* out);
#endif /* !DN_LOOP_FLOAT */

#ifdef __cplusplus
}
#endif

#endif /* DAMPNET_H */