"""`dampnet demo`: the whole story on the embedded default (the virtual rig), end to end.

Stages (each timed, each shown on the terminal as it runs):
  1 rig        the thesis's test campaign (Table 2) on the virtual dyno, with the gas
               charge's position-dependent force switched on (hidden from the model's inputs)
  2 train      the thesis's 3-30-1 MLP (velocity, acceleration, voltage) with LM, evaluated on
               the held-out 2.25 V tests beside the lookup-table baseline
  3 diagnose   where the model fails and which physical effect is missing
  4 improve    the diagnosed effect added, retrained, the error falling; diagnosed again
  5 export     the improved model's header compiled into a C program against the C library,
               run, and checked against Python
  6 fmu        the improved model as an FMI 2.0 FMU, simulated by FMPy on a held-out test and
               checked against the runtime's forces (fmucheck.py)
  7 study      the quarter-car study (thesis Tables 6, 7, skyhook): improved, original,
               lookup table and the truth damper
  8 vehicle    the full vehicle (thesis chapter 5.2): bounce sine sweep and lane change
  9 latency    the quick latency benchmark and the HIL headroom
Output (never overwritten without force): report.html, summary.json, models, header, data.

`dampnet demo --data DATA` (dampnet.demo.on_data.run_data_demo) runs the diagnosis loop on the
user's own data instead: train, diagnose, add what is named, retrain, report before and after.
"""

from dampnet.demo.on_data import run_data_demo
from dampnet.demo.run import DemoError, run_demo

__all__ = ["DemoError", "run_data_demo", "run_demo"]
