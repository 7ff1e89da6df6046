// dampnet._core.Damper and DamperInput: damper models (dn_damper_*) owned by Python. The
// DamperInput fields and Damper.forces's arguments are expanded from DN_DAMPER_INPUT_FIELDS,
// so a new input field needs no edit here.
#include "damper.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "callback_run.hpp"
#include "common.hpp"
#include "dampnet/dampnet.h"
#include "fields.hpp"
#include "mlp.hpp"

namespace dnpy {

namespace {

// The quantities a damper model may read (DN_DAMPER_INPUT_FIELDS with role QTY or QTY_OPT),
// in struct order: the arrays of Damper.forces. CTX fields (t, dt, stage) are the loop's.
#define DNPY_ROLE_QTY(...) __VA_ARGS__
#define DNPY_ROLE_QTY_OPT(...) __VA_ARGS__
#define DNPY_ROLE_CTX(...)
#define DNPY_QTY_MEMBER_(type, name, role, doc) DNPY_ROLE_##role(&dn_damper_input::name, )
double dn_damper_input::* const kQuantities[] = {DN_DAMPER_INPUT_FIELDS(DNPY_QTY_MEMBER_)};
#undef DNPY_QTY_MEMBER_
constexpr std::size_t kNumQuantities = std::size(kQuantities);
#define DNPY_QTY_NAME_(type, name, role, doc) DNPY_ROLE_##role(#name, )
const char* const kQuantityNames[] = {DN_DAMPER_INPUT_FIELDS(DNPY_QTY_NAME_)};
#undef DNPY_QTY_NAME_

// Damper.forces(self, x, v, ...): one DArray parameter per quantity; 0.1's fields are
// required, later ones (QTY_OPT) default to NaN.
#define DNPY_FORCES_PARAM_(type, name, role, doc) DNPY_ROLE_##role(, DArray name)
#define DNPY_FORCES_ARRAY_(type, name, role, doc) DNPY_ROLE_##role(&name, )
#define DNPY_ARG_QTY(name) , py::arg(#name)
#define DNPY_ARG_QTY_OPT(name) , py::arg(#name) = std::numeric_limits<double>::quiet_NaN()
#define DNPY_ARG_CTX(name)
#define DNPY_FORCES_ARG_(type, name, role, doc) DNPY_ARG_##role(name)

// Damper.inverse(self, force, x, v, a, u_lag, ...): the arrays of forces but u (the unknown).
// DNPY_IS_U_(name) is 1 for the field u, else 0 (the probe idiom: only u defines a probe).
#define DNPY_SECOND_(a, b, ...) b
#define DNPY_PROBE_CHECK_(...) DNPY_SECOND_(__VA_ARGS__, 0, )
#define DNPY_PROBE_u ~, 1,
#define DNPY_IS_U_(name) DNPY_PROBE_CHECK_(DNPY_PROBE_##name)
#define DNPY_CAT_(a, b) DNPY_CAT2_(a, b)
#define DNPY_CAT2_(a, b) a##b
#define DNPY_UNLESS_U_0(...) __VA_ARGS__
#define DNPY_UNLESS_U_1(...)
#define DNPY_UNLESS_U_(name) DNPY_CAT_(DNPY_UNLESS_U_, DNPY_IS_U_(name))
#define DNPY_INV_PARAM_(type, name, role, doc) DNPY_UNLESS_U_(name)(DNPY_FORCES_PARAM_(type, name, role, doc))
#define DNPY_IF_U_0(...)
#define DNPY_IF_U_1(...) __VA_ARGS__
#define DNPY_IF_U_(name) DNPY_CAT_(DNPY_IF_U_, DNPY_IS_U_(name))
#define DNPY_INV_ARRAY_(type, name, role, doc) \
  DNPY_ROLE_##role(DNPY_UNLESS_U_(name)(&name) DNPY_IF_U_(name)(nullptr), )
#define DNPY_INV_ARG_(type, name, role, doc) DNPY_UNLESS_U_(name)(DNPY_FORCES_ARG_(type, name, role, doc))

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
    const int st = dn_damper_create_linear(c, &r);
    if (st < 0)  // name the argument, its unit and the range (the status alone says neither)
      throw py::value_error("Damper.linear: c = " + py::str(py::float_(c)).cast<std::string>() +
                            " N s/m: expected a finite damping coefficient >= 0 (" + dn_status_str(st) + ")");
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
    const dn_mlp* mlp = mlp_handle(mlp_obj);
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
    const int st = dn_damper_create_neural(mlp, names.data(), (int)names.size(),
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
        throw py::type_error("Damper.callback: the function returned " + describe(r) +
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

  // Vectorised force of the model plus terms: one array per quantity field of
  // dn_damper_input (kQuantities order); arrays broadcast to one length.
  py::tuple forces(const DArray* const* arrs) {
    py::ssize_t n = 1;
    for (std::size_t q = 0; q < kNumQuantities; ++q) {
      const DArray& p = *arrs[q];
      if (p.size() != 1) {
        if (n != 1 && p.size() != n) throw py::value_error("forces: arrays differ in length");
        n = p.size();
      }
    }
    py::array_t<double> f(n);
    py::array_t<int32_t> st(n);
    py::array_t<uint32_t> mask(n);
    auto at = [](const DArray& arr, py::ssize_t i) { return arr.size() == 1 ? arr.data()[0] : arr.data()[i]; };
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
        for (std::size_t q = 0; q < kNumQuantities; ++q) in.*kQuantities[q] = at(*arrs[q], i);
        sp[i] = dn_damper_force(d.get(), &in, &fp[i], &mp[i]);
      }
    }
    run.raise_pending();
    return py::make_tuple(f, st, mask);
  }

