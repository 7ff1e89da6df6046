// The quarter-car FMU's model (co-simulation only): dampnet's quarter-car loop
// (cpp/include/dampnet/loop.hpp: LoopModel, LoopData, step, forward) with the neural damper of
// the generated header "fmu_model.h" (prefix fmu_model, double precision, plus its physics
// terms) and every vehicle and controller parameter.
//
// Value references (python/dampnet/export/fmu/quarter_car.py writes the same in modelDescription.xml):
//   0 z_r [m]  1 v_r [m/s]   the road at the END of the coming step (t + h), as dn_loop_input
//   2 u [V]                  the control over the coming step (the 'external' law only)
//   9 time                   FMI 3's independent variable (the wrapper answers it)
//   10 + k, 100 + 10 i + j   the damper's feature constants and term parameters (as the damper FMU)
//   200 + i                  the loop state, DN_LOOP_STATE_LIST order (t, z_s, v_s, z_us, v_us, ...)
//   230 + j                  the step quantities, DN_LOOP_OUT_LIST order (force, u, x, v, a, acc_s, acc_us)
//   240 travel = z_s - z_us [m]   241 tyre force k_t (z_us - z_r) + c_t (v_us - v_r) [N]
//   250 status  251 clamped_mask  252 envelope_flags (the damper's inputs at the communication
//       point against the model's training envelope: 0 inside, else DN_ENV_OUTSIDE_* bits)  (Integer)
//   1000 + i                 vehicle field i (DN_VEHICLE_FIELDS order; int fields are Integer)
//   1100 + i                 controller field i (DN_CONTROLLER_FIELDS order)
//
// Timing. A communication step is n loop steps of the vehicle's fixed dt: do_step(t, h) refuses
// an h that is not a whole multiple n dt (relative tolerance 1e-9). The road inputs set before
// do_step(t, h) are the road at t + h (the end of the step, as dn_loop_input): an importer that
// sets the road of the step's start gets the response one step late. With n > 1 the road inside
// the communication step is the cubic Hermite interpolant of (z_r, v_r) at t and at t + h (the
// loop's own assumption within a step), and u is held; n = 1 is exactly one loop step. Every output read at a communication point
// is at that instant: after do_step(t, h) the state at t + h, and force, control, accelerations
// from dampnet::forward at that state (exactly what the next step reports at its start; with
// the 'external' law, with the u currently set). status: the last step's status (its damper
// evaluations' warnings OR-ed) with the evaluation at the communication point's.
// Initialisation (exit_initialization): the parameters are validated as the runtime's
// LoopModel::init does (an invalid value: an error naming the field and its range), the loop
// is reset to rest with the road at the inputs set (QuarterCar.simulate's start) and the loop
// time at the experiment's start time.
// Nothing here allocates or throws after instantiation.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "dampnet/damper.hpp"
#include "dampnet/loop.hpp"
#include "dampnet/mlp.hpp"
#include "fmu_common.hpp"
#include "fmu_damper_params.hpp"
#include "fmu_model.h"

