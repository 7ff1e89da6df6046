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

/* Registries: every name the runtime knows is defined once, in an X-macro list below, and
 * the C enums, the C++ tables and the Python module's registries (dampnet._core:
 * CONTROLLER_KINDS, INTEGRATORS, FEATURE_NAMES, ...) are all expanded from these lists.
 * An enum list's rows are X(id, value, "name", doc): the value is the ABI (never renumber),
 * "name" is the one spelling Python and model files use. DN_ENUM_ROW_ declares them. */
#define DN_ENUM_ROW_(id, value, name, doc) id = value,

/*---- Version ----*/

#define DN_VERSION_MAJOR 0
#define DN_VERSION_MINOR 5 /* 0.5: the damper owns its state (DN_DAMPER_STATE_LIST; the loop and full-car states keep it as one block); 0.4: the full vehicle dn_fullcar_* (0.3: dn_controller.u_tau_s, 13 loop states; 0.2: dn_damper_input.v_lag/z_fric) */
#define DN_VERSION_PATCH 0
/* Version of this header as major*10000 + minor*100 + patch. */
#define DN_VERSION_HEADER (DN_VERSION_MAJOR * 10000 + DN_VERSION_MINOR * 100 + DN_VERSION_PATCH)

/* Version of the linked library as major*10000 + minor*100 + patch; compare with DN_VERSION_HEADER. */
DN_API int dn_version(void);

/* Version of the linked library as a string, e.g. "0.1.0". */
DN_API const char* dn_version_string(void);

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
  X(DN_E_NULL, -1, "a required pointer argument was NULL")                                   \
  X(DN_E_SIZE, -2, "a size is out of range (inputs 1..8, hidden 1..64, layers 1..2)")        \
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

#define DN_STATUS_ENUM_(name, value, text) name = value,
typedef enum dn_status { DN_STATUS_LIST(DN_STATUS_ENUM_) } dn_status;
#undef DN_STATUS_ENUM_

/* A human-readable explanation of a status (an OR of warnings is explained too). Never NULL. */
DN_API const char* dn_status_str(int status);

/*---- The MLP ----*/

#define DN_MAX_INPUTS 8        /* inputs per model */
#define DN_MAX_HIDDEN 64       /* neurons per hidden layer */
#define DN_MAX_HIDDEN_LAYERS 2 /* hidden layers */

/* Capacities of this build of the library: what its fixed-size objects hold. The defaults are
 * the limits above; a build for a small target lowers them (compile definitions of the library
 * and of every C++ file including its headers: the Cortex-M presets of CMakePresets.json set
 * them from the DAMPNET_CAP_* cache options) so that the objects, dn_*_size() and RAM shrink.
 * Set-up refuses a model beyond them with DN_E_SIZE. C code sees the objects only through
 * pointers, so a C program needs no definitions of its own.
 *   DN_CAP_INPUTS   inputs of an MLP, 1..DN_MAX_INPUTS
 *   DN_CAP_HIDDEN   neurons of hidden layer 1, 1..DN_MAX_HIDDEN
 *   DN_CAP_HIDDEN2  neurons of hidden layer 2, 0 (one hidden layer only)..DN_MAX_HIDDEN
 *   DN_CAP_TABLE_V, DN_CAP_TABLE_U  lookup-table velocities (2..) and controls (1..)
 *   DN_CAP_TERMS    physics terms per damper, 0..DN_MAX_TERMS
 *   DN_DOUBLE_KERNEL  1: the double-precision MLP kernel; 0: none (float-only targets:
 *                   DN_PRECISION_DOUBLE and dn_mlp_forward give DN_E_PARAM)
 *   DN_KERNEL_SMALL   1: flash before speed on scalar cores (CMake DAMPNET_KERNEL_SMALL; the
 *                   Cortex-M presets): the one-hidden-layer float forward is compiled once, for
 *                   exactly DN_CAP_INPUTS inputs (set-up refuses another input count with
 *                   DN_E_SIZE), and set-up code is optimised for size; 0 (default): also a
 *                   forward for any input count. No effect on x86's SIMD kernels.
 *   DN_KERNEL_UNROLL  neurons per pass of the scalar float forward, 1, 2, 4 or 8 (CMake
 *                   DAMPNET_KERNEL_UNROLL; default 2 with DN_KERNEL_SMALL, else 8): more is
 *                   more flash and fewer instructions; the result is the same bits for any. */
