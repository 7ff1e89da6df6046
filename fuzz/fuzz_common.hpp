// Shared pieces of the libFuzzer harnesses over the C ABI (dampnet.h): decoding
// fuzz bytes into parameters that reach deep into validation (a mix of ordinary,
// boundary and non-finite values, not only raw bit patterns), building MLPs and
// dampers from them, and the checks every harness makes (abort() on a violated
// API promise, so libFuzzer records the input as a crash).
#pragma once

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <fuzzer/FuzzedDataProvider.h>

#include "dampnet/dampnet.h"

namespace dn_fuzz {

// A violated API promise: report and abort (libFuzzer saves the input).
[[noreturn]] inline void fail(const char* what, const char* call, int status) {
  std::fprintf(stderr, "dn_fuzz: API contract violated: %s (call %s, status %d: %s)\n", what, call,
               status, dn_status_str(status));
  std::abort();
}

inline void check_finite(double v, const char* what, const char* call, int status) {
  if (!std::isfinite(v)) fail(what, call, status);
}

// A double from the fuzz bytes: one selector byte picks a class, so that
// ordinary values, limits and non-finite values are all reached often.
inline double value(FuzzedDataProvider& f) {
  switch (f.ConsumeIntegralInRange<int>(0, 15)) {
    case 0: return 0.0;
    case 1: return -0.0;
    case 2: return NAN;
    case 3: return INFINITY;
    case 4: return -INFINITY;
    case 5: return f.ConsumeBool() ? DBL_MAX : -DBL_MAX;
    case 6: return f.ConsumeBool() ? DBL_MIN * 0.5 : 1e-320;          // denormals
    case 7: return f.ConsumeBool() ? 3.5e38 : -3.5e38;               // just over float's range
    case 8: {                                                         // raw bits
      uint64_t b = f.ConsumeIntegral<uint64_t>();
      double d;
      std::memcpy(&d, &b, sizeof d);
      return d;
    }
    case 9: return std::ldexp(f.ConsumeIntegralInRange<int>(-1000, 1000),  // any magnitude
                              f.ConsumeIntegralInRange<int>(-1080, 1030));
    default:  // ordinary values, the most common: [-100, 100] in steps of 1/1000
      return f.ConsumeIntegralInRange<int>(-100000, 100000) / 1000.0;
  }
}

// A positive "physical" value (mass, stiffness, dt, ...) near a typical scale most of the time.
inline double positive(FuzzedDataProvider& f, double typical) {
  if (f.ConsumeIntegralInRange<int>(0, 3) == 0) return value(f);
  return typical * f.ConsumeIntegralInRange<int>(1, 4000) / 1000.0;
}

// A small integer, mostly in [lo, hi], sometimes anything (sizes, enums).
inline int small_int(FuzzedDataProvider& f, int lo, int hi) {
  if (f.ConsumeIntegralInRange<int>(0, 15) == 0) return f.ConsumeIntegral<int>();
  return f.ConsumeIntegralInRange<int>(lo, hi);
}

// n values into a heap array of exactly n elements (ASan catches any read past it).
inline std::vector<double> values(FuzzedDataProvider& f, int n) {
  std::vector<double> v(n > 0 ? size_t(n) : 0);
  for (double& x : v) x = value(f);
  return v;
}

// A name: one of the known ones most of the time, else arbitrary bytes (any length).
inline std::string name(FuzzedDataProvider& f, const std::vector<const char*>& known) {
  if (!known.empty() && f.ConsumeIntegralInRange<int>(0, 7) != 0)
    return known[f.ConsumeIntegralInRange<size_t>(0, known.size() - 1)];
  return f.ConsumeRandomLengthString(24);
}

inline const std::vector<const char*>& feature_names() {
  static const std::vector<const char*> v = {
#define DN_FUZZ_FEAT_(id, nm, field, param) nm,
      DN_FEATURE_LIST(DN_FUZZ_FEAT_)
#undef DN_FUZZ_FEAT_
  };
  return v;
}
inline const std::vector<const char*>& feature_param_names() {
  static const std::vector<const char*> v = {
#define DN_FUZZ_FP_(id, nm, text) nm,
      DN_FEATURE_PARAM_LIST(DN_FUZZ_FP_)
#undef DN_FUZZ_FP_
  };
  return v;
}
inline const std::vector<const char*>& term_names() {
  static const std::vector<const char*> v = {
#define DN_FUZZ_TERM_(id, val, nm, n, text) nm,
      DN_TERM_LIST(DN_FUZZ_TERM_)
#undef DN_FUZZ_TERM_
  };
  return v;
}

// The storage behind a dn_mlp_desc decoded from fuzz bytes. Arrays are sized to
// what the descriptor claims (see cap() in decode()).
struct MlpDescBuf {
  std::vector<double> w1, b1, w2, b2, w_out, b_out, in_offset, in_gain, sat_lo, sat_hi;
  dn_mlp_desc d{};