  // Vectorised dn_damper_terms_grad at (x, v, u) (the other fields 0): the terms' force and
  // its derivatives. No callback runs (terms only), so the GIL is released.
  py::tuple terms_grad(DArray x, DArray v, DArray u) {
    const DArray* arrs[] = {&x, &v, &u};
    py::ssize_t n = 1;
    for (const DArray* p : arrs)
      if (p->size() != 1) {
        if (n != 1 && p->size() != n) throw py::value_error("terms_grad: arrays differ in length");
        n = p->size();
      }
    py::array_t<double> f(n), gx(n), gv(n), gu(n);
    py::array_t<int32_t> st(n);
    auto at = [](const DArray& arr, py::ssize_t i) { return arr.size() == 1 ? arr.data()[0] : arr.data()[i]; };
    double *fp = f.mutable_data(), *gxp = gx.mutable_data(), *gvp = gv.mutable_data(), *gup = gu.mutable_data();
    int32_t* sp = st.mutable_data();
    {
      py::gil_scoped_release rel;
      for (py::ssize_t i = 0; i < n; ++i) {
        dn_damper_input in{};
        in.x = at(x, i);
        in.v = at(v, i);
        in.u = at(u, i);
        double g[3];
        sp[i] = dn_damper_terms_grad(d.get(), &in, &fp[i], g);
        gxp[i] = g[0];
        gvp[i] = g[1];
        gup[i] = g[2];
      }
    }
    return py::make_tuple(f, gx, gv, gu, st);
  }