#ifndef DN_CAP_INPUTS
#define DN_CAP_INPUTS DN_MAX_INPUTS
#endif
#ifndef DN_CAP_HIDDEN
#define DN_CAP_HIDDEN DN_MAX_HIDDEN
#endif
#ifndef DN_CAP_HIDDEN2
#define DN_CAP_HIDDEN2 DN_MAX_HIDDEN
#endif
#ifndef DN_DOUBLE_KERNEL
#define DN_DOUBLE_KERNEL 1
#endif

/* The loop's real type. DN_LOOP_FLOAT 1 (CMake DAMPNET_LOOP_FLOAT; the cortex-m4 preset) makes
 * dn_real float: the quarter-car loop's state and arithmetic, the damper models, the vehicle
 * and controller parameters, dn_damper_input, dn_loop_input / dn_loop_out and the flat state
 * are single precision, for cores whose FPU has no double (Cortex-M4F: every double operation
 * there is a library routine of ~20-100 cycles). Default 0: double, the host's. The MLP's
 * own API (dn_mlp_*) and the set-up arrays (tables, feature and term parameters) keep double;
 * the full vehicle (dn_fullcar_*) exists only with double. */
#ifndef DN_LOOP_FLOAT
#define DN_LOOP_FLOAT 0
#endif
#if DN_LOOP_FLOAT
typedef float dn_real;
#else
typedef double dn_real;
#endif

/* The damper kinds this build evaluates, a bit mask (bit k: dn_damper_kind k; CMake
 * DAMPNET_DAMPER_KINDS, a list of kind names). Default: all. A kind left out is not linked
 * (a microcontroller's flash: the Cortex-M presets keep only "neural"); creating a damper of
 * it gives DN_E_PARAM. */
#ifndef DN_DAMPER_KINDS
#define DN_DAMPER_KINDS 0x1f
#endif

/* The acceleration-feature schemes this build has, a bit mask (bit k: dn_accel_feature k; CMake
 * DAMPNET_ACCEL_FEATURES, a list of names). Default: all. A scheme left out is not linked (the
 * Cortex-M presets keep "linear" and "explicit": not the implicit solve's iteration); a vehicle
 * asking for it is refused (dn_vehicle_check: DN_E_PARAM), and
 * dn_vehicle_default gives DN_ACCEL_LINEAR when DN_ACCEL_IMPLICIT is out. */
#ifndef DN_ACCEL_FEATURES
#define DN_ACCEL_FEATURES 0x7
#endif

/* The damper-evaluation schemes this build has, a bit mask (bit k: dn_damper_eval k; CMake
 * DAMPNET_DAMPER_EVALS, names). Default: both. The Cortex-M presets keep "per_step" (one
 * evaluation per step, the real-time choice): the per-stage path is not
 * linked, a vehicle asking for it is refused (DN_E_PARAM) and dn_vehicle_default asks for
 * DN_EVAL_PER_STEP. */
#ifndef DN_DAMPER_EVALS
#define DN_DAMPER_EVALS 0x3
#endif

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

/* Hidden-layer activations (MlpModel.activation); the output layer is always linear. */
#define DN_ACTIVATION_LIST(X)                                  \
  X(DN_ACT_TANH, 0, "tanh", "tanh(x) (MATLAB's tansig)")       \
  X(DN_ACT_SIGMOID, 1, "sigmoid", "1 / (1 + exp(-x)) (MATLAB's logsig)")
typedef enum dn_activation { DN_ACTIVATION_LIST(DN_ENUM_ROW_) } dn_activation;

/* A model description: what a generated header or a training run provides.
 * All arrays are double and row-major with PyTorch's layout [out][in].
 * Scaling is MATLAB's mapminmax: x_scaled = (x - in_offset) * in_gain + in_ymin,
 * and y = (y_scaled - out_ymin) / out_gain + out_offset.
 * Saturation: before scaling, input i is clamped to [sat_lo[i], sat_hi[i]]
 * (the training range), in the input's own unit. */
