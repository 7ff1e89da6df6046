"""The quarter car (cpp/include/dampnet/loop.hpp, dampnet._core.Loop) from Python: the loop's
driver, one run over a road with its metrics, the thesis's chapter 5 study and its report, and
the same loop in Python as the tests' oracle (dampnet.sim's docstring lists the modules)."""
