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

namespace dynamics {

// One kind of dynamics: its coefficients over T (p > 0 its parameter), its update from s0, its
// rest value at source value src, its time derivative (v: the relative velocity, the rate of x).
template <int Kind>
struct Rule;

template <>
struct Rule<DN_DYN_LAG_HELD> {
  static constexpr bool kKeep = true, kGain = false;  // the coefficients it uses
  static void coefficients(real p, real T, real& keep, real&) noexcept { keep = std::exp(-T / p); }
  static real advance(bool on, real s0, real src0, real, real keep, real) noexcept {
    return on ? src0 + (s0 - src0) * keep : src0;
  }
  static real rest(real src) noexcept { return src; }
  static real rate(real s, real src, real, real p) noexcept { return (src - s) / p; }
};

template <>
struct Rule<DN_DYN_LAG_RAMP> {
  static constexpr bool kKeep = true, kGain = true;
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
  static constexpr bool kKeep = false, kGain = true;
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

// Where state id's coefficients sit in a DamperSpan: only those its dynamics uses (a lag_held
// state has a keep, a lag_ramp a keep and a gain, a dahl state a gain), packed in the states'
// order, so that the span is as small as the old named coefficients (the firmware's RAM).
namespace span_layout {
constexpr bool kUsesKeep[] = {
#define DN_DS_USES_KEEP_(id, name, unit, dyn, source, param, doc) dynamics::Rule<dyn>::kKeep,
    DN_DAMPER_STATE_LIST(DN_DS_USES_KEEP_)
#undef DN_DS_USES_KEEP_
};
constexpr bool kUsesGain[] = {
#define DN_DS_USES_GAIN_(id, name, unit, dyn, source, param, doc) dynamics::Rule<dyn>::kGain,
    DN_DAMPER_STATE_LIST(DN_DS_USES_GAIN_)
#undef DN_DS_USES_GAIN_
};
constexpr int start(int id) noexcept {
  int n = 0;
  for (int k = 0; k < id; ++k) n += int(kUsesKeep[k]) + int(kUsesGain[k]);
  return n;
}
constexpr int keep_at(int id) noexcept { return kUsesKeep[id] ? start(id) : -1; }
constexpr int gain_at(int id) noexcept { return kUsesGain[id] ? start(id) + int(kUsesKeep[id]) : -1; }
constexpr int kSize = start(DN_DAMPER_STATE_SIZE);
}  // namespace span_layout

// The coefficients of the states' update over an interval of T seconds (Damper::span): a host
// with a fixed step prepares its intervals (dt / 2 and dt) once. keep: a lag's A = exp(-T/tau)
// (0 without the lag); gain: lag_ramp's 1 - tau (1 - A) / T, dahl's 1 / x_c; a coefficient the
// state's dynamics does not use is not stored (reads 0).
struct DamperSpan {
  real c[span_layout::kSize > 0 ? span_layout::kSize : 1] = {};

  template <int id>
  real keep() const noexcept {
    if constexpr (span_layout::keep_at(id) >= 0) return c[span_layout::keep_at(id)];
    else return real(0);
  }
  template <int id>
  real gain() const noexcept {
    if constexpr (span_layout::gain_at(id) >= 0) return c[span_layout::gain_at(id)];
    else return real(0);
  }
  // The slot of state id's keep / gain, or `spare` when its dynamics has none.
  template <int id>
  real& keep_slot(real& spare) noexcept {
    if constexpr (span_layout::keep_at(id) >= 0) return c[span_layout::keep_at(id)];
    else return spare;
  }
  template <int id>
  real& gain_slot(real& spare) noexcept {
    if constexpr (span_layout::gain_at(id) >= 0) return c[span_layout::gain_at(id)];
    else return spare;
  }
};

}  // namespace dampnet