typedef struct dn_mlp_desc {
  int n_inputs;            /* inputs, 1..DN_MAX_INPUTS */
  int n_hidden1;           /* neurons in hidden layer 1, 1..DN_MAX_HIDDEN */
  int n_hidden2;           /* neurons in hidden layer 2, 0 (no second layer) or 1..DN_MAX_HIDDEN */
  int activation;          /* dn_activation of the hidden layers */
  const double* w1;        /* [n_hidden1][n_inputs] */
  const double* b1;        /* [n_hidden1] */
  const double* w2;        /* [n_hidden2][n_hidden1]; NULL when n_hidden2 == 0 */
  const double* b2;        /* [n_hidden2]; NULL when n_hidden2 == 0 */
  const double* w_out;     /* [1][n_last_hidden] */
  const double* b_out;     /* [1] */
  const double* in_offset; /* [n_inputs] mapminmax xoffset (training minimum), input units */
  const double* in_gain;   /* [n_inputs] mapminmax gain, 1/input unit */
  double in_ymin;          /* mapminmax ymin of the inputs, normally -1 */
  double out_offset;       /* mapminmax xoffset of the output (force minimum) [N] */
  double out_gain;         /* mapminmax gain of the output [1/N] */
  double out_ymin;         /* mapminmax ymin of the output, normally -1 */
  const double* sat_lo;    /* [n_inputs] lower saturation limit, input units */
  const double* sat_hi;    /* [n_inputs] upper saturation limit, input units */
} dn_mlp_desc;

/* An immutable, validated model holding float and double copies of the weights. Opaque. */
typedef struct dn_mlp dn_mlp;

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

/* A model with its scalings already folded into float weights: exactly what a dn_mlp's float
 * copy holds after dn_mlp_init from a dn_mlp_desc (the folding is done in double and rounded to
 * float once), written by the exporter (a generated header's P_FOLDED_INIT). For float-only
 * targets (DN_DOUBLE_KERNEL 0): dn_mlp_init_folded only checks and copies floats, so set-up does
 * no double arithmetic (on a single-precision FPU no software double routine is linked) and the
 * image holds float weights, not the double description. The float forward is then
 *   x'_i = x_i clamped to [sat_lo[i], sat_hi[i]] (NaN: sat_mid[i]), minus in_offset[i] when
 *          offsets_folded is 0 (1: layer 1's biases hold the offsets, layer 1 reads x' itself),
 *   t1_j = tanh(b1[j] + sum_i w1[j * n_inputs + i] x'_i),
 *   t2_k = tanh(b2[k] + sum_j w2[k * n_hidden1 + j] t1_j)   (n_hidden2 > 0),
 *   y    = b_out + sum_j w_out[j] t_last_j,   out_offset when that is not finite,
 * tanh for both activations (a sigmoid network's halvings are folded into the weights), and its
 * result is dn_mlp_init's bit for bit on the scalar and SSE kernels (the AVX2 and AVX-512 host
 * kernels fold w_out into their tanh from the float w_out here, from the double one there: a
 * difference of float roundings). Units: y in the model's output unit (N for a damper model). */
typedef struct dn_mlp_folded_f {
  int n_inputs;            /* inputs, 1..DN_MAX_INPUTS */
  int n_hidden1;           /* neurons in hidden layer 1, 1..DN_MAX_HIDDEN */
  int n_hidden2;           /* neurons in hidden layer 2, 0 (no second layer) or 1..DN_MAX_HIDDEN */
  int offsets_folded;      /* 1: b1 includes -w1 in_offset (layer 1 on x'); 0: layer 1 on x' - in_offset */
  const float* w1;         /* [n_hidden1][n_inputs], 1/input unit (mapminmax gain folded in) */
  const float* b1;         /* [n_hidden1] */
  const float* w2;         /* [n_hidden2][n_hidden1]; NULL when n_hidden2 == 0 */
  const float* b2;         /* [n_hidden2]; NULL when n_hidden2 == 0 */
  const float* w_out;      /* [n_last_hidden], output units (the output unscaling folded in) */
  float b_out;             /* output for all-zero hidden units, output units */
  float out_offset;        /* the output given in place of a non-finite one, output units */
  const float* in_offset;  /* [n_inputs] mapminmax xoffset, input units (used when !offsets_folded) */
  const float* sat_lo;     /* [n_inputs] lower saturation limit, input units */
  const float* sat_hi;     /* [n_inputs] upper saturation limit, input units, >= sat_lo */
  const float* sat_mid;    /* [n_inputs] what a NaN input becomes, in [sat_lo, sat_hi], input units */
} dn_mlp_folded_f;

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

