// dampnet._core: the pybind11 front door to the C++ runtime.
// C status codes become Python exceptions in one place (check()).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <map>
#include <tuple>
#include <type_traits>
#include <utility>

#ifdef __linux__
#include <sys/mman.h>
#endif
#include <vector>
#include <memory>
#include <stdexcept>
#include <string>

#include "dampnet/dampnet.h"
#include "dampnet/loop.hpp"

#include "busy.hpp"
#include "callback_run.hpp"
#include "fields.hpp"

namespace py = pybind11;

namespace {

using dnpy::BusyGuard;
using dnpy::CallbackRun;

using DArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

void check(int status, const std::string& what) {
  if (status < 0) throw py::value_error(what + ": " + dn_status_str(status));
}

// h as a constructed C++ object of class C (self, or an argument): not None, of the
// class, and built by its __init__ (see method()). On every method call: no allocation,
// one cached type lookup.
template <class C>
C& constructed(py::handle h) {
  static const py::detail::type_info* const ti = py::detail::get_type_info(typeid(C));
  if (!ti) throw py::type_error("dampnet._core: class not registered");
  if (!h || !PyObject_TypeCheck(h.ptr(), ti->type))
    throw py::type_error(std::string("expected a ") + ti->type->tp_name + ", got " + dnpy::describe(h));
  auto vh = reinterpret_cast<py::detail::instance*>(h.ptr())->get_value_and_holder(ti, false);
  if (!vh || !vh.holder_constructed() || !vh.value_ptr())
    throw py::type_error(std::string("this ") + ti->type->tp_name +
                         " was never initialised (made by __new__ without __init__)");
  return *vh.value_ptr<C>();
}

// The shared_ptr holder of h, a constructed C (None or an uninitialised instance: TypeError).
template <class C>
std::shared_ptr<C> shared(py::handle h, const char* what) {
  if (h.is_none()) throw py::type_error(std::string(what) + ", not None");
  constructed<C>(h);
  return h.cast<std::shared_ptr<C>>();
}

// A dn_mlp owned by Python, with the description's arrays validated by shape.
class PyMlp {
 public:
  PyMlp(DArray w1, DArray b1, py::object w2, py::object b2, DArray w_out, DArray b_out,
        DArray in_offset, DArray in_gain, double in_ymin, double out_offset, double out_gain,
        double out_ymin, DArray sat_lo, DArray sat_hi, const std::string& activation) {
    if (w1.ndim() != 2) throw py::value_error("w1 must be 2-D [n_hidden1, n_inputs]");
    if (w1.shape(0) > DN_MAX_HIDDEN || w1.shape(1) > DN_MAX_INPUTS)  // before the int casts
      throw py::value_error("Mlp: w1 is [n_hidden1, n_inputs]: at most " +
                            std::to_string(DN_MAX_HIDDEN) + " x " + std::to_string(DN_MAX_INPUTS) + " (" +
                            dn_status_str(DN_E_SIZE) + ")");
    dn_mlp_desc d{};
    d.n_hidden1 = static_cast<int>(w1.shape(0));
    d.n_inputs = static_cast<int>(w1.shape(1));
    DArray w2a, b2a;
    if (!w2.is_none()) {
      w2a = DArray::ensure(w2);
      b2a = DArray::ensure(b2);
      if (!w2a || w2a.ndim() != 2 || w2a.shape(1) != d.n_hidden1 || w2a.shape(0) > DN_MAX_HIDDEN)
        throw py::value_error("w2 must be 2-D [n_hidden2, n_hidden1] with n_hidden2 <= " +
                              std::to_string(DN_MAX_HIDDEN) + " (" + dn_status_str(DN_E_SIZE) + ")");
      if (!b2a) throw py::value_error("b2 must be an array of n_hidden2 numbers when w2 is given");
      d.n_hidden2 = static_cast<int>(w2a.shape(0));
      expect(b2a, d.n_hidden2, "b2");
      d.w2 = w2a.data();
      d.b2 = b2a.data();
    }
    const int n_last = d.n_hidden2 > 0 ? d.n_hidden2 : d.n_hidden1;
    expect(b1, d.n_hidden1, "b1");
    expect(w_out, n_last, "w_out");
    expect(b_out, 1, "b_out");
    for (auto* a : {&in_offset, &in_gain, &sat_lo, &sat_hi}) expect(*a, d.n_inputs, "scaling/limits");
    d.activation = -1;
    std::string valid;
    for (const auto& a : dnpy::kActivations) {
      if (activation == a.name) d.activation = a.value;
      valid += std::string(valid.empty() ? "'" : " or '") + a.name + "'";
    }
    if (d.activation < 0)
      throw py::value_error("activation must be " + valid + ", got '" + activation + "'");
    d.w1 = w1.data();
    d.b1 = b1.data();
    d.w_out = w_out.data();
    d.b_out = b_out.data();
    d.in_offset = in_offset.data();
    d.in_gain = in_gain.data();
    d.in_ymin = in_ymin;
    d.out_offset = out_offset;
    d.out_gain = out_gain;
    d.out_ymin = out_ymin;
    d.sat_lo = sat_lo.data();
    d.sat_hi = sat_hi.data();
    dn_mlp* m = nullptr;
    check(dn_mlp_create(&d, &m), "Mlp");
    m_.reset(m);
    n_in_ = d.n_inputs;
  }

  int n_inputs() const { return n_in_; }
  const dn_mlp* handle() const { return m_.get(); }

  // One sample: (force, status, clamped_mask).
  py::tuple forward(DArray x, bool single) const {
    expect(x, n_in_, "x");
    uint32_t mask = 0;
    int st;
    double y;
    if (single) {
      float xf[DN_MAX_INPUTS], yf;
      for (int i = 0; i < n_in_; ++i) xf[i] = static_cast<float>(x.data()[i]);
      st = dn_mlp_forward_f(m_.get(), xf, &yf, &mask);
      y = yf;
    } else {
      st = dn_mlp_forward(m_.get(), x.data(), &y, &mask);
    }
    return py::make_tuple(y, st, mask);
  }

  // Many samples [n, n_inputs] in C++ with the GIL released: (y, status, mask).
  py::tuple predict(DArray x, bool single) const {
    if (x.ndim() != 2 || x.shape(1) != n_in_)
      throw py::value_error("x must be 2-D [n_samples, " + std::to_string(n_in_) + "]");
    const py::ssize_t n = x.shape(0);
    py::array_t<double> y(n);
    py::array_t<int32_t> st(n);
    py::array_t<uint32_t> mask(n);
    const double* xp = x.data();
    double* yp = y.mutable_data();
    int32_t* sp = st.mutable_data();
    uint32_t* mp = mask.mutable_data();
    const dn_mlp* m = m_.get();
    const int ni = n_in_;
    {
      py::gil_scoped_release release;
      for (py::ssize_t r = 0; r < n; ++r) {
        if (single) {
          float xf[DN_MAX_INPUTS], yf;
          for (int i = 0; i < ni; ++i) xf[i] = static_cast<float>(xp[r * ni + i]);
          sp[r] = dn_mlp_forward_f(m, xf, &yf, &mp[r]);
          yp[r] = yf;
        } else {
          sp[r] = dn_mlp_forward(m, xp + r * ni, &yp[r], &mp[r]);
        }
      }
    }
    return py::make_tuple(y, st, mask);
  }

