/* dampnet types: the enums and structs of the C ABI, its opaque handles and its constants.
 *
 * Part of the C ABI; include "dampnet/dampnet.h", which includes this. C99 and C++. The enums
 * and most structs are expanded from the X-macro lists of dn_xmacro.h; the functions taking
 * them are declared in dampnet.h. */
#ifndef DAMPNET_DN_TYPES_H
#define DAMPNET_DN_TYPES_H

#include <stdint.h>

#include "dampnet/dn_config.h"
#include "dampnet/dn_xmacro.h"

#ifdef __cplusplus
extern "C" {
#endif

/* An enum list's rows X(id, value, "name", doc) as enumerators (see dn_xmacro.h). */
#define DN_ENUM_ROW_(id, value, name, doc) id = value,

/*---- Status codes ----*/

#define DN_STATUS_ENUM_(name, value, text) name = value,
typedef enum dn_status { DN_STATUS_LIST(DN_STATUS_ENUM_) } dn_status;
#undef DN_STATUS_ENUM_

/*---- The MLP ----*/

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
  int n_hidden2;           /* neurons in hidden layer 2, 0 (no second layer) or 1..DN_MAX_HIDDEN2 */
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
  int n_hidden2;           /* neurons in hidden layer 2, 0 (no second layer) or 1..DN_MAX_HIDDEN2 */
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

/*---- Training envelope: a bounded-time "is the model guessing here?" flag ----*/

/* The coarse joint envelope of a model's training data (dampnet.envelope.grid writes it; a
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

/*---- Damper models ----*/

#define DN_FPARAM_ENUM_(id, name, text) id,
/* DN_FPARAM_NONE: a feature that needs no parameter (DN_FEATURE_LIST's last column). */
typedef enum dn_feature_param {
  DN_FPARAM_NONE = -1,
  DN_FEATURE_PARAM_LIST(DN_FPARAM_ENUM_) DN_N_FEATURE_PARAMS
} dn_feature_param;
#undef DN_FPARAM_ENUM_

#define DN_INPUT_DECL_(type, name, role, doc) type name;
typedef struct dn_damper_input { DN_DAMPER_INPUT_FIELDS(DN_INPUT_DECL_) } dn_damper_input;
#undef DN_INPUT_DECL_

#define DN_FEATURE_ENUM_(id, name, field, param) id,
typedef enum dn_feature { DN_FEATURE_LIST(DN_FEATURE_ENUM_) DN_N_FEATURES } dn_feature;
#undef DN_FEATURE_ENUM_

typedef enum dn_state_dynamics { DN_STATE_DYNAMICS_LIST(DN_ENUM_ROW_) } dn_state_dynamics;
#define DN_DS_ENUM_(id, name, unit, dyn, source, param, doc) id,
/* The damper's states (DN_DAMPER_STATE_LIST): index in its block; DN_DAMPER_STATE_SIZE of them. */
typedef enum dn_damper_state { DN_DAMPER_STATE_LIST(DN_DS_ENUM_) DN_DAMPER_STATE_SIZE } dn_damper_state;
#undef DN_DS_ENUM_

#define DN_TERM_ENUM_(id, value, name, n_params, text) id = value,
typedef enum dn_term_kind { DN_TERM_LIST(DN_TERM_ENUM_) DN_N_TERM_KINDS } dn_term_kind;
#undef DN_TERM_ENUM_

typedef enum dn_damper_kind { DN_DAMPER_KIND_LIST(DN_ENUM_ROW_) } dn_damper_kind;
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

/* The inverse (dn_damper_inverse): at most DN_INVERSE_MAX_ITERS force evaluations after the two
 * at the control limits (and the steps from its first iterate before those); it stops once the bracket around the control is narrower than
 * DN_INVERSE_TOL_REL times the control range (u_max - u_min), or a step is, or the Newton step
 * the last evaluation asks for is (the control is then within that of the root: the force
 * within DN_INVERSE_TOL_REL * (u_max - u_min) * |dF/du| of the demand), or the force equals
 * the demand to its own rounding (8 epsilons of the larger limit force: float's for a float
 * model, and for that at least a float epsilon of |b_out| + sum |w_out|, the largest sum its
 * output can make: the float force's jitter in u, 2.0e-3 N for the default model). */
#define DN_INVERSE_MAX_ITERS 44
#define DN_INVERSE_TOL_REL 1e-6
/* dn_damper_inverse_near: at most DN_INVERSE_WARM_EVALS Newton steps from the given control
 * before the search from the limits (a start near the answer usually needs 2). */
#define DN_INVERSE_WARM_EVALS 4

/* dn_damper_control_monotonicity's report: where the force turns back in the control. */
typedef struct dn_monotonicity {
  int n_reversed;     /* velocities of the scan at which F(u) turns back by more than the tolerance [-] */
  dn_real v_worst;    /* the velocity of the largest reversal [m/s] */
  dn_real u_from;     /* F(u) runs against its direction (that of F(u_max) - F(u_min)) from here ... */
  dn_real u_to;       /* ... to here [V or A] */
  dn_real reversal_N; /* by this much [N]; 0 when F is monotone in u at every velocity scanned */
} dn_monotonicity;
#define DN_MONOTONICITY_MAX_GRID 4096 /* n_v and n_u of a scan, at most */

/* A damper model: immutable once handed to a loop model (which copies it). Opaque. */
typedef struct dn_damper dn_damper;

/*---- Controllers ----*/

typedef enum dn_controller_kind { DN_CONTROLLER_KIND_LIST(DN_ENUM_ROW_) } dn_controller_kind;

#define DN_FIELD_DECL_(type, name, def, doc) type name;
typedef struct dn_controller { DN_CONTROLLER_FIELDS(DN_FIELD_DECL_) } dn_controller;

/*---- The quarter-car loop ----*/

typedef enum dn_integrator { DN_INTEGRATOR_LIST(DN_ENUM_ROW_) } dn_integrator;
typedef enum dn_damper_eval { DN_DAMPER_EVAL_LIST(DN_ENUM_ROW_) } dn_damper_eval;
/* The default: per stage, or per step in a build without it (DN_DAMPER_EVALS). */
#define DN_EVAL_DEFAULT ((DN_DAMPER_EVALS & (1 << DN_EVAL_PER_STAGE)) ? DN_EVAL_PER_STAGE : DN_EVAL_PER_STEP)
typedef enum dn_accel_feature { DN_ACCEL_FEATURE_LIST(DN_ENUM_ROW_) } dn_accel_feature;
#define DN_ACCEL_MAX_EVALS 6 /* damper evaluations per implicit solve, at most */
/* The default scheme: implicit, or linear in a build without it (DN_ACCEL_FEATURES). */
#define DN_ACCEL_DEFAULT ((DN_ACCEL_FEATURES & (1 << DN_ACCEL_IMPLICIT)) ? DN_ACCEL_IMPLICIT : DN_ACCEL_LINEAR)
/* Smallest g' = 1 + k dF/da at which DN_ACCEL_LINEAR takes its Newton step (see DN_ACCEL_FEATURE_LIST). */
#define DN_ACCEL_LINEAR_MIN_SLOPE 0.5

typedef struct dn_vehicle { DN_VEHICLE_FIELDS(DN_FIELD_DECL_) } dn_vehicle;
#undef DN_FIELD_DECL_

/* Per step input: the road at the END of the step (t + dt) and an external control. */
typedef struct dn_loop_input {
  dn_real z_r; /* road displacement at t + dt [m] */
  dn_real v_r; /* road rate at t + dt [m/s] */
  dn_real u;   /* control for DN_CTRL_EXTERNAL [V]; ignored by the other laws */
} dn_loop_input;

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

/*---- The full vehicle ----*/
#if !DN_LOOP_FLOAT /* the full vehicle is built with double only (DN_LOOP_FLOAT: dn_config.h) */
#define DN_FULLCAR_CORNERS 4
#define DN_FULLCAR_MAX_PATH 256 /* points of the driver's path */
typedef enum dn_tyre_model { DN_TYRE_MODEL_LIST(DN_ENUM_ROW_) } dn_tyre_model;
typedef enum dn_steer_mode { DN_STEER_MODE_LIST(DN_ENUM_ROW_) } dn_steer_mode;
#define DN_FIELD_DECL_(type, name, def, doc) type name;
typedef struct dn_fullcar_params { DN_FULLCAR_FIELDS(DN_FIELD_DECL_) } dn_fullcar_params;
#undef DN_FIELD_DECL_
/* Per step input, at the END of the step (t + dt). */
typedef struct dn_fullcar_input {
  double z_r[DN_FULLCAR_CORNERS]; /* road under each wheel [m] */
  double v_r[DN_FULLCAR_CORNERS]; /* road rate under each wheel [m/s] */
  double steer;                   /* road-wheel angle [rad] (open_loop; ignored by the driver) */
  double u[DN_FULLCAR_CORNERS];   /* control of a corner whose law is DN_CTRL_EXTERNAL [V] */
} dn_fullcar_input;
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
#endif /* !DN_LOOP_FLOAT */

#undef DN_ENUM_ROW_

#ifdef __cplusplus
}
#endif

#endif /* DAMPNET_DN_TYPES_H */