/* The coarse joint envelope of a model's training data (dampnet.envelope_grid writes it; a
 * generated header's P_ENVELOPE_DESC_INIT when the model was exported with its envelope).
 * Every input's training range [lo, hi] is cut into DN_ENVELOPE_CELLS cells (one cell for a
 * constant input, hi = lo); for every pair of inputs (i < j, in the order (0,1), (0,2), ..,
 * (0,n-1), (1,2), ..) a bitmap says which of the DN_ENVELOPE_CELLS^2 cells of the pair's plane
 * held one of the envelope's stored training samples (at most 20,000, dampnet.envelope) or
 * bordered one (those cells dilated by one cell each way). A point is inside when every input is in
 * its range and every pair of inputs falls in a marked cell: the data's 2-D shadows, so a point
 * between two training control levels, or off the (velocity, acceleration) ellipses of the sine
 * tests, is outside; a point inside every shadow can still be far from the data in more than two
 * inputs (the offline k-d tree measure of dampnet.envelope catches that). Memory: the struct is
 * fixed (DN_ENVELOPE_MAX_PAIRS bitmaps of 128 bytes); a check reads one word per pair. */
#define DN_ENVELOPE_CELLS 32 /* cells per input across its training range */
#define DN_ENVELOPE_MAX_PAIRS (DN_MAX_INPUTS * (DN_MAX_INPUTS - 1) / 2)
#define DN_ENVELOPE_PAIR_WORDS (DN_ENVELOPE_CELLS * DN_ENVELOPE_CELLS / 32) /* uint32 per pair */

/* Bits of a check's flags (0: inside). */
#define DN_ENV_OUTSIDE_RANGE 1u /* an input outside its training range, or NaN */
#define DN_ENV_OUTSIDE_JOINT 2u /* two inputs, each in range, in a cell of their plane no training
                                   sample is near */

typedef struct dn_envelope_desc {
  int n_inputs;          /* the model's inputs, 1..DN_MAX_INPUTS */
  const double* lo;      /* [n_inputs] training range, lower limit, feature units (the model's sat_lo) */
  const double* hi;      /* [n_inputs] upper limit (sat_hi), >= lo, hi - lo finite */
  const uint32_t* cells; /* [n_pairs * DN_ENVELOPE_PAIR_WORDS], n_pairs = n (n - 1) / 2: pair p's
                            cell (ci, cj) is bit (ci * DN_ENVELOPE_CELLS + cj) % 32 of word
                            p * DN_ENVELOPE_PAIR_WORDS + (ci * DN_ENVELOPE_CELLS + cj) / 32, where
                            ci = floor((x_i - lo_i) * s_i) with s_i = DN_ENVELOPE_CELLS / (hi_i -
                            lo_i) in double, in that order (0 when hi_i = lo_i or the quotient is
                            infinite), clamped to the last cell (x_i = hi_i). NULL allowed for
                            one input only. */
} dn_envelope_desc;

/* A validated envelope (ranges and bitmaps, copied). Opaque, immutable: share it freely. */
typedef struct dn_envelope dn_envelope;

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

/* Sign convention (the dyno's): displacement x and velocity v are the damper's
 * relative extension and extension rate (positive in rebound, when sprung and
 * unsprung move apart); the force F is positive when it resists extension
 * (tension). In the quarter car: x = z_s - z_us + x_static, v = dz_s - dz_us. */

/* Rows a test build appends to the feature lists (tests/python/test_state_recipe.py proves the
 * recipe below with them); empty otherwise. */
#ifndef DN_EXTRA_FEATURE_PARAMS
#define DN_EXTRA_FEATURE_PARAMS(X)
#endif
#ifndef DN_EXTRA_INPUT_FIELDS
#define DN_EXTRA_INPUT_FIELDS(X)
#endif
#ifndef DN_EXTRA_FEATURES
#define DN_EXTRA_FEATURES(X)
#endif
#ifndef DN_EXTRA_DAMPER_STATES
#define DN_EXTRA_DAMPER_STATES(X)
#endif

/* Constants of derived features (MlpModel.feature_params), by name:
 * X(id, "name", meaning). Unknown names are refused (DN_E_UNKNOWN_NAME). */
