"""Diagnose the missing physics of a damper model (issue 6).

  catalogue.py  candidate effects (gas_spring, thermal, valve_lag, friction, compressibility):
                physics, residual signature, regressors, parameters, what --add adds.
                Users add their own with register_candidate (one place).
  basis.py      the baseline: a flexible function of the model's own inputs
  score.py      cross-validation over tests, phase-randomised null, significance
  localise.py   where the model fails (by test, within the cycle)
  run.py        diagnose(model, dataset) -> JSON-ready dict
  report.py     the HTML report with pictures
  features.py   re-exports the derived features of dampnet.features
"""

from dampnet.diagnosis.catalogue import CANDIDATES, Candidate, additions, register_candidate
from dampnet.diagnosis.run import diagnose

__all__ = ["CANDIDATES", "Candidate", "additions", "diagnose", "register_candidate"]
