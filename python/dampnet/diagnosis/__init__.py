"""Diagnose the missing physics of a damper model (issue 6).

  catalogue.py  candidate effects (gas_spring, thermal, valve_lag, friction, compressibility),
                keyed by the effect catalogue dampnet.effects (ids, titles, physics, what
                --add adds): residual signature, regressors, parameters.
                Users add their own with register_candidate after dampnet.effects.register_effect.
  basis.py      the baseline: a flexible function of the model's own inputs
  score.py      cross-validation over tests, phase-randomised null, significance
  localise.py   where the model fails (by test, within the cycle)
  leftover.py   is structure left at all? a catalogue-independent regression on the inputs'
                history, scored like a candidate; the noise floor; where the structure is
  artefacts.py  tests for the measurement artefacts of dampnet.data.artefacts (time offset, run-order
                drift, sign/unit slips, sensor offsets)
  verdict.py    the three-way verdict: known effect / structure left, not a known effect /
                nothing the inputs predict: noise, or, with the residual well above the force's
                noise, capacity or an unrecorded difference that these data cannot tell apart (or an
                artefact, alone or with the structure left beyond its fix)
  run.py        diagnose(model, dataset) -> JSON-ready dict
  estimate.py   an effect's parameters from data alone (`dampnet train --add` without --diagnosis)
  report.py     the HTML report with pictures
"""

from dampnet.diagnosis.catalogue import CANDIDATES, Candidate, register_candidate
from dampnet.diagnosis.run import diagnose

__all__ = ["CANDIDATES", "Candidate", "diagnose", "register_candidate"]