#define DN_FEATURE_PARAM_LIST(X)                                                                   \
  X(DN_FPARAM_CONTROL_LAG_TAU_S, "control_lag_tau_s",                                               \
    "time constant of voltage_lag / current_lag [s], > 0")                                         \
  X(DN_FPARAM_VELOCITY_LAG_TAU_S, "velocity_lag_tau_s", "time constant of velocity_lag [s], > 0") \
  X(DN_FPARAM_FRICTION_PRESLIDING_M, "friction_presliding_m",                                       \
    "pre-sliding travel of friction_state [m], > 0")                                               \
  DN_EXTRA_FEATURE_PARAMS(X)

#define DN_FPARAM_ENUM_(id, name, text) id,
/* DN_FPARAM_NONE: a feature that needs no parameter (DN_FEATURE_LIST's last column). */
typedef enum dn_feature_param {
  DN_FPARAM_NONE = -1,
  DN_FEATURE_PARAM_LIST(DN_FPARAM_ENUM_) DN_N_FEATURE_PARAMS
} dn_feature_param;
#undef DN_FPARAM_ENUM_

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
    "friction_presliding_m after each reversal [-]")                                        \
  DN_EXTRA_INPUT_FIELDS(X)

#define DN_INPUT_DECL_(type, name, role, doc) type name;
typedef struct dn_damper_input { DN_DAMPER_INPUT_FIELDS(DN_INPUT_DECL_) } dn_damper_input;
#undef DN_INPUT_DECL_

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
 * A new kind of dynamics is a row of DN_STATE_DYNAMICS_LIST and its three formulas in
 * cpp/include/dampnet/damper_state.hpp (and python/dampnet/features.py's twin).
 * tests/python/test_state_recipe.py proves the recipe: it adds such a feature through the
 * DN_EXTRA_* hooks below (a test build only) and runs it through every host. */
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
  X(DN_FEAT_FRICTION_STATE, "friction_state", z_fric, DN_FPARAM_FRICTION_PRESLIDING_M)  \
  DN_EXTRA_FEATURES(X)

#define DN_FEATURE_ENUM_(id, name, field, param) id,
typedef enum dn_feature { DN_FEATURE_LIST(DN_FEATURE_ENUM_) DN_N_FEATURES } dn_feature;
#undef DN_FEATURE_ENUM_

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
typedef enum dn_state_dynamics { DN_STATE_DYNAMICS_LIST(DN_ENUM_ROW_) } dn_state_dynamics;

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
    "Dahl friction state of the friction_state feature, in [-1, 1]")                            \
  DN_EXTRA_DAMPER_STATES(X)
#define DN_DS_ENUM_(id, name, unit, dyn, source, param, doc) id,
typedef enum dn_damper_state { DN_DAMPER_STATE_LIST(DN_DS_ENUM_) DN_DAMPER_STATE_SIZE } dn_damper_state;
#undef DN_DS_ENUM_

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
    "k [N/m^n] >= 0, n > 0)")

#define DN_TERM_ENUM_(id, value, name, n_params, text) id = value,
typedef enum dn_term_kind { DN_TERM_LIST(DN_TERM_ENUM_) DN_N_TERM_KINDS } dn_term_kind;
#undef DN_TERM_ENUM_

#define DN_MAX_TERMS 8        /* physics terms per damper */
#define DN_MAX_TERM_PARAMS 8  /* parameters per term */
#define DN_MAX_TABLE_V 64     /* velocity points of a lookup table */
#define DN_MAX_TABLE_U 16     /* control points of a lookup table */
/* This build's capacities of a damper (see DN_CAP_INPUTS above). */
#ifndef DN_CAP_TERMS
#define DN_CAP_TERMS DN_MAX_TERMS
#endif
#ifndef DN_CAP_TABLE_V
#define DN_CAP_TABLE_V DN_MAX_TABLE_V
#endif
#ifndef DN_CAP_TABLE_U
#define DN_CAP_TABLE_U DN_MAX_TABLE_U
#endif

