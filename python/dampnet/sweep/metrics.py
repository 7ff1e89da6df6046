"""The metrics a cell reports: the table's metric columns, in order, and which may be an objective.

Training (dampnet.sweep.train_cell): NRMSE = RMSE / the force range of the data it is measured
on (the hold-out tests, the training subsets), errors in N, times in s. Simulation
(dampnet.sweep.sim_cell): dampnet.sim.ride.ride_metrics in SI units (m/s^2, m, N), the static
damper force f_static_n [N], the transmissibility peak of sine-sweep roads.
"""

TRAINING = ("holdout_nrmse", "holdout_rmse_n", "holdout_max_abs_error_n", "lookup_holdout_nrmse",
            "train_nrmse", "val_nrmse", "test_nrmse", "noise_floor_nrmse", "epochs", "stop_reason",
            "train_time_s", "n_inputs", "features_used", "model_id")
SIMULATION = ("acc_rms_m_s2", "acc_wk_rms_m_s2", "acc_peak_m_s2", "disp_rms_m", "disp_peak_to_rms",
              "travel_rms_m", "travel_max_m", "tyre_load_rms_n", "tyre_load_rms_rel", "duration_s", "dt_s",
              "f_static_n", "transmissibility_peak", "transmissibility_peak_hz")
BY_KIND = {"training": TRAINING, "simulation": SIMULATION}
#: metrics that are not numbers (never an objective)
TEXT = ("stop_reason", "features_used", "model_id")


def objectives(kind: str) -> list[str]:
    """The metrics of `kind` a spec may name as its objective (numbers; lower is better)."""
    return [m for m in BY_KIND[kind] if m not in TEXT]