  // Vectorised inverse (dn_damper_inverse): the demanded force and one array per quantity but
  // u (nullptr in arrs), broadcast to one length. Every damper kind without a control
  // (callback included) is refused by the runtime before any evaluation: the GIL is released.
  py::tuple inverse(const DArray& demand, const DArray* const* arrs, const DArray* u_start) {
    py::ssize_t n = demand.size();
    if (n == 0) throw py::value_error("inverse: force is empty");
    if (u_start) {
      if (u_start->size() == 0) throw py::value_error("inverse: u_start is empty");
      if (u_start->size() != 1) {
        if (n != 1 && u_start->size() != n) throw py::value_error("inverse: u_start and force differ in length");
        n = u_start->size();
      }
    }
    for (std::size_t q = 0; q < kNumQuantities; ++q) {
      if (!arrs[q]) continue;
      const DArray& p = *arrs[q];
      if (p.size() == 0) throw py::value_error("inverse: an input array is empty");
      if (p.size() != 1) {
        if (n != 1 && p.size() != n) throw py::value_error("inverse: arrays differ in length");
        n = p.size();
      }
    }
    py::array_t<double> u(n), f(n);
    py::array_t<int32_t> st(n), evals(n);
    auto at = [](const DArray& arr, py::ssize_t i) { return arr.size() == 1 ? arr.data()[0] : arr.data()[i]; };
    double* up = u.mutable_data();
    double* fp = f.mutable_data();
    int32_t* sp = st.mutable_data();
    int32_t* ep = evals.mutable_data();
    {
      py::gil_scoped_release rel;
      for (py::ssize_t i = 0; i < n; ++i) {
        dn_damper_input in{};
        for (std::size_t q = 0; q < kNumQuantities; ++q)
          if (arrs[q]) in.*kQuantities[q] = at(*arrs[q], i);
        int k = 0;
        sp[i] = u_start ? dn_damper_inverse_near(d.get(), &in, at(demand, i), at(*u_start, i), &up[i], &fp[i], &k)
                        : dn_damper_inverse(d.get(), &in, at(demand, i), &up[i], &fp[i], &k);
        ep[i] = k;
      }
    }
    return py::make_tuple(u, f, st, evals);
  }
};

}  // namespace

DamperRef damper_ref(py::handle damper, const char* what) {
  std::shared_ptr<PyDamper> p = shared<PyDamper>(damper, what);
  DamperRef r;
  r.n_features = static_cast<int>(p->features.size());
  r.d = std::shared_ptr<const dn_damper>(p, p->d.get());  // shares p's ownership
  return r;
}

