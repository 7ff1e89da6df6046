// What every part of dampnet._core shares: status -> exception (check()), the array type
// the bindings take, the safe access to a bound object (constructed / shared / method),
// and each part's bind_* entry point (called by module.cpp).
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <typeinfo>
#include <utility>

#include "dampnet/dampnet.h"
#include "fields.hpp"

namespace dnpy {

namespace py = pybind11;

// Arrays the bindings read: C-contiguous doubles (other dtypes and layouts are converted).
using DArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

// A negative C status as ValueError: "what: DN_E_...: explanation".
inline void check(int status, const std::string& what) {
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
    throw py::type_error(std::string("expected a ") + ti->type->tp_name + ", got " + describe(h));
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

// A second __init__ on an initialised object: pybind11 ignores it (its dispatcher returns None
// before the constructor runs, the object keeps its old value), so a caller re-initialising one
// believes it changed. refuse_reinit wraps the class's __init__: an initialised object is refused
// with TypeError; anything else (a new object, a wrong self) goes to pybind11's own.
template <class C>
bool initialised(py::handle h) {
  static const py::detail::type_info* const ti = py::detail::get_type_info(typeid(C));
  if (!ti || !h || !PyObject_TypeCheck(h.ptr(), ti->type)) return false;
  auto vh = reinterpret_cast<py::detail::instance*>(h.ptr())->get_value_and_holder(ti, false);
  return vh && vh.holder_constructed();
}
template <class C, class... O>
void refuse_reinit(py::class_<C, O...>& cls) {
  py::object init = cls.attr("__init__");
  const std::string name = py::str(cls.attr("__name__"));
  const std::string doc = py::str(init.attr("__doc__"));
  cls.attr("__init__") = py::cpp_function(
      [init, name](py::handle self, py::args args, py::kwargs kwargs) {
        if (initialised<C>(self))
          throw py::type_error(name + ".__init__: this " + name +
                               " is already initialised; make a new " + name + " instead");
        init(self, *args, **kwargs);
      },
      // not named "__init__": pybind11 would take it for a constructor and skip it the same way
      py::is_method(cls), py::name("init_once"), py::doc(doc.c_str()));
}

// The parts of the module, in the order module.cpp binds them.
void bind_registries(py::module_& mod);   // registries.cpp: version, constants, name lists
void bind_mlp(py::module_& mod);          // mlp.cpp: Mlp
void bind_damper(py::module_& mod);       // damper.cpp: DamperInput, Damper
void bind_step_report(py::module_& mod);  // step_report.cpp: StepReport
void bind_loop(py::module_& mod);         // loop.cpp: LoopModel, Loop
void bind_fullcar(py::module_& mod);      // fullcar.cpp: FullCarModel, FullCar
void bind_envelope(py::module_& mod);     // envelope.cpp: Envelope

}  // namespace dnpy
