// The damper FMU's model: dampnet's damper (the MLP of the generated header "fmu_model.h",
// prefix fmu_model, plus its physics terms) with the derived features' states.
//
// Value references (python/dampnet/export/fmu/damper.py writes the same in modelDescription.xml):
//   0 x [m]  1 v [m/s]  2 a [m/s2]  3 u [control unit]  4 temperature [degC]      inputs
//   5 force [N]                                                                   output (Real)
//   6 status (dampnet status)  7 clamped_mask (bit i: input i clamped)            outputs (Integer)
//   8 envelope_flags (0 inside the training envelope, else DN_ENV_OUTSIDE_* bits)  output (Integer)
//   9 time (FMI 3's independent variable: fmu3.cpp, DNFMU_VR_TIME)
//   30 force_demand [N]                                                           input (the inverse)
//   31 u_command [control unit]  33 force_at_command [N]                          outputs (Real)
//   32 inverse_status (dampnet status of the inverse)                             output (Integer)
//   10 + k   the model's k-th feature constant (names sorted, as in the header)   parameters
//   100 + 10 i + j   parameter j of physics term i                               parameters
//   40 + k   the damper's state k (dampnet.h DN_DAMPER_STATE_LIST: u_lag, v_lag, z_fric, ...;
//            those the model reads)
//   50 + k   its time derivative (model exchange)
//
// The states are the damper's own (damper_state.hpp), updated by the damper exactly as in
// dampnet's quarter-car loop. Co-simulation: between two communication points t0 and t0 + h
// the control is held at its value at t0 and the velocity and displacement move as a ramp to
// the values set at t0 + h, so the states at time t (t0 <= t) with the inputs currently set
// are the damper's advance over T = t - t0 from those at t0; fmi2DoStep / fmi3DoStep commits
// them at the communication point before advancing the time. So the force read at a
// communication point, after setting that point's inputs, is the force the runtime loop
// computes there; a force read after a step before new inputs are set has the inputs held
// over the step. Model exchange: the states are continuous states with the damper's rates.
// Initial states (both interfaces): the damper's rest at the initial inputs (a lag at its
// source, as dampnet.features' training columns start; the Dahl state 0).
// The Integer outputs status, clamped_mask and envelope_flags are discrete variables: in
// co-simulation they are evaluated at the communication point with the inputs set there; in
// model exchange they change only at events (FMI: a discrete variable changes only at an event
// instant): they hold the values of the last event (the end of initialisation, or an event
// mode), and after each completed integrator step the FMU asks for a step event when the
// evaluation at that instant would give other values (step_event, update_discrete).
// The inverse (a controller's door: it sets force_demand and reads u_command): u_command is
// Damper::inverse's control within the model's control range at which the force equals
// force_demand, at the current inputs x, v, a, temperature (u ignored) and the same states as
// the force (states_now); force_at_command the force at u = u_command; inverse_status the
// inverse's status (DN_W_UNREACHABLE: the demand is outside [F(u_min), F(u_max)], u_command the
// nearer limit), a discrete variable as status. A model without a control input (control_range:
// DN_E_MISMATCH) still loads and runs: u_command is 0, force_at_command the force at u = 0 and
// inverse_status DN_E_MISMATCH, none of them an error; the inverse's other errors (a NaN input
// or demand) fail reading u_command and force_at_command, as the force's fail reading force.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <new>

#include "dampnet/damper.hpp"
#include "dampnet/mlp.hpp"
#include "fmu_common.hpp"
#include "fmu_damper_params.hpp"
#include "fmu_model.h"

namespace dnfmu {

class DamperModel {
 public:
  enum Vr : unsigned {
    VR_X = 0, VR_V, VR_A, VR_U, VR_TEMP, VR_FORCE, VR_STATUS, VR_MASK, VR_ENVELOPE,
    VR_DEMAND = 30, VR_U_COMMAND, VR_INV_STATUS, VR_INV_FORCE,  // the inverse
    VR_STATE = 40, VR_DERIV = 50  // the parameters: DamperParams (10 + k, 100 + 10 i + j)
  };
  static constexpr int ST_N = DN_DAMPER_STATE_SIZE;
  static_assert(VR_STATE + ST_N <= VR_DERIV && VR_DERIV + ST_N <= 100, "the damper's states outgrew their value references");
  static_assert(DamperParams::VR_FPARAM + DN_N_FEATURE_PARAMS <= VR_DEMAND && VR_INV_FORCE < VR_STATE &&
                    DNFMU_VR_TIME < DamperParams::VR_FPARAM && DNFMU_VR_TIME > VR_ENVELOPE,
                "the feature constants, the inverse's variables and the states overlap in value references");