/* Damper model kinds. */
#define DN_DAMPER_KIND_LIST(X)                                                                \
  X(DN_DAMPER_LINEAR, 0, "linear", "F = c v")                                                 \
  X(DN_DAMPER_PARAMETRIC, 1, "parametric", "the thesis's eq. 1-3 (dn_parametric_params)")     \
  X(DN_DAMPER_TABLE, 2, "table", "force against velocity for a set of controls, bilinear")    \
  X(DN_DAMPER_NEURAL, 3, "neural", "the MLP on named features")                               \
  X(DN_DAMPER_CALLBACK, 4, "callback",                                                        \
    "a user function (slow path; e.g. a truth model or a real damper)")
typedef enum dn_damper_kind { DN_DAMPER_KIND_LIST(DN_ENUM_ROW_) } dn_damper_kind;

/* Precision of a neural damper's MLP evaluation (the loop's state is dn_real). */
#define DN_PRECISION_LIST(X)                                          \
  X(DN_PRECISION_DOUBLE, 0, "double", "double-precision kernel")     \
  X(DN_PRECISION_FLOAT, 1, "float", "single-precision kernel")
typedef enum dn_precision { DN_PRECISION_LIST(DN_ENUM_ROW_) } dn_precision;

/* The thesis's parametric semi-active damper (eq. 1-3):
 * F = c(V) v + F0 sgn(v), c = gamma / V + c_min for V > 0, c_max for V = 0,
 * clamped to [c_min, c_max]; V is the control clamped to [0, v_max] first.
 * sgn is exact with sgn(0) = 0 when v_smooth = 0, else tanh(v / v_smooth). */
typedef struct dn_parametric_params {
  dn_real c_min;    /* minimum damping [N s/m], >= 0 */
  dn_real c_max;    /* maximum damping [N s/m], >= c_min */
  dn_real gamma;    /* gain [N s V/m] (c = gamma / V + c_min), >= 0 */
  dn_real f0;       /* breakaway (friction) force [N], >= 0 */
  dn_real v_max;    /* largest control [V], > 0 */
  dn_real v_smooth; /* sgn smoothing velocity [m/s], >= 0 (0: exact sgn) */
} dn_parametric_params;

/* A user damper: returns the force [N] for one evaluation. It runs inside the
 * step, so it must follow the real-time rules if the loop does. A stateful
 * callback should be used with DN_EVAL_PER_STEP (then called once per step,
 * stage 0). Nullable: user. */
typedef dn_real (*dn_damper_fn)(void* user, const dn_damper_input* in);

/* A damper model: immutable once handed to a loop model (which copies it). Opaque. */
typedef struct dn_damper dn_damper;

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
  X(DN_CTRL_EXTERNAL, 5, "external", "u = dn_loop_input.u (the caller's controller)")
typedef enum dn_controller_kind { DN_CONTROLLER_KIND_LIST(DN_ENUM_ROW_) } dn_controller_kind;

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
  X(dn_real, u_tau_s, 0.0, "command filter time constant [s], >= 0; 0 = none (not EXTERNAL)")

#define DN_FIELD_DECL_(type, name, def, doc) type name;
typedef struct dn_controller { DN_CONTROLLER_FIELDS(DN_FIELD_DECL_) } dn_controller;

/*---- The quarter-car loop ----*/

/* Integrators. */
#define DN_INTEGRATOR_LIST(X)                                                     \
  X(DN_INT_RK4, 0, "rk4", "classical 4th-order Runge-Kutta")                      \
  X(DN_INT_SEMI_EULER, 1, "semi_euler",                                           \
    "semi-implicit (symplectic) Euler: v first, then z with the new v")
typedef enum dn_integrator { DN_INTEGRATOR_LIST(DN_ENUM_ROW_) } dn_integrator;

/* When the damper is evaluated within an RK4 step. */
#define DN_DAMPER_EVAL_LIST(X)                                                          \
  X(DN_EVAL_PER_STAGE, 0, "per_stage",                                                  \
    "at each of the 4 stages (4th order; 4 evaluations per step)")                      \
  X(DN_EVAL_PER_STEP, 1, "per_step",                                                    \
    "once at the step start, force held over the step (1 evaluation; 1st order)")
