"""The full vehicle: four dampers in a ride-and-handling model (the thesis's chapter 5.2).

The runtime's full-car model (cpp/include/dampnet/fullcar.hpp, dampnet._core.FullCar) from
Python: its parameters, the thesis's tests (bounce sine sweep, ISO 3888-1 double lane change,
rough road), their metrics, the comparison of damper models, and plots. One job per module.
"""
