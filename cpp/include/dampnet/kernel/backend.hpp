// The MLP kernel's backend: the one place that chooses it.
//
// A backend is one file of kernel/ holding the kernel's dense layers and whatever else it
// does its own way (as RTNeural's dense.h / dense_eigen.h / dense_xsimd.h, chosen in config.h):
//
//   DN_KERNEL_BACKEND   file                 needs                            kernel_isa()
//   scalar              dense_scalar.hpp     nothing (any C++17 target)       "scalar"
//   sse                 dense_sse.hpp        SSE (x86-64's baseline)          "sse"
//   avx2                dense_avx2.hpp       -mavx2 -mfma                     "avx2+fma"
//   avx512              dense_avx512.hpp     -mavx2 -mfma -mavx512f -mavx512vl -mavx512dq   "avx512"
//   eigen               dense_eigen.hpp      Eigen 3 (<Eigen/Core>)           "eigen"
//
// The build says which one with -DDN_KERNEL_BACKEND=NAME; CMake derives it from its options
// (DAMPNET_AVX2, DAMPNET_AVX512, DAMPNET_NATIVE, DAMPNET_USE_EIGEN: docs/build-options.md)
// and passes it to everything it compiles. Unset, the backend is eigen where DAMPNET_USE_EIGEN
// is defined (its older spelling), else sse on a target with SSE and scalar on any other (a
// microcontroller): never a wider one because the compiler flags happen to allow it
// (-march=native). A backend the flags cannot compile stops the build here (static_assert),
// naming the flags it needs.
//
// Every backend defines, in dampnet::DN_KERNEL_NS::detail (mlp.hpp calls them):
//   kSimdFloat        true: the float model is evaluated by forward_simd (AVX2 / AVX-512) and
//                     MlpParams stores its extra tables (tw, inv_w, sat_lo8 ...)
//   kFused1           true: one-hidden-layer models take the fused scalar pass (forward_fused1);
//                     layer 1 is stored at the capacity's stride
//   dense_t, clamp_tanh_args(float*), dot_padded, inputs_in_range
//   kOwnPass<T>       where the backend's own forward pass replaces mlp.hpp's dense + tanh + dot
//                     passes for T models: never, one_layer (one hidden layer) or always
//   forward_own       that pass, after the inputs (b_out included)
//   forward_batch_simd where kSimdFloat: forward_batch's pass over kB samples (forward_simd_batch)
#pragma once

// Flash against speed on scalar cores (dampnet.h, "Capacities"): DN_KERNEL_SMALL 1 compiles
// one float forward, for DN_CAP_INPUTS inputs; DN_KERNEL_UNROLL neurons per pass of it.
#ifndef DN_KERNEL_SMALL
#define DN_KERNEL_SMALL 0
#endif
#ifndef DN_KERNEL_UNROLL
#if DN_KERNEL_SMALL
#define DN_KERNEL_UNROLL 2
#else
#define DN_KERNEL_UNROLL 8
#endif
#endif

#if defined(__clang__) && defined(DN_REALTIME_SANITIZE)
#define DN_REALTIME [[clang::nonblocking]]
#else
#define DN_REALTIME
#endif

// Each forward is one function (not inlined into every caller: the damper's and the loop's
// several call sites would each get a copy, and its stack; a flash-lean build's flash, the
// host's L1i: issue 30).
#if defined(__clang__)
#define DN_KERNEL_OUTLINE __attribute__((noinline))  // (clang has no noclone)
#elif defined(__GNUC__)
#define DN_KERNEL_OUTLINE __attribute__((noinline, noclone))
#else
#define DN_KERNEL_OUTLINE
#endif
// Set-up code of a flash-lean build is optimised for size (GCC): it runs once, and -O3 would
// unroll its copies and checks into kilobytes.
#if DN_KERNEL_SMALL && defined(__GNUC__) && !defined(__clang__)
#define DN_SETUP_SIZE __attribute__((optimize("Os")))
#else
#define DN_SETUP_SIZE
#endif
// The backends' small hooks that mlp.hpp's forward calls (plain inline: always_inline changes
// GCC's early inlining and with it the kernel's block layout).
#define DN_KERNEL_HOOK inline

