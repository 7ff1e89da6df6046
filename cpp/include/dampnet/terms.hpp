// Physics terms of hybrid dampers: one table, keyed by the kind names of
// DN_TERM_LIST (dampnet.h). Mirrored in numpy by python/dampnet/terms.py.
//
// To add a kind: one DN_TERM_LIST line in dampnet.h, and here one force
// function and one validation function named after the kind's id.
#pragma once

#include <cmath>
#include <cstring>

#include "dampnet/dampnet.h"
#include "dampnet/real.hpp"

namespace dampnet {

struct Term {
  int kind = 0;
  real p[DN_MAX_TERM_PARAMS] = {};
};

namespace terms {

// ---- position_poly: F = p0 + p1 x + p2 x^2 + p3 x^3 ----
inline real force_DN_TERM_POSITION_POLY(const real* p, const dn_damper_input& in) noexcept {
  const real x = in.x;
  return p[0] + x * (p[1] + x * (p[2] + x * p[3]));
}
inline int validate_DN_TERM_POSITION_POLY(const real*) noexcept { return DN_OK; }

// ---- bump_stop: F = sgn(x) k (|x| - x_free)^n beyond x_free ----
inline real force_DN_TERM_BUMP_STOP(const real* p, const dn_damper_input& in) noexcept {
  const real ax = std::fabs(in.x), over = ax - p[0];
  if (!(over > 0)) return 0;
  const real f = p[1] * std::pow(over, p[2]);
  return in.x > 0 ? f : -f;
}
inline int validate_DN_TERM_BUMP_STOP(const real* p) noexcept {
  return (p[0] >= 0 && p[1] >= 0 && p[2] > 0) ? DN_OK : DN_E_PARAM;
}

struct KindInfo {
  const char* name;
  int n_params;
  real (*force)(const real*, const dn_damper_input&) noexcept;
  int (*validate)(const real*) noexcept;
};

// Indexed by dn_term_kind (values are consecutive from 0).
inline const KindInfo* table() noexcept {
  static const KindInfo t[] = {
#define DN_TERM_ROW_(id, value, name, n, text) {name, n, &force_##id, &validate_##id},
      DN_TERM_LIST(DN_TERM_ROW_)
#undef DN_TERM_ROW_
  };
  return t;
}

// The kind id of a name, or -1.
inline int kind_of(const char* name) noexcept {
  if (!name) return -1;
  for (int k = 0; k < DN_N_TERM_KINDS; ++k)
    if (std::strcmp(table()[k].name, name) == 0) return k;
  return -1;
}

// Validate and fill a term from (kind name, params; each finite also in dn_real).
inline int make(Term& t, const char* kind, const double* params, int n_params) noexcept {
  const int k = kind_of(kind);
  if (k < 0) return DN_E_UNKNOWN_NAME;
  const KindInfo& info = table()[k];
  if (n_params != info.n_params) return DN_E_SIZE;
  if (n_params > 0 && !params) return DN_E_NULL;
  real p[DN_MAX_TERM_PARAMS] = {};
  for (int i = 0; i < n_params; ++i) {
    p[i] = static_cast<real>(params[i]);
    if (!std::isfinite(p[i])) return DN_E_NONFINITE_PARAM;
  }
  const int st = info.validate(p);
  if (st != DN_OK) return st;
  t.kind = k;
  for (int i = 0; i < DN_MAX_TERM_PARAMS; ++i) t.p[i] = p[i];
  return DN_OK;
}

// [RT] Sum of the terms' forces.
inline real sum(const Term* ts, int n, const dn_damper_input& in) noexcept {
  real f = 0;
  for (int i = 0; i < n; ++i) f += table()[ts[i].kind].force(ts[i].p, in);
  return f;
}

}  // namespace terms
}  // namespace dampnet
