"""The quarter car: the runtime's loop from Python, dampers, roads, ride metrics, the thesis's study.

One job per module, each importing only the ones above it in this list:

  vehicle.py         Vehicle and Controller: the runtime's dn_vehicle / dn_controller (its
                     defaults, law names and validation, read from dampnet._core)
  loop.py            QuarterCar and damper_from_model: the one driver of dampnet._core.Loop
  roads/             road profiles (impulse, sweep, ISO 8608, the thesis road, CSV) and the IRI
  ride.py            ride metrics (ISO 2631-1 Wk weighting, transmissibility, travel, tyre load)
  dampers.py         damper specs (truth, neural, hybrid, lookup, linear), load_spec, their
                     runtime dampers and steady forces
  calibration.py     damping levels, equivalent damping, the semi-active controllers
  runs.py            one run of a damper spec over a road (through loop.py) with its metrics
  study.py           the chapter 5 study (run_study)
  report.py          a study's text tables and JSON form
  plots.py           plots of runs and of a study
  reference_loop.py  the same loop in Python: the test oracle, used by tests only
"""