namespace dnfmu {

namespace qc {

// One field of dn_vehicle / dn_controller: name, doc (DN_*_FIELDS), Integer or Real, where.
struct Field {
  const char* name;
  const char* doc;
  bool is_int;
  std::size_t offset;
};

#define DNFMU_QC_VFIELD_(type, name, def, doc) {#name, doc, std::is_same<type, int>::value, offsetof(dn_vehicle, name)},
#define DNFMU_QC_CFIELD_(type, name, def, doc) \
  {#name, doc, std::is_same<type, int>::value, offsetof(dn_controller, name)},
constexpr Field kVehicle[] = {DN_VEHICLE_FIELDS(DNFMU_QC_VFIELD_)};
constexpr Field kController[] = {DN_CONTROLLER_FIELDS(DNFMU_QC_CFIELD_)};
#undef DNFMU_QC_VFIELD_
#undef DNFMU_QC_CFIELD_
constexpr int kNVehicle = int(sizeof kVehicle / sizeof kVehicle[0]);
constexpr int kNController = int(sizeof kController / sizeof kController[0]);

// The valid names of an enum field, "name=value, ..." from the runtime's lists; the field's doc
// starts with its enum type's name (DN_VEHICLE_FIELDS: "dn_integrator", ...).
#define DNFMU_QC_ENUM_(id, value, name, doc) name "=" #value ", "
struct EnumNames {
  const char* type;
  const char* names;
};
constexpr EnumNames kEnums[] = {
    {"dn_integrator", DN_INTEGRATOR_LIST(DNFMU_QC_ENUM_)},
    {"dn_damper_eval", DN_DAMPER_EVAL_LIST(DNFMU_QC_ENUM_)},
    {"dn_accel_feature", DN_ACCEL_FEATURE_LIST(DNFMU_QC_ENUM_)},
    {"dn_controller_kind", DN_CONTROLLER_KIND_LIST(DNFMU_QC_ENUM_)},
};
#undef DNFMU_QC_ENUM_

inline const char* enum_names(const char* doc) noexcept {
  for (const EnumNames& e : kEnums) {
    const std::size_t n = std::strlen(e.type);
    if (std::strncmp(doc, e.type, n) == 0 && (doc[n] == '\0' || doc[n] == ' ')) return e.names;
  }
  return nullptr;
}

template <class S>
double get(const S& s, const Field& f) noexcept {
  const char* p = reinterpret_cast<const char*>(&s) + f.offset;
  return f.is_int ? double(*reinterpret_cast<const int*>(p)) : *reinterpret_cast<const double*>(p);
}
template <class S>
void copy_field(S& to, const S& from, const Field& f) noexcept {
  std::memcpy(reinterpret_cast<char*>(&to) + f.offset, reinterpret_cast<const char*>(&from) + f.offset,
              f.is_int ? sizeof(int) : sizeof(double));
}

// "name = value" into buf; an enum value with its name: "kind = 2 (skyhook_continuous)".
template <class S>
void name_value(char* buf, std::size_t n, const S& s, const Field& f) noexcept {
  if (!f.is_int) {
    std::snprintf(buf, n, "%s = %.12g", f.name, get(s, f));
    return;
  }
  const int value = int(get(s, f));
  const char* names = enum_names(f.doc);
  char key[16];
  std::snprintf(key, sizeof key, "=%d, ", value);
  const char* hit = names ? std::strstr(names, key) : nullptr;
  if (!hit) {
    std::snprintf(buf, n, "%s = %d", f.name, value);
    return;
  }
  const char* start = hit;
  while (start > names && start[-1] != ' ') --start;
  std::snprintf(buf, n, "%s = %d (%.*s)", f.name, value, int(hit - start), start);
}

// Why `user` fails `check` (a status < 0): the first field that fails on its own (the others at
// their defaults), else the first pair of fields that fail together, named with their docs.
template <class S, class Check>
int explain(Message& m, const char* what, const S& user, const S& defaults, const Field* fields, int n, Check check,
            int st) noexcept {
  char a[96], b[96];
  for (int i = 0; i < n; ++i) {
    S trial = defaults;
    copy_field(trial, user, fields[i]);
    const int s = check(trial);
    if (s >= 0) continue;
    name_value(a, sizeof a, user, fields[i]);
    const char* names = fields[i].is_int ? enum_names(fields[i].doc) : nullptr;
    if (names)
      return m.fail(s, "parameter %s: %s, one of %.*s", a, fields[i].doc, int(std::strlen(names)) - 2, names);
    if (s == DN_E_NONFINITE_PARAM) return m.fail(s, "parameter %s: must be finite (%s)", a, fields[i].doc);
    return m.fail(s, "parameter %s: %s", a, fields[i].doc);
  }
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      S trial = defaults;
      copy_field(trial, user, fields[i]);
      copy_field(trial, user, fields[j]);
      const int s = check(trial);
      if (s >= 0) continue;
      name_value(a, sizeof a, user, fields[i]);
      name_value(b, sizeof b, user, fields[j]);
      // an enum's doc is its type's name: the value's name says more
      const char* da = fields[i].is_int ? "" : fields[i].doc;
      const char* db = fields[j].is_int ? "" : fields[j].doc;
      return m.fail(s, "parameters %s and %s are refused together: %s%s%s", a, b, da, *da && *db ? "; " : "", db);
    }
  return m.fail(st, "the %s parameters are refused: %s", what, status_text(st));
}

}  // namespace qc

class QuarterCarModel {
 public:
  enum Vr : unsigned {
    VR_Z_R = 0, VR_V_R = 1, VR_U = 2,  // the damper's parameters: DamperParams (10 + k, 100 + 10 i + j)
    VR_STATE = 200, VR_OUT = 230, VR_TRAVEL = 240, VR_TYRE = 241, VR_STATUS = 250, VR_MASK = 251,
    VR_ENVELOPE = 252, VR_VEHICLE = 1000, VR_CONTROLLER = 1100
  };
#define DNFMU_QC_COUNT_(name, doc) +1
  static constexpr int kOut = 0 DN_LOOP_OUT_LIST(DNFMU_QC_COUNT_);
#undef DNFMU_QC_COUNT_
  static_assert(DN_LOOP_STATE_SIZE <= int(VR_OUT - VR_STATE), "the loop state outgrew its value references");
  static_assert(kOut <= int(VR_TRAVEL - VR_OUT), "the step report outgrew its value references");
  static_assert(qc::kNVehicle <= 100 && qc::kNController <= 100, "parameter value references overlap");