  Message message;

  int instantiate() noexcept {
    const dn_mlp_desc desc = FMU_MODEL_DESC_INIT;
    int st = damper_.md.load(&desc);
    if (st == DN_OK) st = damper_.mf.load(&desc);
    if (st == DN_OK) st = load_envelope(envelope_, desc);
    if (st != DN_OK) return message.fail(st, "the model header does not load: %s", status_text(st));
    params_.load_defaults();
    reset();
    st = params_.build(damper_, message);  // the defaults are the trained model's: a failure here is a broken header
    memo_.valid = false;
    if (st < 0) return st;
    for (int s = 0; s < ST_N; ++s) used_[s] = damper_.state_read(s);
    n_states_ = 0;
    for (int s = 0; s < ST_N; ++s)
      if (used_[s]) slot_[n_states_++] = s;
    return DN_OK;
  }

  void reset() noexcept {
    me_ = false;
    latched_ = Discrete{};
    for (double& v : in_) v = 0.0;
    in_[VR_TEMP] = 20.0;
    demand_ = 0.0;
    time_ = t0_ = 0.0;
    for (double& v : x_) v = 0.0;
    for (double& v : start_in_) v = 0.0;
  }

  // Parameters take effect here; the initial states are the steady state at the inputs set.
  int exit_initialization(bool model_exchange) noexcept {
    me_ = model_exchange;
    const int st = params_.build(damper_, message);
    memo_.valid = false;
    if (st < 0) return st;
    dampnet::Damper::rest(input(in_)).store(x_);
    snapshot();
    if (me_) update_discrete();
    return DN_OK;
  }

  bool parameter(unsigned vr) const noexcept { return params_.owns(vr); }
  bool enumeration(unsigned) const noexcept { return false; }

  // Model exchange: the discrete outputs would change at this instant (a step event), and
  // their update in event mode.
  bool step_event() const noexcept { return me_ && !(discrete_now() == latched_); }
  void update_discrete() noexcept { latched_ = discrete_now(); }

  int get_real(unsigned vr, double* value) noexcept {
    if (vr <= VR_TEMP) {
      *value = in_[vr];
      return DN_OK;
    }
    if (vr == VR_FORCE) {
      uint32_t mask = 0;
      const int st = evaluate(value, &mask);
      return st < 0 ? message.fail(st, "the force cannot be evaluated at t = %g s: %s", time_, status_text(st)) : DN_OK;
    }
    if (vr == VR_DEMAND) {
      *value = demand_;
      return DN_OK;
    }
    if (vr == VR_U_COMMAND || vr == VR_INV_FORCE) {
      double u = 0.0, f = 0.0;
      const int st = command(&u, vr == VR_INV_FORCE ? &f : nullptr);
      if (st < 0)
        return message.fail(st, "%s cannot be evaluated at t = %g s (force_demand = %g N): %s",
                            vr == VR_U_COMMAND ? "u_command" : "force_at_command", time_, demand_, status_text(st));
      *value = vr == VR_U_COMMAND ? u : f;
      return DN_OK;
    }
    if (const double* p = params_.find(vr)) {
      *value = *p;
      return DN_OK;
    }
    const int s = state_of(vr, VR_STATE);
    if (s >= 0) {
      double st[ST_N];
      states_now(st);
      *value = st[s];
      return DN_OK;
    }
    const int d = state_of(vr, VR_DERIV);
    if (d >= 0) {
      double st[ST_N], dx[ST_N];
      states_now(st);
      rates(st, dx);
      *value = dx[d];
      return DN_OK;
    }
    return no_such(message, "Real", vr);
  }

