"""The quarter car: the runtime's loop from Python, dampers, roads, ride metrics, the thesis's study.

  loop.py            QuarterCar and damper_from_model: the one driver of dampnet._core.Loop
  study.py           damper specs, calibration, the chapter 5 study, its tables and plots
  ride.py            ride metrics (ISO 2631-1 Wk weighting, transmissibility, travel, tyre load)
  reference_loop.py  the same loop in Python: the test oracle, and the home of the truth damper's runs
  roads/             road profiles (impulse, sweep, ISO 8608, the thesis road, CSV) and the IRI
"""