  Message message;

  int instantiate() noexcept {
    const dn_mlp_desc desc = FMU_MODEL_DESC_INIT;
    int st = damper_.md.load(&desc);
    if (st == DN_OK) st = damper_.mf.load(&desc);
    if (st == DN_OK) st = load_envelope(envelope_, desc);
    if (st != DN_OK) return message.fail(st, "the model header does not load: %s", status_text(st));
    params_.load_defaults();
    veh_ = dampnet::default_vehicle();
    ctrl_ = dampnet::default_controller();
#ifdef DNFMU_VEHICLE_START  // the start values of modelDescription.xml (fmu_config.h), DN_VEHICLE_FIELDS order
    {
      static constexpr double v[] = DNFMU_VEHICLE_START;
      static_assert(sizeof v / sizeof v[0] == qc::kNVehicle, "DNFMU_VEHICLE_START: one value per vehicle field");
      for (int i = 0; i < qc::kNVehicle; ++i) put(veh_, qc::kVehicle[i], v[i]);
    }
#endif
#ifdef DNFMU_CONTROLLER_START
    {
      static constexpr double c[] = DNFMU_CONTROLLER_START;
      static_assert(sizeof c / sizeof c[0] == qc::kNController, "DNFMU_CONTROLLER_START: one value per field");
      for (int i = 0; i < qc::kNController; ++i) put(ctrl_, qc::kController[i], c[i]);
    }
#endif
    reset();
    st = params_.build(damper_, message);  // the trained model's values: a failure here is a broken header
    return st < 0 ? st : DN_OK;
  }

  void reset() noexcept {
    for (double& v : in_) v = 0.0;
    time_ = 0.0;
    ready_ = false;
    initialized_ = false;
    last_status_ = DN_OK;
  }

  int exit_initialization(bool model_exchange) noexcept {
    if (model_exchange)
      return message.fail(DN_E_PARAM, "the quarter-car FMU is a co-simulation FMU only (no model exchange)");
    const int st = prepare();
    if (st < 0) return st;
    initialized_ = true;
    return DN_OK;
  }

