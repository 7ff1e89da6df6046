"""Ride metrics of quarter-car runs (ISO 2631-1 Wk weighting, transmissibility, travel, tyre load)."""

from dampnet.ride.metrics import (WK, WK_TABLE, peak_to_rms, ride_metrics, rms, transmissibility,
                                  wk_analog, wk_sos, wk_weighted)

__all__ = ["WK", "WK_TABLE", "wk_analog", "wk_sos", "wk_weighted", "rms", "peak_to_rms",
           "transmissibility", "ride_metrics"]