  int set_real(unsigned vr, double value) noexcept {
    if (vr <= VR_TEMP) {
      in_[vr] = value;
      return DN_OK;
    }
    if (vr == VR_DEMAND) {
      demand_ = value;
      return DN_OK;
    }
    if (double* p = params_.find(vr)) {
      *p = value;
      return DN_OK;
    }
    return message.fail(DN_E_PARAM, "value reference %u cannot be set: only the inputs x, v, a, u, temperature, "
                        "force_demand and the parameters", vr);
  }

  int get_int(unsigned vr, int* value) noexcept {
    if (vr == VR_INV_STATUS) {
      *value = me_ ? latched_.inverse : inverse_now();  // model exchange: the last event's value
      return DN_OK;
    }
    if (vr != VR_STATUS && vr != VR_MASK && vr != VR_ENVELOPE) return no_such(message, "Integer", vr);
    const Discrete d = me_ ? latched_ : discrete_now(false);  // model exchange: the last event's values
    *value = vr == VR_STATUS ? d.status : vr == VR_MASK ? d.mask : d.envelope;
    return DN_OK;
  }
  int set_int(unsigned vr, int) noexcept { return message.fail(DN_E_PARAM, "no settable Integer %u", vr); }

  int do_step(double t, double h) noexcept {
    if (!(h > 0) || !std::isfinite(t + h))
      return message.fail(DN_E_PARAM, "the communication step must be a finite step > 0 s (got t = %g s, h = %g s)",
                          t, h);
    time_ = t;  // the states at the communication point t, committed
    double st[ST_N];
    states_now(st);
    for (int s = 0; s < ST_N; ++s)
      if (used_[s] && !std::isfinite(st[s]))
        return message.fail(DN_E_NONFINITE_INPUT, "a state is not finite at t = %g s (an input is NaN or infinite)",
                            t);
    for (int s = 0; s < ST_N; ++s) x_[s] = st[s];
    snapshot();
    time_ = t + h;
    return DN_OK;
  }

  void set_time(double t) noexcept { time_ = t; }
  double time() const noexcept { return time_; }
  int n_states() const noexcept { return n_states_; }
  void get_states(double* x) const noexcept {
    for (int i = 0; i < n_states_; ++i) x[i] = x_[slot_[i]];
  }
  void set_states(const double* x) noexcept {
    for (int i = 0; i < n_states_; ++i) x_[slot_[i]] = x[i];
  }
  int derivatives(double* dx) noexcept {
    double r[ST_N];
    rates(x_, r);
    for (int i = 0; i < n_states_; ++i) dx[i] = r[slot_[i]];
    return DN_OK;
  }

 private:
  // The Integer outputs of one evaluation.
  struct Discrete {
    int status = DN_OK, mask = 0, envelope = 0, inverse = DN_OK;
    bool operator==(const Discrete& o) const noexcept {
      return status == o.status && mask == o.mask && envelope == o.envelope && inverse == o.inverse;
    }
  };

  dampnet::Damper damper_;  // the MLP of the header with the current parameters
  dampnet::Envelope envelope_;  // its training envelope (the header's, or its ranges alone)
  DamperParams params_;
  double in_[5] = {};         // x, v, a, u, temperature
  double demand_ = 0.0;       // force_demand [N]: the inverse's demand
  double start_in_[5] = {};   // the inputs at the last communication point t0 (co-simulation)
  double x_[ST_N] = {};       // states: at t0 (co-simulation), the integrator's (model exchange)
  double time_ = 0.0, t0_ = 0.0;
  bool me_ = false;
  Discrete latched_;          // model exchange: the discrete outputs since the last event
  bool used_[ST_N] = {};
  // the last inverse (inverse_memo): its input (u 0), demand and results
  struct InverseMemo {
    bool valid = false;
    dn_damper_input in{};
    double demand = 0.0, u = 0.0, f = 0.0;
    int status = DN_OK;
  };
  mutable InverseMemo memo_;
  int slot_[ST_N] = {};
  int n_states_ = 0;

  int state_of(unsigned vr, unsigned base) const noexcept {
    return vr >= base && vr < base + ST_N && used_[vr - base] ? int(vr - base) : -1;
  }

  void snapshot() noexcept {
    t0_ = time_;
    for (int i = 0; i < 5; ++i) start_in_[i] = in_[i];
  }