 private:
  static void expect(const DArray& a, py::ssize_t n, const char* name) {
    if (a.size() != n)
      throw py::value_error(std::string(name) + ": expected " + std::to_string(n) +
                            " values, got " + std::to_string(a.size()));
  }
  struct Deleter {
    void operator()(dn_mlp* m) const { dn_mlp_destroy(m); }
  };
  std::unique_ptr<dn_mlp, Deleter> m_;
  int n_in_ = 0;
};

// ---- Dampers, controllers and the quarter-car loop ----

py::dict vehicle_dict(const dn_vehicle& s) {
  py::dict d;
#define DN_GET_(type, name, def, doc) d[#name] = s.name;
  DN_VEHICLE_FIELDS(DN_GET_)
  return d;
}

py::dict controller_dict(const dn_controller& s) {
  py::dict d;
  DN_CONTROLLER_FIELDS(DN_GET_)
#undef DN_GET_
  return d;
}

py::dict field_docs_vehicle() {
  py::dict d;
#define DN_DOC_(type, name, def, doc) d[#name] = py::make_tuple(static_cast<type>(def), doc);
  DN_VEHICLE_FIELDS(DN_DOC_)
  return d;
}

py::dict field_docs_controller() {
  py::dict d;
  DN_CONTROLLER_FIELDS(DN_DOC_)
#undef DN_DOC_
  return d;
}

// The runtime's registries (dampnet.h's X-macro lists) as module attributes, so Python
// reads every name from here instead of retyping it.
void add_registries(py::module_& mod) {
  // enum lists: {name: (value, doc)} in value order
  auto enum_dict = [](std::initializer_list<std::tuple<int, const char*, const char*>> rows) {
    py::dict d;
    for (const auto& [value, name, doc] : rows) d[name] = py::make_tuple(value, doc);
    return d;
  };
#define DNPY_ENUM_ROW_(id, value, name, doc) {int(value), name, doc},
  mod.attr("CONTROLLER_KINDS") = enum_dict({DN_CONTROLLER_KIND_LIST(DNPY_ENUM_ROW_)});
  mod.attr("INTEGRATORS") = enum_dict({DN_INTEGRATOR_LIST(DNPY_ENUM_ROW_)});
  mod.attr("DAMPER_EVALS") = enum_dict({DN_DAMPER_EVAL_LIST(DNPY_ENUM_ROW_)});
  mod.attr("ACCEL_FEATURES") = enum_dict({DN_ACCEL_FEATURE_LIST(DNPY_ENUM_ROW_)});
  mod.attr("ACTIVATIONS") = enum_dict({DN_ACTIVATION_LIST(DNPY_ENUM_ROW_)});
  mod.attr("DAMPER_KINDS") = enum_dict({DN_DAMPER_KIND_LIST(DNPY_ENUM_ROW_)});
  mod.attr("PRECISIONS") = enum_dict({DN_PRECISION_LIST(DNPY_ENUM_ROW_)});
#undef DNPY_ENUM_ROW_

  // features: the damper-input field each reads, the feature parameter each needs
  py::dict param_docs, inputs, params;
  std::vector<const char*> param_names;
#define DNPY_FPARAM_(id, name, doc) param_docs[name] = doc, param_names.push_back(name);
  DN_FEATURE_PARAM_LIST(DNPY_FPARAM_)
#undef DNPY_FPARAM_
#define DNPY_FEATURE_(id, name, field, param)                                      \
  inputs[name] = #field;                                                         \
  params[name] = (param) == DN_FPARAM_NONE ? py::object(py::none())              \
                                           : py::object(py::str(param_names[(param)]));
  DN_FEATURE_LIST(DNPY_FEATURE_)
#undef DNPY_FEATURE_
  mod.attr("FEATURE_INPUTS") = inputs;
  mod.attr("FEATURE_PARAMS") = params;
  mod.attr("FEATURE_PARAM_NAMES") = param_docs;

  py::dict damper_input;
#define DNPY_INPUT_(type, name, role, doc) damper_input[#name] = doc;
  DN_DAMPER_INPUT_FIELDS(DNPY_INPUT_)
#undef DNPY_INPUT_
  mod.attr("DAMPER_INPUT_FIELDS") = damper_input;

  // the step report's keys (Loop.step): dn_loop_out's quantities, then the rest
  py::dict step_out;
#define DNPY_OUT_(name, doc) step_out[#name] = doc;
  DN_LOOP_OUT_LIST(DNPY_OUT_)
#undef DNPY_OUT_
  step_out["features"] = "a neural damper's inputs before saturation, in its features' order [feature units]; empty for other dampers";
  step_out["clamped_mask"] = "neural: bit i set when input i was clamped or replaced [-]";
  step_out["status"] = "the step's status: DN_OK, or an OR of DN_W_* warnings [-]";
  mod.attr("STEP_OUTPUT_FIELDS") = step_out;

  // every enum field of a vehicle or controller has its name table (checked at import)
#define DNPY_ENUM_TABLE_(type, name, def, doc) \
  if (std::is_same<type, int>::value) dnpy::enum_field(#name);
  DN_VEHICLE_FIELDS(DNPY_ENUM_TABLE_)
  DN_CONTROLLER_FIELDS(DNPY_ENUM_TABLE_)
#undef DNPY_ENUM_TABLE_
}

// A damper owned by Python. A callback damper keeps its Python function here.
class PyDamper {
 public:
  struct Deleter {
    void operator()(dn_damper* d) const { dn_damper_destroy(d); }
  };
  std::unique_ptr<dn_damper, Deleter> d;
  py::object callback;        // the Python function of a callback damper
  std::vector<std::string> features;  // a neural damper's inputs (empty for the others)
  // Calls of forces() under way. Counted with the GIL held, read by add_term (GIL held): a
  // damper is immutable while evaluated (forces releases the GIL; a callback may re-enter).
  std::atomic<int> evaluating{0};

  static std::shared_ptr<PyDamper> wrap(dn_damper* raw) {
    auto p = std::make_shared<PyDamper>();
    p->d.reset(raw);
    return p;
  }

  static std::shared_ptr<PyDamper> linear(double c) {
    dn_damper* r = nullptr;
    check(dn_damper_create_linear(c, &r), "Damper.linear");
    return wrap(r);
  }
  static std::shared_ptr<PyDamper> parametric(double c_min, double c_max, double gamma, double f0,
                                              double v_max, double v_smooth) {
    dn_parametric_params p{c_min, c_max, gamma, f0, v_max, v_smooth};
    dn_damper* r = nullptr;
    check(dn_damper_create_parametric(&p, &r), "Damper.parametric");
    return wrap(r);
  }
  static std::shared_ptr<PyDamper> table(DArray v, DArray u, DArray f) {
    if (v.ndim() != 1 || u.ndim() != 1)
      throw py::value_error("Damper.table: velocities and controls must be 1-D");
    if (v.shape(0) > DN_MAX_TABLE_V || u.shape(0) > DN_MAX_TABLE_U)  // before the int casts
      throw py::value_error("Damper.table: at most " + std::to_string(DN_MAX_TABLE_V) +
                            " velocities and " + std::to_string(DN_MAX_TABLE_U) + " controls (" +
                            dn_status_str(DN_E_SIZE) + ")");
    if (f.ndim() != 2 || f.shape(0) != u.shape(0) || f.shape(1) != v.shape(0))
      throw py::value_error("Damper.table: forces must be 2-D [n_controls, n_velocities]");
    dn_damper* r = nullptr;
    check(dn_damper_create_table(v.data(), (int)v.shape(0), u.data(), (int)u.shape(0), f.data(),
                                 &r),
          "Damper.table");
    return wrap(r);
  }
  static std::shared_ptr<PyDamper> neural(py::handle mlp_obj, const std::vector<std::string>& feats,
                                          const std::map<std::string, double>& fparams,
                                          bool single) {
    if (mlp_obj.is_none()) throw py::type_error("Damper.neural: mlp must be an Mlp, not None");
    const PyMlp* mlp = &constructed<PyMlp>(mlp_obj);
    if (feats.size() > DN_MAX_INPUTS || fparams.size() > 64)  // before the int casts
      throw py::value_error("Damper.neural: at most " + std::to_string(DN_MAX_INPUTS) + " features (" +
                            dn_status_str(DN_E_SIZE) + ")");
    std::vector<const char*> names, pnames;
    std::vector<double> pvals;
    for (const auto& f : feats) names.push_back(f.c_str());
    for (const auto& kv : fparams) {
      pnames.push_back(kv.first.c_str());
      pvals.push_back(kv.second);
    }
    dn_damper* r = nullptr;
    const int st = dn_damper_create_neural(mlp->handle(), names.data(), (int)names.size(),
                                           pnames.data(), pvals.data(), (int)pvals.size(),
                                           single ? DN_PRECISION_FLOAT : DN_PRECISION_DOUBLE, &r);
    if (st == DN_E_UNKNOWN_NAME) {
      std::string msg = "Damper.neural: unknown feature or feature parameter name in [";
      for (const auto& f : feats) msg += f + " ";
      msg += "] / feature_params; known features:";
#define DN_FNAME_(id, name, field, param) msg += std::string(" ") + name;
      DN_FEATURE_LIST(DN_FNAME_)
#undef DN_FNAME_
      throw py::value_error(msg + " (" + dn_status_str(st) + ")");
    }
    check(st, "Damper.neural");
    auto p = wrap(r);
    p->features = feats;
    return p;
  }

  // The C function of a callback damper: calls the Python function with the GIL. Its
  // exception (or a result that is no number) goes to the run on this thread
  // (CallbackRun), which raises it; the runtime sees NaN and stops the run.
  static double trampoline(void* user, const dn_damper_input* in) noexcept {
    auto* self = static_cast<PyDamper*>(user);
    py::gil_scoped_acquire gil;
    CallbackRun* run = CallbackRun::current();
    if (run && run->failed()) return std::nan("");
    try {
      py::object r = self->callback(*in);
      const double f = PyFloat_AsDouble(r.ptr());
      if (f == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        throw py::type_error("Damper.callback: the function returned " + dnpy::describe(r) +
                             ", expected the force [N] as a number");
      }
      return f;
    } catch (py::error_already_set& e) {
      e.restore();
    } catch (const py::builtin_exception& e) {
      e.set_error();
    } catch (const std::exception& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
    if (run) run->record_current_error();
    else PyErr_WriteUnraisable(self->callback.ptr());  // no run to raise it in (not expected)
    return std::nan("");
  }

  static std::shared_ptr<PyDamper> callback_damper(py::function fn) {
    auto p = std::make_shared<PyDamper>();
    dn_damper* r = nullptr;
    check(dn_damper_create_callback(&PyDamper::trampoline, p.get(), &r), "Damper.callback");
    p->d.reset(r);
    p->callback = fn;
    return p;
  }

  void add_term(const std::string& kind, DArray params) {
    if (evaluating.load() > 0)
      throw std::runtime_error("Damper.add_term: the damper is being evaluated (forces in another "
                               "thread, or its callback re-entering it); add terms before use");
    if (params.size() > DN_MAX_TERM_PARAMS)  // before the int cast
      throw py::value_error("add_term('" + kind + "'): at most " +
                            std::to_string(DN_MAX_TERM_PARAMS) + " parameters (" +
                            dn_status_str(DN_E_SIZE) + ")");
    const int st = dn_damper_add_term(d.get(), kind.c_str(), params.data(), (int)params.size());
    if (st == DN_E_UNKNOWN_NAME) {
      std::string msg = "add_term: unknown kind '" + kind + "'; known:";
#define DN_TNAME_(id, value, name, n, text) msg += std::string(" ") + name;
      DN_TERM_LIST(DN_TNAME_)
#undef DN_TNAME_
      throw py::value_error(msg);
    }
    check(st, "add_term('" + kind + "')");
  }

  // Vectorised force of the model plus terms; arrays broadcast to one length.
  py::tuple forces(DArray x, DArray v, DArray a, DArray u, DArray u_lag, DArray temp,
                   DArray v_lag, DArray z_fric) {
    const DArray* arrs[] = {&x, &v, &a, &u, &u_lag, &temp, &v_lag, &z_fric};
    py::ssize_t n = 1;
    for (auto* p : arrs)
      if (p->size() != 1) {
        if (n != 1 && p->size() != n) throw py::value_error("forces: arrays differ in length");
        n = p->size();
      }
    py::array_t<double> f(n);
    py::array_t<int32_t> st(n);
    py::array_t<uint32_t> mask(n);
    auto at = [&](const DArray& arr, py::ssize_t i) { return arr.size() == 1 ? arr.data()[0] : arr.data()[i]; };
    double* fp = f.mutable_data();
    int32_t* sp = st.mutable_data();
    uint32_t* mp = mask.mutable_data();
    struct Evaluating {  // counted for add_term; decremented on every exit
      std::atomic<int>& n;
      explicit Evaluating(std::atomic<int>& c) : n(c) { ++n; }
      ~Evaluating() { --n; }
    } evaluating_now(evaluating);
    CallbackRun run;
    {
      std::unique_ptr<py::gil_scoped_release> rel;
      if (!callback) rel.reset(new py::gil_scoped_release);
      for (py::ssize_t i = 0; i < n; ++i) {
        dn_damper_input in{};
        in.x = at(x, i);
        in.v = at(v, i);
        in.a = at(a, i);
        in.u = at(u, i);
        in.u_lag = at(u_lag, i);
        in.temperature = at(temp, i);
        in.v_lag = at(v_lag, i);
        in.z_fric = at(z_fric, i);
        sp[i] = dn_damper_force(d.get(), &in, &fp[i], &mp[i]);
      }
    }
    run.raise_pending();
    return py::make_tuple(f, st, mask);
  }
};

// A fresh C-contiguous [rows] or [rows, cols] array for simulate's results. From 4 MiB up
// (Linux) its memory is an anonymous mapping of whole, 2 MiB-aligned huge pages with
// MADV_HUGEPAGE (THP is "madvise" on many systems), owned by the array (a capsule unmaps
// it): first touch then takes one page fault per 2 MiB instead of one per 4 KiB, which on
// a VM costs more than the kernel's zeroing of the page. (numpy's own allocator advises
// huge pages for large arrays too, but its malloc'd blocks are not 2 MiB-aligned, so each
// array's first and last partial huge pages fault per 4 KiB.) Same contents, fresh memory;
// smaller arrays, and any failure to map, take numpy's allocator.
template <class T>
py::array_t<T> fresh_array(py::ssize_t rows, py::ssize_t cols = -1) {
  const std::vector<py::ssize_t> shape = cols < 0 ? std::vector<py::ssize_t>{rows}
                                                  : std::vector<py::ssize_t>{rows, cols};
  const size_t bytes = size_t(rows) * size_t(cols < 0 ? 1 : cols) * sizeof(T);
#ifdef __linux__
  constexpr size_t kHuge = size_t(2) << 20;
  if (bytes >= 2 * kHuge) {
    const size_t len = (bytes + kHuge - 1) / kHuge * kHuge;
    void* raw = mmap(nullptr, len + kHuge, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (raw != MAP_FAILED) {
      char* base = static_cast<char*>(raw);
      char* p = reinterpret_cast<char*>((reinterpret_cast<uintptr_t>(base) + kHuge - 1) & ~(kHuge - 1));
      if (p > base) munmap(base, size_t(p - base));                       // the slack before
      if (base + len + kHuge > p + len) munmap(p + len, size_t(base + len + kHuge - (p + len)));  // after
      madvise(p, len, MADV_HUGEPAGE);
      struct Mapping { void* p; size_t len; };
      py::capsule owner(new Mapping{p, len}, [](void* m) {
        auto* mp = static_cast<Mapping*>(m);
        munmap(mp->p, mp->len);
        delete mp;
      });
      return py::array_t<T>(shape, reinterpret_cast<T*>(p), owner);
    }
  }
#endif
  return py::array_t<T>(shape);
}

class PyLoopModel {
 public:
  struct Deleter {
    void operator()(dn_loop_model* m) const { dn_loop_model_destroy(m); }
  };
  std::unique_ptr<dn_loop_model, Deleter> m;
  std::shared_ptr<PyDamper> damper;
  dn_vehicle veh{};
  dn_controller ctrl{};

  PyLoopModel(std::shared_ptr<PyDamper> d, py::dict vehicle, py::dict controller) : damper(d) {
    if (!damper) throw py::type_error("LoopModel: damper must be a Damper, not None");
    ctrl = dnpy::controller_from(controller);
    veh = dnpy::vehicle_from(vehicle);
    // the runtime's validation, naming the field (the same checks dn_loop_model_create makes)
    dnpy::raise_if_invalid("LoopModel: ", vehicle, veh, controller, ctrl);
    dn_loop_model* r = nullptr;
    check(dn_loop_model_create(&veh, damper->d.get(), &ctrl, &r), "LoopModel");
    m.reset(r);
  }

  // Vectorised control law (the controller alone), for tests.
  py::array_t<double> control(DArray v_s, DArray v_us, DArray u_ext) const {
    if (v_s.size() != v_us.size() || (u_ext.size() != 1 && u_ext.size() != v_s.size()))
      throw py::value_error("control: arrays differ in length");
    py::array_t<double> u(v_s.size());
    for (py::ssize_t i = 0; i < v_s.size(); ++i)
      u.mutable_data()[i] = dampnet::control_law(ctrl, v_s.data()[i], v_us.data()[i],
                                                 u_ext.data()[u_ext.size() == 1 ? 0 : i]);
    return u;
  }
};

py::dict out_dict(const dn_loop_out& o, int status) {
  py::dict r;
  r["force"] = o.force;
  r["u"] = o.u;
  r["x"] = o.x;
  r["v"] = o.v;
  r["a"] = o.a;
  r["acc_s"] = o.acc_s;
  r["acc_us"] = o.acc_us;
  py::array_t<double> f(o.n_features);
  for (int i = 0; i < o.n_features; ++i) f.mutable_data()[i] = o.features[i];
  r["features"] = f;
  r["clamped_mask"] = o.clamped_mask;
  r["status"] = status;
  return r;
}

// What Loop.step returns: the step's report as read-only attributes, and also as a
// read-only mapping with the keys of out_dict() (r["force"], r.get, r.keys(), dict(r)), so
// code that reads the former dict keeps working; it is not a dict (==, json, pickle, copy
// need dict(r)). Cheaper than a dict: one object
// holding the C struct; `features` becomes a numpy array only when asked for.
struct StepReport {
  dn_loop_out o;
  int status;
};

const char* const kStepKeys[] = {"force", "u", "x", "v", "a", "acc_s", "acc_us",
                                 "features", "clamped_mask", "status"};

py::object step_report_get(const StepReport& r, const std::string& key) {
  const dn_loop_out& o = r.o;
  if (key == "force") return py::float_(o.force);
  if (key == "u") return py::float_(o.u);
  if (key == "x") return py::float_(o.x);
  if (key == "v") return py::float_(o.v);
  if (key == "a") return py::float_(o.a);
  if (key == "acc_s") return py::float_(o.acc_s);
  if (key == "acc_us") return py::float_(o.acc_us);
  if (key == "features") {
    py::array_t<double> f(o.n_features);
    for (int i = 0; i < o.n_features; ++i) f.mutable_data()[i] = o.features[i];
    return std::move(f);
  }
  if (key == "clamped_mask") return py::int_(o.clamped_mask);
  if (key == "status") return py::int_(r.status);
  throw py::key_error(key);
}

// The Python type of a StepReport: a plain CPython object holding the struct (no
// pybind11 instance registry, pymalloc): creating one costs a few tens of ns where a
// pybind11 class instance cost ~150. Attributes are native getters; the mapping
// methods are pybind11 functions set on the type (see make_step_report_type).
struct StepReportObject {
  PyObject_HEAD
  StepReport r;
};
PyTypeObject* g_step_report_type = nullptr;

const StepReport& report_of(py::handle h) {
  if (!g_step_report_type || !PyObject_TypeCheck(h.ptr(), g_step_report_type))
    throw py::type_error("expected a StepReport");
  return reinterpret_cast<StepReportObject*>(h.ptr())->r;
}

PyObject* step_report_attr(PyObject* self, void* closure) {
  try {
    const auto i = reinterpret_cast<std::intptr_t>(closure);
    return step_report_get(reinterpret_cast<StepReportObject*>(self)->r, kStepKeys[i]).release().ptr();
  } catch (py::error_already_set& e) {
    e.restore();
  } catch (const std::exception& e) {
    PyErr_SetString(PyExc_RuntimeError, e.what());
  }
  return nullptr;
}

void step_report_dealloc(PyObject* self) {
  PyTypeObject* tp = Py_TYPE(self);
  PyObject_Free(self);
  Py_DECREF(tp);  // heap type: every instance holds a reference to it
}

class PyLoop {
 public:
  struct Deleter {
    void operator()(dn_loop_data* d) const { dn_loop_data_destroy(d); }
  };
  std::shared_ptr<PyLoopModel> model;
  std::unique_ptr<dn_loop_data, Deleter> d;
  // Set while a call uses the state (BusyGuard): a Loop refuses concurrent use.
  mutable std::atomic<bool> busy{false};

  explicit PyLoop(std::shared_ptr<PyLoopModel> m) : model(m) {
    if (!model) throw py::type_error("Loop: model must be a LoopModel, not None");
    dn_loop_data* r = nullptr;
    check(dn_loop_data_create(model->m.get(), &r), "Loop");
    d.reset(r);
  }

  void reset() {
    BusyGuard guard(busy, "Loop.reset", dnpy::kLoopContract);
    check(dn_loop_reset(model->m.get(), d.get()), "reset");
  }

  py::array_t<double> get_state() const {
    py::array_t<double> s(DN_LOOP_STATE_SIZE);
    BusyGuard guard(busy, "Loop.state", dnpy::kLoopContract);
    dn_loop_get_state(d.get(), s.mutable_data());
    return s;
  }
  void set_state(DArray s) {
    if (s.size() != DN_LOOP_STATE_SIZE)
      throw py::value_error("state: expected " + std::to_string(DN_LOOP_STATE_SIZE) + " values");
    BusyGuard guard(busy, "Loop.state", dnpy::kLoopContract);
    check(dn_loop_set_state(d.get(), s.data()), "state");
  }

  py::object step(double z_r, double v_r, double u) { return report(z_r, v_r, u, true); }

  // What step() would report, without advancing (a StepReport too).
  py::object forward(double u) { return report(0.0, 0.0, u, false); }

  py::object report(double z_r, double v_r, double u, bool advance) {
    dn_loop_input in{z_r, v_r, u};
    auto* obj = PyObject_New(StepReportObject, g_step_report_type);
    if (!obj) throw py::error_already_set();
    py::object owner = py::reinterpret_steal<py::object>(reinterpret_cast<PyObject*>(obj));
    StepReport& r = obj->r;
    r.o = dn_loop_out{};
    {
      BusyGuard guard(busy, advance ? "Loop.step" : "Loop.forward", dnpy::kLoopContract);
      CallbackRun run;
      r.status = advance ? dn_loop_step(model->m.get(), d.get(), &in, &r.o)
                         : dn_loop_forward(model->m.get(), d.get(), &in, &r.o);
      run.raise_pending();
    }
    check(r.status, advance ? "step" : "forward");
    return owner;
  }

  // The same step with the smallest Python cost: only the damper force [N] comes back
  // (no report dict), for Python code that steps the loop at a real-time rate.
  double step_force(double z_r, double v_r, double u) {
    dn_loop_input in{z_r, v_r, u};
    dn_loop_out o;
    int st;
    {
      BusyGuard guard(busy, "Loop.step_force", dnpy::kLoopContract);
      CallbackRun run;
      st = dn_loop_step(model->m.get(), d.get(), &in, &o);
      run.raise_pending();
    }
    check(st, "step");
    return o.force;
  }

  // A whole road in C++ with the GIL released (see loop.py for the contract). out: None
  // (fresh arrays) or a dict with the result's keys (a previous result of the same length)
  // whose arrays are written in place and returned.
  py::dict simulate(DArray road, DArray road_rate, py::object u_obj, bool reset_first,
                    py::object out_obj) {
    if (road.ndim() != 1 || road_rate.ndim() != 1 || road.size() != road_rate.size() ||
        road.size() < 1)
      throw py::value_error("simulate: road and road_rate must be 1-D of the same length >= 1");
    const py::ssize_t n = road.size();
    // A default DArray is an empty array, not a null handle: whether u was given is has_u.
    const bool has_u = !u_obj.is_none();
    DArray u;
    if (has_u) {
      u = DArray::ensure(u_obj);
      if (!u || u.ndim() != 1 || u.size() != n)
        throw py::value_error("simulate: u must be 1-D with one value per road sample");
    }
    // A neural damper reports its inputs (dn_loop_out.n_features); the others none. (Not
    // probed with a forward call: a stateful callback damper would see an extra call.)
    const int nf = static_cast<int>(model->damper->features.size());
    py::array_t<double> states, force, control, xs, vs, as, acc_s, acc_us, feats;
    py::array_t<int32_t> status;
    if (out_obj.is_none()) {
      states = fresh_array<double>(n, DN_LOOP_STATE_SIZE);
      force = fresh_array<double>(n), control = fresh_array<double>(n), xs = fresh_array<double>(n);
      vs = fresh_array<double>(n), as = fresh_array<double>(n), acc_s = fresh_array<double>(n);
      acc_us = fresh_array<double>(n);
      feats = fresh_array<double>(n, nf);
      status = fresh_array<int32_t>(n);
    } else {
      if (!py::isinstance<py::dict>(out_obj))
        throw py::type_error("simulate: out must be None or a dict of arrays (a previous result)");
      const py::dict out = out_obj.cast<py::dict>();
      // The array under `key`, exactly of this dtype and shape, C-contiguous and writeable.
      auto take = [&](const char* key, auto proto, std::initializer_list<py::ssize_t> shape) {
        using A = decltype(proto);
        if (!out.contains(key)) throw py::value_error(std::string("simulate: out has no '") + key + "'");
        py::object o = out[key];
        if (!py::isinstance<A>(o)) throw py::value_error(std::string("simulate: out['") + key + "'] has the wrong dtype");
        A a = o.cast<A>();
        bool ok = a.ndim() == (py::ssize_t)shape.size() && a.writeable() &&
                  (a.flags() & py::array::c_style) && (a.flags() & py::detail::npy_api::NPY_ARRAY_ALIGNED_);
        int k = 0;
        for (py::ssize_t e : shape) ok = ok && a.shape(k++) == e;
        if (!ok)
          throw py::value_error(std::string("simulate: out['") + key +
                                "'] must be a writeable, aligned, C-contiguous array of the result's shape");
        return a;
      };
      using AD = py::array_t<double>;
      states = take("state", AD(), {n, (py::ssize_t)DN_LOOP_STATE_SIZE});
      force = take("force", AD(), {n});
      control = take("control", AD(), {n});
      xs = take("x", AD(), {n});
      vs = take("v", AD(), {n});
      as = take("a", AD(), {n});
      acc_s = take("acc_s", AD(), {n});
      acc_us = take("acc_us", AD(), {n});
      feats = take("features", AD(), {n, (py::ssize_t)nf});
      status = take("status", py::array_t<int32_t>(), {n});
      // The outputs are written while the inputs are read: they must not share memory.
      auto span = [](const py::array& a) {
        const char* p = static_cast<const char*>(a.data());
        return std::make_pair(p, p + a.nbytes());
      };
      const std::pair<const char*, const char*> ins[3] = {
          span(road), span(road_rate), has_u ? span(u) : std::make_pair(nullptr, nullptr)};
      const py::array outs[] = {states, force, control, xs, vs, as, acc_s, acc_us, feats, status};
      auto overlap = [](std::pair<const char*, const char*> a, std::pair<const char*, const char*> b) {
        return a.first && b.first && a.first < b.second && b.first < a.second;
      };
      for (const py::array& a : outs) {
        const auto o = span(a);
        for (const auto& i : ins)
          if (overlap(o, i))
            throw py::value_error("simulate: out's arrays must not share memory with road, road_rate or u");
        for (const py::array& b : outs)
          if (&a != &b && a.nbytes() > 0 && overlap(o, span(b)))
            throw py::value_error("simulate: out's arrays must not share memory with each other");
      }
    }
    double* S = states.mutable_data();
    double *F = force.mutable_data(), *U = control.mutable_data(), *X = xs.mutable_data(),
           *V = vs.mutable_data(), *A = as.mutable_data(), *AS = acc_s.mutable_data(),
           *AU = acc_us.mutable_data(), *FE = feats.mutable_data();
    int32_t* ST = status.mutable_data();
    const double *R = road.data(), *RR = road_rate.data(), *UU = has_u ? u.data() : nullptr;
    const dn_loop_model* m = model->m.get();
    dn_loop_data* dd = d.get();
    py::ssize_t fail_at = -1;
    int fail_status = 0;
    BusyGuard guard(busy, "Loop.simulate", dnpy::kLoopContract);
    CallbackRun run;
    {
      py::gil_scoped_release release;
      if (reset_first) dn_loop_reset(m, dd);
      double s[DN_LOOP_STATE_SIZE];
      dn_loop_get_state(dd, s);
      s[dampnet::S_z_r] = R[0];
      s[dampnet::S_v_r] = RR[0];
      fail_status = dn_loop_set_state(dd, s);
      if (fail_status < 0) fail_at = 0;
      for (py::ssize_t k = 0; k < n && fail_at < 0; ++k) {
        dn_loop_get_state(dd, S + k * DN_LOOP_STATE_SIZE);
        dn_loop_out o{};
        int st;
        if (k + 1 < n) {
          dn_loop_input in{R[k + 1], RR[k + 1], UU ? UU[k] : 0.0};
          st = dn_loop_step(m, dd, &in, &o);
        } else {
          dn_loop_input in{0.0, 0.0, UU ? UU[k] : 0.0};
          st = dn_loop_forward(m, dd, &in, &o);
        }
        ST[k] = st;
        if (st < 0) {
          fail_at = k;
          fail_status = st;
          break;
        }
        F[k] = o.force;
        U[k] = o.u;
        X[k] = o.x;
        V[k] = o.v;
        A[k] = o.a;
        AS[k] = o.acc_s;
        AU[k] = o.acc_us;
        for (int i = 0; i < nf; ++i) FE[k * nf + i] = o.features[i];
      }
    }
    run.raise_pending();
    if (fail_at >= 0)
      throw py::value_error("simulate: sample " + std::to_string(fail_at) + ": " +
                            dn_status_str(fail_status));
    py::dict r;
    r["state"] = states;
    r["force"] = force;
    r["control"] = control;
    r["x"] = xs;
    r["v"] = vs;
    r["a"] = as;
    r["acc_s"] = acc_s;
    r["acc_us"] = acc_us;
    r["features"] = feats;
    r["status"] = status;
    return r;
  }

  int64_t damper_evals() const {
    BusyGuard guard(busy, "Loop.damper_evals", dnpy::kLoopContract);
    return dn_loop_damper_evals(d.get());
  }
};

// Methods get self through constructed<C>(): pybind11 binds a member pointer as a function
// of `C*` (a pointer accepts None: `Loop.reset(None)` ran on a null `this`), and hands an
// instance made by `Loop.__new__(Loop)` without __init__ to any method as freshly allocated,
// unconstructed memory. Both are refused with TypeError here.
template <class C, class R, class... A>
auto method(R (C::*f)(A...)) {
  return [f](py::handle self, A... a) -> R { return (constructed<C>(self).*f)(std::forward<A>(a)...); };
}
template <class C, class R, class... A>
auto method(R (C::*f)(A...) const) {
  return [f](py::handle self, A... a) -> R { return (constructed<C>(self).*f)(std::forward<A>(a)...); };
}

}  // namespace

PYBIND11_MODULE(_core, mod) {
  mod.doc() =
      "dampnet C++ runtime (MLP kernel, quarter-car loop).\n\n"
      "Threading: Mlp, Damper and LoopModel are immutable once built and may be shared by "
      "threads; a Loop is one mutable loop state: one call at a time (a second call while one "
      "is under way raises RuntimeError), so give each thread its own Loop on a shared model. "
      "Loop.simulate, Mlp.predict and Damper.forces release the GIL (callback dampers hold it).";
  mod.attr("__version__") = dn_version_string();
  mod.def("version", &dn_version, "Library version as major*10000 + minor*100 + patch.");
  mod.def("status_str", &dn_status_str, "Explain a dampnet status code.");
  {
    py::dict info;
    info["kernel_isa"] = dampnet::kernel_isa();  // the SIMD path of the kernel in this build
#ifdef DN_BUILD_FLAGS
    info["flags"] = DN_BUILD_FLAGS;
#else
    info["flags"] = "";
#endif
#ifdef DN_ISA_FLAGS
    info["isa_flags"] = DN_ISA_FLAGS;
#else
    info["isa_flags"] = "";
#endif
#ifdef DAMPNET_USE_EIGEN
    info["eigen"] = true;
#else
    info["eigen"] = false;
#endif
#if defined(__clang__)
    info["compiler"] = "clang " __clang_version__;
#elif defined(__GNUC__)
    info["compiler"] = "gcc " __VERSION__;
#else
    info["compiler"] = "unknown";
#endif
    mod.attr("BUILD_INFO") = info;
  }
  mod.attr("MAX_INPUTS") = DN_MAX_INPUTS;
  mod.attr("MAX_HIDDEN") = DN_MAX_HIDDEN;
  mod.attr("DN_ACCEL_MAX_EVALS") = DN_ACCEL_MAX_EVALS;
#define DN_STATUS_ATTR_(name, value, text) mod.attr(#name) = static_cast<int>(value);
  DN_STATUS_LIST(DN_STATUS_ATTR_)
#undef DN_STATUS_ATTR_

  py::class_<PyMlp>(mod, "Mlp", "An immutable MLP model evaluated by the C++ kernel; may be shared by threads "
                          "(predict releases the GIL).")
      .def(py::init<DArray, DArray, py::object, py::object, DArray, DArray, DArray, DArray, double,
                    double, double, double, DArray, DArray, const std::string&>(),
           py::arg("w1"), py::arg("b1"), py::arg("w2"), py::arg("b2"), py::arg("w_out"),
           py::arg("b_out"), py::arg("in_offset"), py::arg("in_gain"), py::arg("in_ymin"),
           py::arg("out_offset"), py::arg("out_gain"), py::arg("out_ymin"), py::arg("sat_lo"),
           py::arg("sat_hi"), py::arg("activation"))
      .def_property_readonly("n_inputs", method(&PyMlp::n_inputs))
      .def("forward", method(&PyMlp::forward), py::arg("x"), py::arg("single") = false,
           "One sample -> (output, status, clamped_mask).")
      .def("predict", method(&PyMlp::predict), py::arg("x"), py::arg("single") = false,
           "Samples [n, n_inputs] -> (outputs[n], status[n], clamped_mask[n]); GIL released.");

  // ---- the quarter-car loop ----
  {
    py::list names;
#define DN_SNAME_(i, name, doc) names.append(#name);
    DN_LOOP_STATE_LIST(DN_SNAME_)
#undef DN_SNAME_
    mod.attr("STATE_NAMES") = py::tuple(names);
    py::list feats;
#define DN_FNAME_(id, name, field, param) feats.append(name);
    DN_FEATURE_LIST(DN_FNAME_)
#undef DN_FNAME_
    mod.attr("FEATURE_NAMES") = py::tuple(feats);
    py::dict terms;
#define DN_TINFO_(id, value, name, n, text) terms[name] = py::make_tuple(n, text);
    DN_TERM_LIST(DN_TINFO_)
#undef DN_TINFO_
    mod.attr("TERM_KINDS") = terms;
    mod.attr("VEHICLE_FIELDS") = field_docs_vehicle();
    mod.attr("CONTROLLER_FIELDS") = field_docs_controller();
    add_registries(mod);
  }
  mod.def("check_vehicle", [](py::dict vehicle) {
    const dn_vehicle v = dnpy::vehicle_from(vehicle);
    dn_controller c;
    dn_controller_default(&c, DN_CTRL_PASSIVE);
    dnpy::raise_if_invalid("", vehicle, v, py::dict(), c);
  }, py::arg("vehicle"),
     "Validate a vehicle dict (VEHICLE_FIELDS) as LoopModel does: None, or ValueError / "
     "TypeError naming the field and its valid range or names.");
  mod.def("check_controller", [](py::dict controller) {
    const dn_controller c = dnpy::controller_from(controller);
    dn_vehicle v;
    dn_vehicle_default(&v);
    dnpy::raise_if_invalid("", py::dict(), v, controller, c);
  }, py::arg("controller"),
     "Validate a controller dict (CONTROLLER_FIELDS) as LoopModel does: None, or ValueError / "
     "TypeError naming the field and its valid range or names.");

  py::class_<dn_damper_input>(mod, "DamperInput", "What a damper is evaluated on (dn_damper_input).")
      .def(py::init<>())
      .def_readwrite("x", &dn_damper_input::x)
      .def_readwrite("v", &dn_damper_input::v)
      .def_readwrite("a", &dn_damper_input::a)
      .def_readwrite("u", &dn_damper_input::u)
      .def_readwrite("u_lag", &dn_damper_input::u_lag)
      .def_readwrite("v_lag", &dn_damper_input::v_lag)
      .def_readwrite("z_fric", &dn_damper_input::z_fric)
      .def_readwrite("temperature", &dn_damper_input::temperature)
      .def_readwrite("t", &dn_damper_input::t)
      .def_readwrite("dt", &dn_damper_input::dt)
      .def_readwrite("stage", &dn_damper_input::stage);

  py::class_<PyDamper, std::shared_ptr<PyDamper>>(mod, "Damper", "A damper model (dn_damper); loop models copy it. Immutable once set up (add_term "
      "is set-up, refused while the damper is evaluated): may be shared by threads. A callback "
      "damper calls its function with the GIL held; state kept by that function (a truth "
      "damper) is the caller's to protect: use a stateful callback damper in one loop at a time.")
      .def_static("linear", &PyDamper::linear, py::arg("c"), "F = c v.")
      .def_static("parametric", &PyDamper::parametric, py::arg("c_min"), py::arg("c_max"),
                  py::arg("gamma"), py::arg("f0"), py::arg("v_max"), py::arg("v_smooth") = 0.0,
                  "The thesis's eq. 1-3 (see dn_parametric_params).")
      .def_static("table", &PyDamper::table, py::arg("velocities"), py::arg("controls"),
                  py::arg("forces"), "Bilinear lookup table, clamped outside the grid.")
      .def_static("neural", &PyDamper::neural, py::arg("mlp"), py::arg("features"),
                  py::arg("feature_params") = std::map<std::string, double>{},
                  py::arg("single") = false, "The MLP on named features.")
      .def_static("callback", &PyDamper::callback_damper, py::arg("fn"),
                  "A Python function fn(DamperInput) -> force [N] (slow path, holds the GIL).")
      .def("add_term", method(&PyDamper::add_term), py::arg("kind"), py::arg("params"),
           "Add a physics term (TERM_KINDS); set-up, before the damper is used.")
      .def_property_readonly("kind", [](py::handle p) { return dn_damper_kind_of(constructed<PyDamper>(p).d.get()); })
      .def("forces", method(&PyDamper::forces), py::arg("x"), py::arg("v"), py::arg("a"), py::arg("u"),
           py::arg("u_lag"), py::arg("temperature"),
           py::arg("v_lag") = std::numeric_limits<double>::quiet_NaN(),
           py::arg("z_fric") = std::numeric_limits<double>::quiet_NaN(),
           "Vectorised force (v_lag, z_fric default NaN: a model that reads them must be given them) -> (force[n], status[n], clamped_mask[n]); GIL released except for callback dampers.");

  py::class_<PyLoopModel, std::shared_ptr<PyLoopModel>>(mod, "LoopModel",
                                                        "Vehicle, damper and controller (constant): immutable, may drive Loops in many threads at once.")
      .def(py::init([](py::handle damper, py::dict vehicle, py::dict controller) {
             return std::make_shared<PyLoopModel>(
                 shared<PyDamper>(damper, "LoopModel: damper must be a Damper"), vehicle, controller);
           }),
           py::arg("damper"),
           py::arg("vehicle") = py::dict(), py::arg("controller") = py::dict())
      .def_property_readonly("vehicle", [](py::handle m) { return vehicle_dict(constructed<PyLoopModel>(m).veh); })
      .def_property_readonly("controller",
                             [](py::handle m) { return controller_dict(constructed<PyLoopModel>(m).ctrl); })
      .def("control", method(&PyLoopModel::control), py::arg("v_s"), py::arg("v_us"),
           py::arg("u_ext") = DArray(py::array_t<double>(py::ssize_t(1), std::array<double, 1>{0.0}.data())),
           "The control law alone on arrays of velocities.");

  {
    static PyGetSetDef getset[std::size(kStepKeys) + 1] = {};
    for (std::size_t i = 0; i < std::size(kStepKeys); ++i)
      getset[i] = {kStepKeys[i], &step_report_attr, nullptr, nullptr,
                   reinterpret_cast<void*>(static_cast<std::intptr_t>(i))};
    static const char* doc =
        "A step's report (Loop.step): read-only attributes, and a read-only mapping with the "
        "same keys (r['force'], r.keys(), dict(r)); to_dict() gives a plain dict.";
    static PyType_Slot slots[] = {{Py_tp_dealloc, reinterpret_cast<void*>(&step_report_dealloc)},
                                  {Py_tp_getset, getset},
                                  {Py_tp_doc, const_cast<char*>(doc)},
                                  {0, nullptr}};
    unsigned flags = Py_TPFLAGS_DEFAULT;
#ifdef Py_TPFLAGS_DISALLOW_INSTANTIATION
    flags |= Py_TPFLAGS_DISALLOW_INSTANTIATION;
#endif
    static PyType_Spec spec = {"dampnet._core.StepReport", int(sizeof(StepReportObject)), 0, flags,
                               slots};
    py::object tp = py::reinterpret_steal<py::object>(PyType_FromSpec(&spec));
    if (!tp) throw py::error_already_set();
    g_step_report_type = reinterpret_cast<PyTypeObject*>(tp.ptr());
    auto keys = [] {
      py::list k;
      for (const char* name : kStepKeys) k.append(name);
      return k;
    };
    auto key_str = [](py::handle key) -> std::string {
      if (!py::isinstance<py::str>(key)) throw py::key_error(py::repr(key).cast<std::string>());
      return key.cast<std::string>();
    };
    auto method = [&](const char* name, py::cpp_function f) {  // bound like a method
      py::object m = py::reinterpret_steal<py::object>(PyInstanceMethod_New(f.ptr()));
      if (!m) throw py::error_already_set();
      tp.attr(name) = m;
    };
    method("__getitem__", py::cpp_function([key_str](py::handle self, py::handle key) {
             return step_report_get(report_of(self), key_str(key));
           }));
    method("get", py::cpp_function([](py::handle self, py::handle key, py::object dflt) -> py::object {
             if (py::isinstance<py::str>(key)) {
               const std::string k = key.cast<std::string>();
               for (const char* name : kStepKeys)
                 if (k == name) return step_report_get(report_of(self), k);
             }
             return dflt;
           }, py::arg("self"), py::arg("key"), py::arg("default") = py::none()));
    method("__contains__", py::cpp_function([](py::handle, py::handle key) {
             if (!py::isinstance<py::str>(key)) return false;
             const std::string k = key.cast<std::string>();
             for (const char* name : kStepKeys)
               if (k == name) return true;
             return false;
           }));
    method("__len__", py::cpp_function([](py::handle) { return std::size(kStepKeys); }));
    method("__iter__", py::cpp_function([keys](py::handle) { return keys().attr("__iter__")(); }));
    method("keys", py::cpp_function([keys](py::handle) { return keys(); }));
    method("values", py::cpp_function([](py::handle self) {
             py::list v;
             for (const char* name : kStepKeys) v.append(step_report_get(report_of(self), name));
             return v;
           }));
    method("items", py::cpp_function([](py::handle self) {
             py::list v;
             for (const char* name : kStepKeys)
               v.append(py::make_tuple(name, step_report_get(report_of(self), name)));
             return v;
           }));
    method("to_dict", py::cpp_function([](py::handle self) {
             const StepReport& r = report_of(self);
             return out_dict(r.o, r.status);
           }));
    method("__repr__", py::cpp_function([](py::handle self) {
             const StepReport& r = report_of(self);
             return py::str("StepReport(force={!r}, u={!r}, x={!r}, v={!r}, a={!r}, status={})")
                 .format(r.o.force, r.o.u, r.o.x, r.o.v, r.o.a, r.status);
           }));
    mod.attr("StepReport") = tp;
    py::module_::import("collections.abc").attr("Mapping").attr("register")(tp);
    tp.release();  // the module keeps the type alive for g_step_report_type
  }

  py::class_<PyLoop>(mod, "Loop", "A loop's state (mutable) for a LoopModel. Not shareable: one call at a time; a second call "
      "while one is under way (from another thread, simulate releasing the GIL, or re-entered "
      "from a callback damper) raises RuntimeError and leaves the first undisturbed. Give each "
      "thread its own Loop(model) on a shared LoopModel.")
      .def(py::init([](py::handle model) {
             return std::make_unique<PyLoop>(shared<PyLoopModel>(model, "Loop: model must be a LoopModel"));
           }),
           py::arg("model"))
      .def("reset", method(&PyLoop::reset))
      .def_property("state", method(&PyLoop::get_state), method(&PyLoop::set_state), "Flat state (STATE_NAMES).")
      .def("step", method(&PyLoop::step), py::arg("z_r"), py::arg("v_r"), py::arg("u") = 0.0,
           "One step; road at the end of the step. Returns the report at the step start "
           "(a StepReport: attributes, or keys as in a dict).")
      .def("step_force", method(&PyLoop::step_force), py::arg("z_r"), py::arg("v_r"), py::arg("u") = 0.0,
           "One step, as step(), returning only the damper force [N] of its report (cheapest call).")
      .def("forward", method(&PyLoop::forward), py::arg("u") = 0.0, "The report without advancing.")
      .def("simulate", method(&PyLoop::simulate), py::arg("road"), py::arg("road_rate"),
           py::arg("u") = py::none(), py::arg("reset") = true, py::arg("out") = py::none(),
           "Run a road in C++ (GIL released) -> dict of arrays (fresh, or out's written in place). "
           "RuntimeError if the Loop is in use by another call; out's arrays must not be read or "
           "written by another thread during the run.")
      .def_property_readonly("model", [](py::handle l) { return constructed<PyLoop>(l).model; })
      .def_property_readonly("damper_evals", method(&PyLoop::damper_evals));
}