typedef enum dn_damper_eval { DN_DAMPER_EVAL_LIST(DN_ENUM_ROW_) } dn_damper_eval;
/* The default: per stage, or per step in a build without it (DN_DAMPER_EVALS). */
#define DN_EVAL_DEFAULT ((DN_DAMPER_EVALS & (1 << DN_EVAL_PER_STAGE)) ? DN_EVAL_PER_STAGE : DN_EVAL_PER_STEP)

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
typedef enum dn_accel_feature { DN_ACCEL_FEATURE_LIST(DN_ENUM_ROW_) } dn_accel_feature;
#define DN_ACCEL_MAX_EVALS 6 /* damper evaluations per implicit solve, at most */
/* The default scheme: implicit, or linear in a build without it (DN_ACCEL_FEATURES). */
#define DN_ACCEL_DEFAULT ((DN_ACCEL_FEATURES & (1 << DN_ACCEL_IMPLICIT)) ? DN_ACCEL_IMPLICIT : DN_ACCEL_LINEAR)
/* Smallest g' = 1 + k dF/da at which DN_ACCEL_LINEAR takes its Newton step (see above). */
#define DN_ACCEL_LINEAR_MIN_SLOPE 0.5

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

typedef struct dn_vehicle { DN_VEHICLE_FIELDS(DN_FIELD_DECL_) } dn_vehicle;


/* Physical plausibility, X(name, value, doc): a step whose new state leaves any of these fails
 * with DN_E_DIVERGED and is not taken, like a step that overflows. They lie far beyond any road
 * vehicle (long-travel off-road suspensions move about 0.9 m; a body rolled 57 degrees has
 * overturned), so only a runaway reaches them: a damper that feeds energy in (a negative-slope
 * table, a callback), a step beyond the stability limit, a road far beyond ISO 8608 class H's at
 * speed. The quarter car and the full car check them at every step (and the Python reference
 * loop, dampnet.sim.reference_loop). */
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
#undef DN_FIELD_DECL_

/* Fill with the defaults above. Nullable: nothing. */
DN_API void dn_vehicle_default(dn_vehicle* v);
/* Fill with the defaults above for a law (kind). */
DN_API void dn_controller_default(dn_controller* c, int kind);

/* Validate a vehicle / a controller as dn_loop_model_create does (the same checks):
 * DN_OK, DN_E_NONFINITE_PARAM (a NaN or infinite field), DN_E_PARAM (a field out of the
 * range its DN_VEHICLE_FIELDS / DN_CONTROLLER_FIELDS doc states, or an enum field that is
 * no value of its list), DN_E_NULL. */
DN_API int dn_vehicle_check(const dn_vehicle* v);
DN_API int dn_controller_check(const dn_controller* c);

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

/* Per step input: the road at the END of the step (t + dt) and an external control. */
typedef struct dn_loop_input {
  dn_real z_r; /* road displacement at t + dt [m] */
  dn_real v_r; /* road rate at t + dt [m/s] */
  dn_real u;   /* control for DN_CTRL_EXTERNAL [V]; ignored by the other laws */
} dn_loop_input;

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

#define DN_OUT_DECL_(name, doc) dn_real name;
typedef struct dn_loop_out {
  DN_LOOP_OUT_LIST(DN_OUT_DECL_)
  dn_real features[DN_MAX_INPUTS]; /* a neural damper's inputs (before saturation), feature units */
  int n_features;                 /* number of valid features (0 unless neural) */
  uint32_t clamped_mask;          /* neural: bit i = input i clamped */
} dn_loop_out;
#undef DN_OUT_DECL_

/* A validated, immutable loop model (vehicle, damper copy, controller). Opaque. */
typedef struct dn_loop_model dn_loop_model;
/* A loop's mutable state. One model may drive many data. Opaque. */
typedef struct dn_loop_data dn_loop_data;

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

/* [RT] Reset to rest: zero displacements, velocities, road and time; u_lag and
 * u_cmd = the control the controller gives at rest (external: 0); f_last = f_static;
 * temperature from the vehicle; v_lag = 0 and z_fric = 0 (at rest, no friction
 * direction). */
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
#if !DN_LOOP_FLOAT /* the full vehicle is built with double only (DN_LOOP_FLOAT above) */
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
#define DN_FULLCAR_CORNERS 4
#define DN_FULLCAR_MAX_PATH 256 /* points of the driver's path */
#define DN_TYRE_MODEL_LIST(X)                                                               \
  X(DN_TYRE_MAGIC_FORMULA, 0, "magic_formula",                                              \
    "Fy = D sin(C atan(B alpha - E (B alpha - atan(B alpha)))), D and B from the load")     \
  X(DN_TYRE_LINEAR, 1, "linear", "Fy = K(N0) alpha: the static load's cornering stiffness")