  // The damper's input for inputs in (x, v, a, u, temperature), its states not filled.
  dn_damper_input input(const double* in) const noexcept {
    dn_damper_input d{};
    d.x = in[VR_X];
    d.v = in[VR_V];
    d.a = in[VR_A];
    d.u = in[VR_U];
    d.temperature = in[VR_TEMP];
    d.t = time_;
    d.dt = 0.0;
    d.stage = 0;
    return d;
  }

  // The states at the current time with the current inputs (see the file comment).
  void states_now(double* s) const noexcept {
    for (int i = 0; i < ST_N; ++i) s[i] = x_[i];
    if (me_) return;
    const double T = time_ - t0_;
    if (!(T > 0)) return;
    dampnet::DamperState now;
    damper_.advance(damper_.span(T), dampnet::DamperState::load(x_), input(start_in_), input(in_), now);
    for (int i = 0; i < ST_N; ++i)
      if (used_[i]) s[i] = now.s[i];
  }

  void rates(const double* s, double* r) const noexcept {
    dampnet::DamperState ds;
    damper_.rates(dampnet::DamperState::load(s), input(in_), ds);
    for (int i = 0; i < ST_N; ++i) r[i] = used_[i] ? ds.s[i] : 0.0;
  }

  // with_inverse: inverse_status too (the status of an inverse, besides the force's evaluation)
  Discrete discrete_now(bool with_inverse = true) const noexcept {
    double f = 0.0;
    uint32_t mask = 0, env = 0;
    const int st = evaluate(&f, &mask, &env);
    return Discrete{st, static_cast<int>(mask), static_cast<int>(env), with_inverse ? inverse_now() : DN_OK};
  }

  // The damper's input now: the current inputs with the states at the current time (states_now).
  dn_damper_input input_now() const noexcept {
    double s[ST_N];
    states_now(s);
    dn_damper_input d = input(in_);
    dampnet::Damper::fill(dampnet::DamperState::load(s), d);
    return d;
  }

  int inverse_now() const noexcept {
    double u = 0.0, f = 0.0;
    return inverse_memo(input_now(), &u, &f);
  }

  // Damper::inverse at the damper's input d and demand_, or the last one's results when both are
  // bit for bit the same but for d.u, which the inverse ignores (u_command, force_at_command and
  // inverse_status are read at one point, and a controller may set u to u_command between: one
  // inverse for the three; the damper is rebuilt only where memo_ is reset).
  int inverse_memo(const dn_damper_input& d, double* u, double* f) const noexcept {
    dn_damper_input key = d;
    key.u = 0.0;
    if (memo_.valid && std::memcmp(&memo_.in, &key, sizeof key) == 0 &&
        std::memcmp(&memo_.demand, &demand_, sizeof demand_) == 0) {
      *u = memo_.u;
      *f = memo_.f;
      return memo_.status;
    }
    const int st = damper_.inverse(d, demand_, u, f);
    memo_ = InverseMemo{true, key, demand_, *u, *f, st};
    return st;
  }

  // u_command (*u) and, with f, force_at_command: the inverse's control at the current inputs and
  // states (u ignored) and the force at it. Without a control input (DN_E_MISMATCH) *u = 0 and *f
  // the force at u = 0, DN_OK; the inverse's other errors (and the force's, at u = 0) returned.
  int command(double* u, double* f) const noexcept {
    dn_damper_input d = input_now();
    double fu = 0.0;
    int st = inverse_memo(d, u, &fu);
    if (st == DN_E_MISMATCH) {
      *u = 0.0;
      if (!f) return DN_OK;
      d.u = *u;
      uint32_t mask = 0;
      st = damper_.force(d, &fu, nullptr, &mask);
    }
    if (f) *f = fu;
    return st < 0 ? st : DN_OK;
  }

  // The force; with env, the envelope flags of the network's inputs (before saturation).
  int evaluate(double* force, uint32_t* mask, uint32_t* env = nullptr) const noexcept {
    dn_damper_input d = input_now();
    double feat[DN_MAX_INPUTS] = {};
    const int st = damper_.force(d, force, env ? feat : nullptr, mask);
    // a failed evaluation (a non-finite input) has no network inputs: outside, as in the quarter car
    if (env) *env = st < 0 ? DN_ENV_OUTSIDE_RANGE : envelope_.check(feat);
    return st;
  }
};

}  // namespace dnfmu
