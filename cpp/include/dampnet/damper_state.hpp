// The damper's own states (dampnet.h DN_DAMPER_STATE_LIST): their block, and the formulas of
// each kind of dynamics (DN_STATE_DYNAMICS_LIST). The damper owns the update, as MuJoCo's
// actuators own their activations: Damper (damper.hpp) prepares the coefficients of an
// interval (span), advances the block over it (advance), writes it into its input (fill),
// gives its rest value (rest) and its time derivatives (rates, for model exchange). A host
// keeps the block and never names a state.
//
// Within a host's step the states move from their values s0 at the step start, where the
// source was src0, to the evaluation's time T later, where the source is src:
//   lag_held   the source held at src0 (the control):   s = src0 + (s0 - src0) A
//   lag_ramp   the source a ramp from src0 to src (a motion quantity), exact first-order hold:
//              s = A s0 + (1 - A) src0 + (src - src0) (1 - tau (1 - A) / T)
//   dahl       along the source's net travel dx = src - src0 (a reversal inside one interval
//              counts only its net travel):  s = sg + (s0 - sg) exp(-|dx| / x_c), sg = sgn(dx)
// with A = exp(-T/tau). They match python/dampnet/features.py's training columns as the
// sample time goes to 0. Without its parameter a lag follows its source and a Dahl state stays.
#pragma once

#include <cmath>

#include "dampnet/dampnet.h"
#include "dampnet/real.hpp"

namespace dampnet {

enum DamperStateIndex {
#define DN_DS_INDEX_(id, name, unit, dyn, source, param, doc) DS_##name = id,
  DN_DAMPER_STATE_LIST(DN_DS_INDEX_)
#undef DN_DS_INDEX_
};

// The damper's state block: a host keeps DN_DAMPER_STATE_SIZE values per damper.
struct DamperState {
  real s[DN_DAMPER_STATE_SIZE] = {};

  static DamperState load(const real* from) noexcept {
    DamperState b;
    for (int k = 0; k < DN_DAMPER_STATE_SIZE; ++k) b.s[k] = from[k];
    return b;
  }
  void store(real* to) const noexcept {
    for (int k = 0; k < DN_DAMPER_STATE_SIZE; ++k) to[k] = s[k];
  }
};

// The coefficients of the states' update over an interval of T seconds (Damper::span): a host
// with a fixed step prepares its intervals (dt / 2 and dt) once.
struct DamperSpan {
  real keep[DN_DAMPER_STATE_SIZE] = {};  // lags: A = exp(-T/tau) (0 without the lag)
  real gain[DN_DAMPER_STATE_SIZE] = {};  // lag_ramp: 1 - tau (1 - A) / T; dahl: 1 / x_c
};

namespace dynamics {

// One kind of dynamics: its coefficients over T (p > 0 its parameter), its update from s0, its
// rest value at source value src, its time derivative (v: the relative velocity, the rate of x).
template <int Kind>
struct Rule;

template <>
struct Rule<DN_DYN_LAG_HELD> {
  static void coefficients(real p, real T, real& keep, real&) noexcept { keep = std::exp(-T / p); }
  static real advance(bool on, real s0, real src0, real, real keep, real) noexcept {
    return on ? src0 + (s0 - src0) * keep : src0;
  }
  static real rest(real src) noexcept { return src; }
  static real rate(real s, real src, real, real p) noexcept { return (src - s) / p; }
};

template <>
struct Rule<DN_DYN_LAG_RAMP> {
  static void coefficients(real p, real T, real& keep, real& gain) noexcept {
    const real c = -std::expm1(-T / p);  // 1 - A from expm1: exact also for tau >> T
    keep = 1 - c;
    gain = 1 - p * c / T;
  }
  static real advance(bool on, real s0, real src0, real src, real keep, real gain) noexcept {
    return on ? keep * s0 + (1 - keep) * src0 + (src - src0) * gain : src;
  }
  static real rest(real src) noexcept { return src; }
  static real rate(real s, real src, real, real p) noexcept { return (src - s) / p; }
};

template <>
struct Rule<DN_DYN_DAHL> {
  static void coefficients(real p, real, real&, real& gain) noexcept { gain = 1 / p; }
  static real advance(bool on, real s0, real src0, real src, real, real inv_p) noexcept {
    if (!on) return s0;
    const real dx = src - src0;
    if (dx == 0) return s0;
    const real sg = dx > 0 ? 1 : -1;
    return sg + (s0 - sg) * std::exp(-std::fabs(dx) * inv_p);
  }
  static real rest(real) noexcept { return 0; }
  static real rate(real s, real, real v, real p) noexcept { return (v - std::fabs(v) * s) / p; }
};

}  // namespace dynamics
}  // namespace dampnet
