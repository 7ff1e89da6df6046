"""Simulation: the runtime's quarter car and full vehicle from Python, and what the two share.

Shared, one job per module:

  vehicle.py         Vehicle and Controller: the runtime's dn_vehicle / dn_controller (its
                     defaults, law names and validation, read from dampnet._core)
  roads/             road profiles (impulse, sweep, ISO 8608, the thesis road, CSV) and the IRI
  ride.py            ride metrics (ISO 2631-1 Wk weighting, transmissibility, travel, tyre load)
  dampers.py         damper specs (truth, neural, hybrid, lookup, linear), load_spec, their
                     runtime dampers and steady forces
  calibration.py     damping levels, equivalent damping, the semi-active controllers
  limits.py          the ranges of a run's settings and the size a run may reach
  monotonicity.py    is a damper's force monotone in its control (its inverse unique)? where it turns back
  plots.py           plots of runs and of a study (and the plotting set-up both cars use)
  run_dir.py         a run's directory as `simulate` and `vehicle` write it (schema, files, staged writing)

quarter_car/ (cpp/include/dampnet/loop.hpp), each module importing only the ones above it:

  loop.py            QuarterCar and damper_from_model: the one driver of dampnet._core.Loop
  runs.py            one run of a damper spec over a road (through loop.py) with its metrics
  study.py           the chapter 5 study (run_study)
  report.py          a study's text tables and JSON form
  reference_loop.py  the same loop in Python: the test oracle, used by tests only

full_car/ (cpp/include/dampnet/fullcar.hpp): the full vehicle, four dampers in a ride-and-handling
model (its parameters, manoeuvres, metrics, runs, study and plots).
"""