// The backends' numbers: DN_KERNEL_BACKEND=NAME becomes DN_KERNEL_BACKEND_ID.
#define DN_KERNEL_BACKEND_scalar 1
#define DN_KERNEL_BACKEND_sse 2
#define DN_KERNEL_BACKEND_avx2 3
#define DN_KERNEL_BACKEND_avx512 4
#define DN_KERNEL_BACKEND_eigen 5
#define DN_KERNEL_CAT_(a, b) a##b
#define DN_KERNEL_CAT(a, b) DN_KERNEL_CAT_(a, b)

#if defined(DN_KERNEL_BACKEND)
#define DN_KERNEL_BACKEND_ID DN_KERNEL_CAT(DN_KERNEL_BACKEND_, DN_KERNEL_BACKEND)
#if !(DN_KERNEL_BACKEND_ID >= 1 && DN_KERNEL_BACKEND_ID <= 5)
#error "DN_KERNEL_BACKEND: one of scalar, sse, avx2, avx512, eigen"
#endif
#elif defined(DAMPNET_USE_EIGEN)
#define DN_KERNEL_BACKEND_ID DN_KERNEL_BACKEND_eigen
#elif defined(__SSE__)
#define DN_KERNEL_BACKEND_ID DN_KERNEL_BACKEND_sse
#else
#define DN_KERNEL_BACKEND_ID DN_KERNEL_BACKEND_scalar
#endif

// Per backend: its file, kernel_isa(), the inline namespace its names carry (translation
// units built for different backends never share a function), the alignment of its arrays
// and the multiple its hidden layers are padded to.
#if DN_KERNEL_BACKEND_ID == DN_KERNEL_BACKEND_scalar
#define DN_KERNEL_HEADER "dampnet/kernel/dense_scalar.hpp"
#define DN_KERNEL_ISA "scalar"
#define DN_KERNEL_NS isa_scalar
#define DN_KERNEL_FLAGS_OK true
#elif DN_KERNEL_BACKEND_ID == DN_KERNEL_BACKEND_sse
#define DN_KERNEL_HEADER "dampnet/kernel/dense_sse.hpp"
#define DN_KERNEL_ISA "sse"
#define DN_KERNEL_NS isa_sse
#if defined(__SSE__)
#define DN_KERNEL_FLAGS_OK true
#endif
#elif DN_KERNEL_BACKEND_ID == DN_KERNEL_BACKEND_avx2
#define DN_KERNEL_HEADER "dampnet/kernel/dense_avx2.hpp"
#define DN_KERNEL_ISA "avx2+fma"
#define DN_KERNEL_NS isa_avx2_fma
#if defined(__AVX2__) && defined(__FMA__)
#define DN_KERNEL_FLAGS_OK true
#endif
#elif DN_KERNEL_BACKEND_ID == DN_KERNEL_BACKEND_avx512
#define DN_KERNEL_HEADER "dampnet/kernel/dense_avx512.hpp"
#define DN_KERNEL_ISA "avx512"
#define DN_KERNEL_NS isa_avx512
#define DN_KERNEL_ALIGN 64
#define DN_KERNEL_PAD 16
#if defined(__AVX2__) && defined(__FMA__) && defined(__AVX512F__) && defined(__AVX512VL__) && defined(__AVX512DQ__)
#define DN_KERNEL_FLAGS_OK true
#endif
#else
#define DN_KERNEL_HEADER "dampnet/kernel/dense_eigen.hpp"
#define DN_KERNEL_ISA "eigen"
#define DN_KERNEL_NS isa_eigen
#define DN_KERNEL_FLAGS_OK true
#endif
#ifndef DN_KERNEL_FLAGS_OK
#define DN_KERNEL_FLAGS_OK false
#endif
#ifndef DN_KERNEL_ALIGN
#define DN_KERNEL_ALIGN 32
#endif
#ifndef DN_KERNEL_PAD
#define DN_KERNEL_PAD 8
#endif

static_assert(DN_KERNEL_FLAGS_OK,
              "DN_KERNEL_BACKEND: the compiler flags do not support this backend (sse: an x86 target; "
              "avx2: -mavx2 -mfma; avx512: -mavx2 -mfma -mavx512f -mavx512vl -mavx512dq)");
#if defined(DN_KERNEL_BACKEND) && defined(DAMPNET_USE_EIGEN)
static_assert(DN_KERNEL_BACKEND_ID == DN_KERNEL_BACKEND_eigen,
              "DAMPNET_USE_EIGEN is defined but DN_KERNEL_BACKEND names another backend");
#endif
