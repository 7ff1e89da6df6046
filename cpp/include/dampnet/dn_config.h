/* dampnet build options: the limits, this build's capacities and its configuration macros.
 *
 * Part of the C ABI; include "dampnet/dampnet.h", which includes this. C99 and C++. The
 * defaults below are what a build without compile definitions gets; a build for a small target
 * (the Cortex-M presets of CMakePresets.json, CMake's DAMPNET_* options) overrides them. */
#ifndef DAMPNET_DN_CONFIG_H
#define DAMPNET_DN_CONFIG_H

/*---- The MLP ----*/

#define DN_MAX_INPUTS 8        /* inputs per model */
#define DN_MAX_HIDDEN_LAYERS 2 /* hidden layers */
/* Neurons of hidden layer 1: 64 unless the build raises it (CMake DAMPNET_MAX_HIDDEN, up to
 * DN_MAX_HIDDEN_LIMIT), to hold an averaged network: the mean of k networks of n neurons is one
 * network of k*n (`dampnet train --average k`). Raising it enlarges every MLP object (its layer-1
 * storage), so the default stays small; the Python module is built with 384 (pyproject.toml), and
 * `dampnet export` sizes an FMU's or a firmware's build from the model. Layer 2 keeps at most
 * DN_MAX_HIDDEN2 neurons, so its [H2][H1] storage grows only linearly with DN_MAX_HIDDEN. */
#define DN_MAX_HIDDEN_LIMIT 1024
#define DN_MAX_HIDDEN_DEFAULT 64
#ifndef DN_MAX_HIDDEN
#define DN_MAX_HIDDEN DN_MAX_HIDDEN_DEFAULT
#endif
#if DN_MAX_HIDDEN < 1 || DN_MAX_HIDDEN > DN_MAX_HIDDEN_LIMIT
#error "DN_MAX_HIDDEN: neurons of hidden layer 1, 1..DN_MAX_HIDDEN_LIMIT (1024)"
#endif
#if DN_MAX_HIDDEN < 64
#define DN_MAX_HIDDEN2 DN_MAX_HIDDEN /* neurons of hidden layer 2 */
#else
#define DN_MAX_HIDDEN2 64
#endif

/* Capacities of this build of the library: what its fixed-size objects hold. The defaults are
 * the limits above; a build for a small target lowers them (compile definitions of the library
 * and of every C++ file including its headers: the Cortex-M presets of CMakePresets.json set
 * them from the DAMPNET_CAP_* cache options) so that the objects, dn_*_size() and RAM shrink.
 * Set-up refuses a model beyond them with DN_E_SIZE. C code sees the objects only through
 * pointers, so a C program needs no definitions of its own.
 *   DN_CAP_INPUTS   inputs of an MLP, 1..DN_MAX_INPUTS
 *   DN_CAP_HIDDEN   neurons of hidden layer 1, 1..DN_MAX_HIDDEN
 *   DN_CAP_HIDDEN2  neurons of hidden layer 2, 0 (one hidden layer only)..DN_MAX_HIDDEN2
 *   DN_CAP_TABLE_V, DN_CAP_TABLE_U  lookup-table velocities (2..) and controls (1..)
 *   DN_CAP_TERMS    physics terms per damper, 0..DN_MAX_TERMS
 *   DN_CAP_INVERSE_V, DN_CAP_INVERSE_U  the cold inverse's first-iterate grid of a neural damper
 *                   (dn_damper_inverse): velocities x controls, each 2..64, or both 0 for none
 *                   (then the search starts at the control limits); default 33 x 17, 4.5 KB of
 *                   every damper object; the Cortex-M presets leave it out (no force law linked)
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
#define DN_CAP_HIDDEN2 DN_MAX_HIDDEN2
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

/* The control laws this build runs, a bit mask (bit k: dn_controller_kind k; CMake
 * DAMPNET_CONTROLLER_KINDS, a list of law names). Default: all. A law left out is refused by
 * dn_controller_check and at set-up (DN_E_PARAM); leaving out every force-tracking law
 * (skyhook_force, groundhook_force, hybrid_force, clipped_optimal) keeps the damper's inverse
 * out of the loop's code (the Cortex-M presets: about 3.6 KB of an M4F's flash). The firmware
 * export adds the law it runs (dampnet.export.mcu). */
#ifndef DN_CONTROLLER_KINDS
#define DN_CONTROLLER_KINDS 0x3ff
#endif

/*---- Damper models ----*/

#define DN_MAX_TERMS 8        /* physics terms per damper */
#define DN_MAX_TERM_PARAMS 10 /* parameters per term (the valve's 10) */
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
/* The cold inverse's first-iterate grid (DN_CAP_INVERSE_V above; damper.hpp InverseGuess). */
#define DN_MAX_INVERSE_GRID 64
#ifndef DN_CAP_INVERSE_V
#define DN_CAP_INVERSE_V 33
#endif
#ifndef DN_CAP_INVERSE_U
#define DN_CAP_INVERSE_U 17
#endif
#if (DN_CAP_INVERSE_V == 0) != (DN_CAP_INVERSE_U == 0) || DN_CAP_INVERSE_V == 1 || DN_CAP_INVERSE_U == 1 || \
    DN_CAP_INVERSE_V < 0 || DN_CAP_INVERSE_U < 0 || DN_CAP_INVERSE_V > DN_MAX_INVERSE_GRID ||           \
    DN_CAP_INVERSE_U > DN_MAX_INVERSE_GRID
#error "DN_CAP_INVERSE_V, DN_CAP_INVERSE_U: both 2..64 (DN_MAX_INVERSE_GRID), or both 0 (no first-iterate grid)"
#endif

#endif /* DAMPNET_DN_CONFIG_H */