  void decode(FuzzedDataProvider& f) {
    d.n_inputs = small_int(f, 1, DN_MAX_INPUTS);
    d.n_hidden1 = small_int(f, 1, 12);
    d.n_hidden2 = f.ConsumeBool() ? 0 : small_int(f, 0, 12);
    d.activation = small_int(f, 0, 1);
    // A size beyond the limits gets one-element arrays: the library must refuse it
    // before reading them (ASan reports any read past them).
    auto cap = [](int n, int max) { return n < 0 ? 0 : (n > max ? 1 : n); };
    const int ni = cap(d.n_inputs, DN_MAX_INPUTS), h1 = cap(d.n_hidden1, DN_MAX_HIDDEN),
              h2 = cap(d.n_hidden2, DN_MAX_HIDDEN2);
    const int n_last = d.n_hidden2 > 0 ? h2 : h1;
    // Weights: mostly ordinary (scaled into a typical trained range), sometimes anything.
    const bool wild = f.ConsumeIntegralInRange<int>(0, 3) == 0;
    auto weights = [&](int n) {
      std::vector<double> v(static_cast<size_t>(n));
      for (double& x : v) x = wild ? value(f) : f.ConsumeIntegralInRange<int>(-3000, 3000) / 1000.0;
      return v;
    };
    w1 = weights(h1 * ni);
    b1 = weights(h1);
    w2 = weights(h2 * h1);
    b2 = weights(h2);
    w_out = weights(n_last);
    b_out = weights(1);
    in_offset = values(f, ni);
    in_gain = values(f, ni);
    sat_lo = values(f, ni);
    sat_hi = values(f, ni);
    if (f.ConsumeBool())  // a valid range most of the time: lo < hi, around the offset
      for (int i = 0; i < ni; ++i) {
        if (sat_lo[i] > sat_hi[i]) std::swap(sat_lo[i], sat_hi[i]);
      }
    d.in_ymin = f.ConsumeBool() ? -1.0 : value(f);
    d.out_offset = value(f);
    d.out_gain = f.ConsumeBool() ? 1.0 / positive(f, 1000.0) : value(f);
    d.out_ymin = f.ConsumeBool() ? -1.0 : value(f);
    d.w1 = w1.data();
    d.b1 = b1.data();
    d.w2 = d.n_hidden2 > 0 ? w2.data() : nullptr;
    d.b2 = d.n_hidden2 > 0 ? b2.data() : nullptr;
    d.w_out = w_out.data();
    d.b_out = b_out.data();
    d.in_offset = in_offset.data();
    d.in_gain = in_gain.data();
    d.sat_lo = sat_lo.data();
    d.sat_hi = sat_hi.data();
    // Occasionally a NULL where an array is required (or a zero-size array's NULL data()).
    if (f.ConsumeIntegralInRange<int>(0, 31) == 0) {
      const double** ptrs[] = {&d.w1, &d.b1, &d.w2, &d.b2, &d.w_out, &d.b_out,
                               &d.in_offset, &d.in_gain, &d.sat_lo, &d.sat_hi};
      *ptrs[f.ConsumeIntegralInRange<int>(0, 9)] = nullptr;
    }
  }
};

// A damper of any kind decoded from fuzz bytes (or nullptr when creation failed,
// which is checked to leave *out NULL). The MLP of a neural damper is kept alive
// by the caller through *mlp (destroyed after the damper, as a user might).
inline double callback_force(void* user, const dn_damper_input* in) {
  // A user function: a fixed value chosen by the fuzzer (possibly non-finite) plus c v.
  const double* p = static_cast<const double*>(user);
  return p[0] + p[1] * in->v;
}

struct DamperBuf {
  MlpDescBuf mlp_desc;
  dn_mlp* mlp = nullptr;
  dn_damper* damper = nullptr;
  double cb_user[2] = {0, 0};
  std::vector<std::string> feat_storage, pname_storage;