void bind_damper(py::module_& mod) {
  py::class_<dn_damper_input>(mod, "DamperInput", "What a damper is evaluated on (dn_damper_input).")
      .def(py::init<>())
#define DNPY_INPUT_RW_(type, name, role, doc) .def_readwrite(#name, &dn_damper_input::name, doc)
      DN_DAMPER_INPUT_FIELDS(DNPY_INPUT_RW_);
#undef DNPY_INPUT_RW_


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
      .def("terms_grad", method(&PyDamper::terms_grad), py::arg("x"), py::arg("v"), py::arg("u"),
           "The physics terms alone at (x [m], v [m/s], u [V or A]), vectorised -> (force [N], "
           "dF/dx [N/m], dF/dv [N s/m], dF/du [N per control unit], status) "
           "(dn_damper_terms_grad; dF/da is 0: no term reads the acceleration).")
      .def_property_readonly("kind", [](py::handle p) { return dn_damper_kind_of(constructed<PyDamper>(p).d.get()); })
      .def("forces",
           [](py::handle self DN_DAMPER_INPUT_FIELDS(DNPY_FORCES_PARAM_)) {
             const DArray* arrs[] = {DN_DAMPER_INPUT_FIELDS(DNPY_FORCES_ARRAY_)};
             static_assert(std::size(arrs) == kNumQuantities, "one array per quantity");
             return constructed<PyDamper>(self).forces(arrs);
           } DN_DAMPER_INPUT_FIELDS(DNPY_FORCES_ARG_),
           "Vectorised force of the model plus terms -> (force[n] [N], status[n], "
           "clamped_mask[n]); one array (or scalar) per quantity of DAMPER_INPUT_FIELDS, "
           "broadcast to one length. Fields appended after 0.1 default to NaN: a model that "
           "reads them must be given them. GIL released except for callback dampers.")
      .def("inverse",
           [](py::handle self, DArray force DN_DAMPER_INPUT_FIELDS(DNPY_INV_PARAM_), std::optional<DArray> u_start) {
             const DArray* arrs[] = {DN_DAMPER_INPUT_FIELDS(DNPY_INV_ARRAY_)};
             static_assert(std::size(arrs) == kNumQuantities, "one slot per quantity");
             return constructed<PyDamper>(self).inverse(force, arrs, u_start ? &*u_start : nullptr);
           },
           py::arg("force") DN_DAMPER_INPUT_FIELDS(DNPY_INV_ARG_), py::kw_only(), py::arg("u_start") = py::none(),
           "Vectorised inverse (dn_damper_inverse): the control [V or A] within the control "
           "range (control_range) at which the force equals the demand force [N] at the given "
           "motion and states (every quantity of forces but u) -> (u[n], force[n] [N] achieved, "
           "status[n], evaluations[n]); DN_W_UNREACHABLE: no control gives the demand (outside "
           "the forces at the control limits), the nearer limit is returned. Arrays broadcast to "
           "one length. evaluations: every force evaluation made, the limits' included (a neural "
           "damper starts at its first-iterate grid's control: 2 for most reachable demands). "
           "u_start [V or A] (keyword, array or scalar): a control near the answer to start "
           "Newton's steps from instead (dn_damper_inverse_near, a controller's last command). "
           "GIL released.")
      .def("control_range",
           [](py::handle self) {
             dn_real lo = 0, hi = 0;
             const int st = dn_damper_control_range(constructed<PyDamper>(self).d.get(), &lo, &hi);
             if (st < 0) throw py::value_error(std::string("Damper.control_range: ") + dn_status_str(st));
             return py::make_tuple(double(lo), double(hi));
           },
           "(u_min, u_max) [V or A]: the control range the inverse searches (ValueError for a "
           "damper whose force does not depend on u, or a callback damper).")
      .def("control_monotonicity",
           [](py::handle self, double v_min, double v_max, int n_v, int n_u, double tolerance_N,
              const std::map<std::string, double>& at) {
             const PyDamper& p = constructed<PyDamper>(self);
             dn_damper_input in{};
             for (const auto& kv : at) {
               std::size_t q = 0;
               while (q < kNumQuantities && kv.first != kQuantityNames[q]) ++q;
               if (q == kNumQuantities || kv.first == "v" || kv.first == "u")
                 throw py::value_error("Damper.control_monotonicity: at: unknown or scanned quantity '" +
                                       kv.first + "' (give x, a, u_lag, temperature or a state)");
               in.*kQuantities[q] = kv.second;
             }
             dn_monotonicity r{};
             int st;
             {
               py::gil_scoped_release rel;  // (a callback damper is refused before any call)
               st = dn_damper_control_monotonicity(p.d.get(), &in, v_min, v_max, n_v, n_u, tolerance_N, &r);
             }
             if (st < 0) throw py::value_error(std::string("Damper.control_monotonicity: ") + dn_status_str(st));
             py::dict out;
             out["n_reversed"] = r.n_reversed;
             out["v_worst"] = double(r.v_worst);
             out["u_from"] = double(r.u_from);
             out["u_to"] = double(r.u_to);
             out["reversal_N"] = double(r.reversal_N);
             return out;
           },
           py::arg("v_min"), py::arg("v_max"), py::arg("n_v") = 101, py::arg("n_u") = 201,
           py::arg("tolerance_N") = 0.0, py::arg("at") = std::map<std::string, double>{},
           "dn_damper_control_monotonicity: scan F over n_v velocities in [v_min, v_max] [m/s] x "
           "n_u controls of control_range, the other quantities from `at` (default 0); -> "
           "{n_reversed, v_worst [m/s], u_from, u_to [V or A], reversal_N [N]} of the largest "
           "turn of F(u) against its direction (all 0: monotone beyond tolerance_N [N]).");
}

}  // namespace dnpy
