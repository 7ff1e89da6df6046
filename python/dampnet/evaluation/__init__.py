"""Evaluation of damper models: error tables, the lookup-table baseline, plots.

  metrics.py  error_stats, evaluate_predictions, evaluate_model, format_table:
              overall / per_test / per_frequency tables as plain dicts (stable keys)
  lookup.py   LookupTable, fit_lookup: the industry's peak-force/peak-velocity table
  plots.py    PNG figures (error histogram, time series, loops, error heat map)
"""

from dampnet.evaluation.lookup import LookupTable, fit_lookup
from dampnet.evaluation.metrics import error_stats, evaluate_model, evaluate_predictions, format_table

__all__ = ["LookupTable", "fit_lookup", "error_stats", "evaluate_model", "evaluate_predictions",
           "format_table"]