typedef enum dn_tyre_model { DN_TYRE_MODEL_LIST(DN_ENUM_ROW_) } dn_tyre_model;
#define DN_STEER_MODE_LIST(X)                                                           \
  X(DN_STEER_OPEN_LOOP, 0, "open_loop", "road-wheel angle from dn_fullcar_input.steer")  \
  X(DN_STEER_DRIVER, 1, "driver", "preview driver following the model's path")
typedef enum dn_steer_mode { DN_STEER_MODE_LIST(DN_ENUM_ROW_) } dn_steer_mode;
/* Full-vehicle parameters: X(type, name, default, doc). Defaults: a compact-pickup-class
 * vehicle whose front corner is the thesis's Table 5 quarter car (700 kg sprung, 40 kg
 * unsprung, 15 kN/m, 200 kN/m); sources of the other figures in the README. */
#define DN_FULLCAR_FIELDS(X)                                                                   \
  X(double, m_s, 2600.0, "sprung mass [kg], > 0")                                              \
  X(double, i_xx, 900.0, "sprung-mass roll inertia about the roll axis [kg m^2], > 0")          \
  X(double, i_yy, 3900.0, "sprung-mass pitch inertia [kg m^2], > 0")                           \
  X(double, i_zz, 4800.0, "vehicle yaw inertia [kg m^2], > 0")                                 \
  X(double, a, 1.5, "CG to front axle [m], > 0")                                               \
  X(double, b, 1.75, "CG to rear axle [m], > 0")                                               \
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
  X(double, driver_preview_s, 0.6, "driver preview time [s], > 0")                             \
  X(double, driver_preview_min_m, 5.0, "driver shortest preview distance [m], > 0")            \
  X(double, driver_gain, 1.0, "driver gain on the pure-pursuit angle [-], > 0")                \
  X(double, driver_tau_s, 0.05, "steering lag time constant [s], >= 0 (0: none)")              \
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
#define DN_FIELD_DECL_(type, name, def, doc) type name;
typedef struct dn_fullcar_params { DN_FULLCAR_FIELDS(DN_FIELD_DECL_) } dn_fullcar_params;
#undef DN_FIELD_DECL_
/* Fill with the defaults above. */
DN_API void dn_fullcar_default(dn_fullcar_params* p);
/* Validate as dn_fullcar_model_create does: DN_OK, DN_E_NONFINITE_PARAM, DN_E_PARAM (a field
 * out of its documented range, an unknown enum value), DN_E_NULL. */
DN_API int dn_fullcar_check(const dn_fullcar_params* p);
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
/* Per step input, at the END of the step (t + dt). */
typedef struct dn_fullcar_input {
  double z_r[DN_FULLCAR_CORNERS]; /* road under each wheel [m] */
  double v_r[DN_FULLCAR_CORNERS]; /* road rate under each wheel [m/s] */
  double steer;                   /* road-wheel angle [rad] (open_loop; ignored by the driver) */
  double u[DN_FULLCAR_CORNERS];   /* control of a corner whose law is DN_CTRL_EXTERNAL [V] */
} dn_fullcar_input;
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
#define DN_OUT_CORNER_DECL_(name, doc) double name[DN_FULLCAR_CORNERS];
#define DN_OUT_DECL_(name, doc) double name;
typedef struct dn_fullcar_out {
  DN_FULLCAR_OUT_CORNER_LIST(DN_OUT_CORNER_DECL_)
  DN_FULLCAR_OUT_LIST(DN_OUT_DECL_)
  uint32_t clamped_mask[DN_FULLCAR_CORNERS]; /* neural: bit i = input i clamped */
} dn_fullcar_out;
#undef DN_OUT_CORNER_DECL_
#undef DN_OUT_DECL_
/* A validated, immutable full-car model / its mutable state. Opaque. */
typedef struct dn_fullcar_model dn_fullcar_model;
typedef struct dn_fullcar_data dn_fullcar_data;
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

#undef DN_ENUM_ROW_

#ifdef __cplusplus
}
#endif

#endif /* DAMPNET_H */