  ~DamperBuf() {
    dn_damper_destroy(damper);
    dn_mlp_destroy(mlp);
  }

  // Returns the status of the creation (terms are added after a successful one).
  int create(FuzzedDataProvider& f, bool allow_callback) {
    const int kind = f.ConsumeIntegralInRange<int>(0, allow_callback ? 4 : 3);
    int st = DN_E_PARAM;
    switch (kind) {
      case DN_DAMPER_LINEAR:
        st = dn_damper_create_linear(f.ConsumeBool() ? positive(f, 1500.0) : value(f), &damper);
        break;
      case DN_DAMPER_PARAMETRIC: {
        dn_parametric_params p;
        const bool typical = f.ConsumeBool();
        p.c_min = typical ? positive(f, 500.0) : value(f);
        p.c_max = typical ? p.c_min + positive(f, 3000.0) : value(f);
        p.gamma = typical ? positive(f, 1000.0) : value(f);
        p.f0 = typical ? positive(f, 50.0) : value(f);
        p.v_max = typical ? positive(f, 5.0) : value(f);
        p.v_smooth = f.ConsumeBool() ? 0.0 : (typical ? positive(f, 0.01) : value(f));
        st = dn_damper_create_parametric(f.ConsumeIntegralInRange<int>(0, 31) ? &p : nullptr, &damper);
        break;
      }
      case DN_DAMPER_TABLE: {
        const int n_v = small_int(f, 0, 10), n_u = small_int(f, 0, 4);
        // Sizes beyond the limits get one-element arrays (refused before any read).
        const auto cap = [](int n, int max) { return n < 0 ? 0 : (n > max ? 1 : n); };
        std::vector<double> vs(size_t(cap(n_v, DN_MAX_TABLE_V))), us(size_t(cap(n_u, DN_MAX_TABLE_U))),
            fs(size_t(cap(n_v, DN_MAX_TABLE_V) * cap(n_u, DN_MAX_TABLE_U)));
        const bool sorted = f.ConsumeBool();
        double acc = -1.0;
        for (double& v : vs) v = sorted ? (acc += positive(f, 0.1)) : value(f);
        acc = -1.0;
        for (double& u : us) u = sorted ? (acc += positive(f, 1.0)) : value(f);
        for (double& x : fs) x = f.ConsumeBool() ? value(f) : f.ConsumeIntegralInRange<int>(-5000, 5000);
        // A size within the limits is never larger than its array (no overread by the
        // harness itself); a size beyond the limits is passed as it is.
        const int pass_v = n_v, pass_u = n_u;
        st = dn_damper_create_table(vs.empty() ? nullptr : vs.data(), pass_v,
                                    us.empty() ? nullptr : us.data(), pass_u,
                                    fs.empty() ? nullptr : fs.data(), &damper);
        break;
      }
      case DN_DAMPER_NEURAL: {
        mlp_desc.decode(f);
        const int mst = dn_mlp_create(&mlp_desc.d, &mlp);
        if ((mst == DN_OK) != (mlp != nullptr)) fail("dn_mlp_create: *out NULL iff error", "dn_mlp_create", mst);
        const int n_feat = small_int(f, 0, DN_MAX_INPUTS);
        const int n_par = small_int(f, 0, 4);
        const int nf = n_feat < 0 ? 0 : (n_feat > 16 ? 16 : n_feat);
        const int np = n_par < 0 ? 0 : (n_par > 8 ? 8 : n_par);
        feat_storage.clear();
        pname_storage.clear();
        for (int i = 0; i < nf; ++i) feat_storage.push_back(name(f, feature_names()));
        for (int i = 0; i < np; ++i) pname_storage.push_back(name(f, feature_param_names()));
        std::vector<const char*> feats, pnames;
        for (auto& s : feat_storage) feats.push_back(s.c_str());
        for (auto& s : pname_storage) pnames.push_back(s.c_str());
        std::vector<double> pvals(static_cast<size_t>(np));
        for (double& v : pvals) v = f.ConsumeBool() ? positive(f, 0.01) : value(f);
        const int pass_f = n_feat > nf ? nf : n_feat;
        const int pass_p = n_par > np ? np : n_par;
        const int precision = small_int(f, 0, 1);
        // A NULL model is an error too; creating from it is part of the contract.
        st = dn_damper_create_neural(mlp, feats.empty() ? nullptr : feats.data(), pass_f,
                                     pnames.empty() ? nullptr : pnames.data(),
                                     pvals.empty() ? nullptr : pvals.data(), pass_p, precision,
                                     &damper);
        break;
      }
      default:
        cb_user[0] = f.ConsumeBool() ? value(f) : 0.0;
        cb_user[1] = positive(f, 1500.0);
        st = dn_damper_create_callback(&callback_force, cb_user, &damper);
        break;
    }
    if ((st == DN_OK) != (damper != nullptr)) fail("damper create: *out NULL iff error", "dn_damper_create_*", st);
    if (st != DN_OK) return st;
    if (dn_damper_kind_of(damper) != kind) fail("dn_damper_kind_of differs from the created kind", "dn_damper_kind_of", st);
    // Terms: any kind name, any parameter count (the array holds exactly what is passed).
    const int n_terms = f.ConsumeIntegralInRange<int>(0, 10);
    for (int t = 0; t < n_terms; ++t) {
      const std::string kind_name = name(f, term_names());
      const int n_params = small_int(f, 0, 5);
      const int np = n_params < 0 ? 0 : (n_params > 16 ? 16 : n_params);
      std::vector<double> p(static_cast<size_t>(np));
      for (double& v : p) v = f.ConsumeBool() ? f.ConsumeIntegralInRange<int>(-20000, 20000) / 100.0 : value(f);
      dn_damper_add_term(damper, kind_name.c_str(), p.empty() ? nullptr : p.data(),
                         n_params > np ? np : n_params);
    }
    return st;
  }
};

// A damper input: mostly ordinary values, any field may be anything.
inline dn_damper_input damper_input(FuzzedDataProvider& f) {
  dn_damper_input in;
  std::memset(&in, 0, sizeof in);
  auto pick = [&](double typical) {
    return f.ConsumeIntegralInRange<int>(0, 3) == 0 ? value(f)
                                                    : typical * f.ConsumeIntegralInRange<int>(-2000, 2000) / 1000.0;
  };
  in.x = pick(0.1);
  in.v = pick(1.0);
  in.a = pick(50.0);
  in.u = pick(5.0);
  in.u_lag = pick(5.0);
  in.temperature = pick(40.0);
  in.t = pick(10.0);
  in.dt = pick(0.001);
  in.stage = small_int(f, 0, 3);
  in.v_lag = pick(1.0);
  in.z_fric = pick(1.0);
  return in;
}

}  // namespace dn_fuzz