  bool parameter(unsigned vr) const noexcept {
    return params_.owns(vr) || vehicle_field(vr) || controller_field(vr);
  }
  // The enum fields (integrator, kind, ...): FMI Enumeration variables.
  bool enumeration(unsigned vr) const noexcept {
    const qc::Field* f = vehicle_field(vr);
    if (!f) f = controller_field(vr);
    return f && f->is_int;
  }

  int get_real(unsigned vr, double* value) noexcept {
    if (vr <= VR_U) {
      *value = in_[vr];
      return DN_OK;
    }
    if (const qc::Field* f = vehicle_field(vr)) {
      if (f->is_int) return no_such(message, "Real", vr);
      *value = qc::get(veh_, *f);
      return DN_OK;
    }
    if (const qc::Field* f = controller_field(vr)) {
      if (f->is_int) return no_such(message, "Real", vr);
      *value = qc::get(ctrl_, *f);
      return DN_OK;
    }
    if (const double* p = params_.find(vr)) {
      *value = *p;
      return DN_OK;
    }
    const bool state = vr >= VR_STATE && vr < VR_STATE + DN_LOOP_STATE_SIZE;
    const bool out = vr >= VR_OUT && vr < VR_OUT + unsigned(kOut);
    if (!state && !out && vr != VR_TRAVEL && vr != VR_TYRE) return no_such(message, "Real", vr);
    const int st = outputs();
    if (st < 0) return st;
    const double* s = data_.s;
    if (state) *value = s[vr - VR_STATE];
    else if (out) *value = out_value(vr - VR_OUT);
    else if (vr == VR_TRAVEL) *value = s[dampnet::S_z_s] - s[dampnet::S_z_us];
    else
      *value = lm_.veh.k_t * (s[dampnet::S_z_us] - s[dampnet::S_z_r]) +
               lm_.veh.c_t * (s[dampnet::S_v_us] - s[dampnet::S_v_r]);
    return DN_OK;
  }

  int set_real(unsigned vr, double value) noexcept {
    if (vr <= VR_U) {
      in_[vr] = value;
      if (!initialized_) ready_ = false;  // the road at the start: the initial state
      out_ready_ = false;                 // the external law's u enters the outputs
      return DN_OK;
    }
    if (const qc::Field* f = vehicle_field(vr)) {
      if (f->is_int) return message.fail(DN_E_PARAM, "parameter %s is an Integer, not a Real", f->name);
      put(veh_, *f, value);
      ready_ = false;
      return DN_OK;
    }
    if (const qc::Field* f = controller_field(vr)) {
      if (f->is_int) return message.fail(DN_E_PARAM, "parameter %s is an Integer, not a Real", f->name);
      put(ctrl_, *f, value);
      ready_ = false;
      return DN_OK;
    }
    if (double* p = params_.find(vr)) {
      *p = value;
      ready_ = false;
      return DN_OK;
    }
    return message.fail(DN_E_PARAM, "value reference %u cannot be set: only the inputs z_r, v_r, u and the "
                        "parameters", vr);
  }

  int get_int(unsigned vr, int* value) noexcept {
    if (const qc::Field* f = vehicle_field(vr)) {
      if (!f->is_int) return no_such(message, "Integer", vr);
      *value = int(qc::get(veh_, *f));
      return DN_OK;
    }
    if (const qc::Field* f = controller_field(vr)) {
      if (!f->is_int) return no_such(message, "Integer", vr);
      *value = int(qc::get(ctrl_, *f));
      return DN_OK;
    }
    if (vr != VR_STATUS && vr != VR_MASK && vr != VR_ENVELOPE) return no_such(message, "Integer", vr);
    const int st = outputs();
    if (st < 0 && !ready_) return st;  // no model to evaluate (a parameter refused)
    if (vr == VR_ENVELOPE) {
      // the features of a failed evaluation are not the damper's: outside (a non-finite input)
      *value = st < 0 ? int(DN_ENV_OUTSIDE_RANGE) : int(envelope_.check(out_.features));
      return DN_OK;
    }
    *value = vr == VR_STATUS ? (st < 0 ? st : (last_status_ | out_status_)) : int(out_.clamped_mask);
    return DN_OK;
  }

