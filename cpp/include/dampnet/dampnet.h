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

/*---- Version ----*/

#define DN_VERSION_MAJOR 0
#define DN_VERSION_MINOR 1
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
  X(DN_E_NULL, -1, "a required pointer argument was NULL")                                   \
  X(DN_E_SIZE, -2, "a size is out of range (inputs 1..8, hidden 1..64, layers 1..2)")        \
  X(DN_E_NONFINITE_PARAM, -3, "a model parameter is NaN or infinite")                        \
  X(DN_E_PARAM, -4, "a parameter is out of its valid range")                                 \
  X(DN_E_ACTIVATION, -5, "unknown activation (expected DN_ACT_TANH or DN_ACT_SIGMOID)")     \
  X(DN_E_ALLOC, -6, "out of memory while creating an object")                                \
  X(DN_E_NONFINITE_OUTPUT, -7,                                                               \
    "the output overflowed to a non-finite value; it was replaced by the output offset")     \
  X(DN_E_MISMATCH, -8, "the model does not match the sizes or features it is used with")

#define DN_STATUS_ENUM_(name, value, text) name = value,
typedef enum dn_status { DN_STATUS_LIST(DN_STATUS_ENUM_) } dn_status;
#undef DN_STATUS_ENUM_

/* A human-readable explanation of a status (an OR of warnings is explained too). Never NULL. */
DN_API const char* dn_status_str(int status);

/*---- The MLP ----*/

#define DN_MAX_INPUTS 8        /* inputs per model */
#define DN_MAX_HIDDEN 64       /* neurons per hidden layer */
#define DN_MAX_HIDDEN_LAYERS 2 /* hidden layers */

/* Hidden-layer activation; the output layer is always linear. */
typedef enum dn_activation {
  DN_ACT_TANH = 0,    /* tanh(x) (MATLAB's tansig) */
  DN_ACT_SIGMOID = 1  /* 1 / (1 + exp(-x)) (MATLAB's logsig) */
} dn_activation;

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
 * return DN_OK and *out set, or a DN_E_* error with *out = NULL. */
DN_API int dn_mlp_create(const dn_mlp_desc* desc, dn_mlp** out);

/* Destroy a model. Nullable: m. */
DN_API void dn_mlp_destroy(dn_mlp* m);

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

#ifdef __cplusplus
}
#endif

#endif /* DAMPNET_H */