  int set_int(unsigned vr, int value) noexcept {
    const qc::Field* f = vehicle_field(vr);
    if (f && f->is_int) {
      put(veh_, *f, value);
      ready_ = false;
      return DN_OK;
    }
    f = controller_field(vr);
    if (f && f->is_int) {
      put(ctrl_, *f, value);
      ready_ = false;
      return DN_OK;
    }
    return message.fail(DN_E_PARAM, "no settable Integer %u", vr);
  }

  int do_step(double t, double h) noexcept {
    if (!initialized_ || !ready_) return message.fail(DN_E_PARAM, "a step before the initialization finished");
    const double dt = lm_.veh.dt;
    const double n = std::round(h / dt);
    if (!(n >= 1 && n <= double(kMaxSteps)) || !(std::fabs(h - n * dt) <= 1e-9 * n * dt))
      return message.fail(DN_E_PARAM, "the communication step h = %.17g s is not a whole multiple of the quarter "
                          "car's fixed step dt = %.17g s (parameter dt): the FMU takes h / dt loop steps per "
                          "communication step; use h = n dt, n = 1, 2, ... (at most %ld)", h, dt, kMaxSteps);
    const long steps = long(n);
    const double z0 = data_.s[dampnet::S_z_r], v0 = data_.s[dampnet::S_v_r];
    const dampnet::LoopData before = data_;
    int status = DN_OK;
    for (long k = 1; k <= steps; ++k) {
      dn_loop_input in{in_[VR_Z_R], in_[VR_V_R], in_[VR_U]};
      if (k < steps) hermite_road(z0, v0, in.z_r, in.v_r, steps * dt, double(k) / double(steps), &in.z_r, &in.v_r);
      const int st = dampnet::step(lm_, data_, in, nullptr);
      if (st < 0) {
        data_ = before;
        return message.fail(st, "the loop step %ld of %ld from t = %.17g s failed (state unchanged): %s", k, steps,
                            t + double(k - 1) * dt, status_text(st));
      }
      status |= st;
    }
    last_status_ = status;
    time_ = t + h;
    out_ready_ = false;
    return DN_OK;
  }

  void set_time(double t) noexcept { time_ = t; }
  double time() const noexcept { return time_; }
  int n_states() const noexcept { return 0; }
  void get_states(double*) const noexcept {}
  void set_states(const double*) noexcept {}
  int derivatives(double*) noexcept {
    return message.fail(DN_E_PARAM, "the quarter-car FMU is a co-simulation FMU only (no model exchange)");
  }
  bool step_event() const noexcept { return false; }
  void update_discrete() noexcept {}

 private:
  dampnet::Damper damper_;   // the MLP of the header (double precision) with the current parameters
  dampnet::LoopModel lm_;    // vehicle, a copy of the damper, controller: built by prepare()
  dampnet::LoopData data_;
  dn_vehicle veh_ = dampnet::default_vehicle();
  dn_controller ctrl_ = dampnet::default_controller();
  DamperParams params_;
  dampnet::Envelope envelope_;  // the model's training envelope (the header's, or its ranges alone)
  double in_[3] = {};  // z_r, v_r, u
  double time_ = 0.0;
  bool ready_ = false;        // lm_ and data_ built from the current parameters (and start inputs)
  bool initialized_ = false;  // after exit_initialization: steps allowed, the state is the loop's
  bool out_ready_ = false;    // out_ is forward() at the current state and inputs
  int last_status_ = DN_OK;   // the status of the last step
  int out_status_ = DN_OK;
  dn_loop_out out_{};

  // loop steps in one communication step (a step count that fits a long everywhere)
  static constexpr long kMaxSteps = 2147483647L;

  // The road at theta in [0, 1] of a communication step of length H: the cubic Hermite
  // interpolant of (z0, v0) at its start and (z1, v1) at its end.
  static void hermite_road(double z0, double v0, double z1, double v1, double H, double theta, double* z,
                           double* v) noexcept {
    const double t2 = theta * theta, t3 = t2 * theta;
    *z = (2 * t3 - 3 * t2 + 1) * z0 + (t3 - 2 * t2 + theta) * H * v0 + (3 * t2 - 2 * t3) * z1 + (t3 - t2) * H * v1;
    *v = (6 * t2 - 6 * theta) / H * (z0 - z1) + (3 * t2 - 4 * theta + 1) * v0 + (3 * t2 - 2 * theta) * v1;
  }

  template <class S>
  static void put(S& s, const qc::Field& f, double v) noexcept {
    char* p = reinterpret_cast<char*>(&s) + f.offset;
    if (f.is_int) *reinterpret_cast<int*>(p) = int(v);
    else *reinterpret_cast<double*>(p) = v;
  }
  static const qc::Field* vehicle_field(unsigned vr) noexcept {
    return vr >= VR_VEHICLE && vr < VR_VEHICLE + unsigned(qc::kNVehicle) ? &qc::kVehicle[vr - VR_VEHICLE] : nullptr;
  }
  static const qc::Field* controller_field(unsigned vr) noexcept {
    return vr >= VR_CONTROLLER && vr < VR_CONTROLLER + unsigned(qc::kNController) ? &qc::kController[vr - VR_CONTROLLER]
                                                                                 : nullptr;
  }
  double out_value(unsigned j) const noexcept {
    unsigned k = 0;
#define DNFMU_QC_OUT_(name, doc) \
  if (j == k++) return out_.name;
    DN_LOOP_OUT_LIST(DNFMU_QC_OUT_)
#undef DNFMU_QC_OUT_
    return 0.0;
  }

  // The loop model from the current parameters, reset to rest with the road at the inputs set:
  // the state at the experiment's start (QuarterCar.simulate's start). Before initialization
  // (an importer reading the outputs in initialization mode) and at exit_initialization.
  int prepare() noexcept {
    if (ready_) return DN_OK;
    int st = params_.build(damper_, message);
    if (st < 0) return st;
    st = lm_.init(veh_, damper_, ctrl_);
    if (st < 0) {
      if (dampnet::check_vehicle(veh_) < 0)
        return qc::explain(message, "vehicle", veh_, dampnet::default_vehicle(), qc::kVehicle, qc::kNVehicle,
                           dampnet::check_vehicle, st);
      return qc::explain(message, "controller", ctrl_, dampnet::default_controller(), qc::kController,
                         qc::kNController, dampnet::check_controller, st);
    }
    if (!std::isfinite(in_[VR_Z_R]) || !std::isfinite(in_[VR_V_R]))
      return message.fail(DN_E_NONFINITE_INPUT, "the road at the start is not finite (z_r = %g m, v_r = %g m/s)",
                          in_[VR_Z_R], in_[VR_V_R]);
    dampnet::reset(lm_, data_);
    data_.s[dampnet::S_t] = time_;
    data_.s[dampnet::S_z_r] = in_[VR_Z_R];
    data_.s[dampnet::S_v_r] = in_[VR_V_R];
    last_status_ = DN_OK;
    out_ready_ = false;
    ready_ = true;
    return DN_OK;
  }

  // forward() at the current state with the current inputs, once per state and input change.
  int outputs() noexcept {
    int st = prepare();
    if (st < 0) return st;
    if (out_ready_) return out_status_;
    const dn_loop_input in{in_[VR_Z_R], in_[VR_V_R], in_[VR_U]};
    st = dampnet::forward(lm_, data_, in, &out_);
    out_status_ = st;
    out_ready_ = true;
    if (st < 0)
      return message.fail(st, "the outputs cannot be evaluated at t = %.17g s: %s", time_, status_text(st));
    return st;
  }
};

}  // namespace dnfmu
