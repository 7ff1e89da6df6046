"""The metrics a cell reports: the table's metric columns, in order, and which may be an objective.

Training (dampnet.sweep.train_cell): NRMSE = RMSE / the force range of the data it is measured
on (the hold-out tests, the training subsets), errors in N, times in s; algorithm_used: the algorithm trained with (the cell's, or what
'auto' chose). Simulation
(dampnet.sweep.sim_cell): dampnet.sim.ride.ride_metrics in SI units (m/s^2, m, N), the static
damper force f_static_n [N], the transmissibility peak of sine-sweep roads. Full vehicle
(dampnet.sweep.fullcar_cell): the metrics of the cell's test (its entry's columns in
dampnet.recipes.maneuvers, every test's in registry order), as `dampnet vehicle` reports them (units in the names: m_s2 = m/s^2, rad_s2, deg, deg_s = deg/s, n = N; counts:
cones_hit, cones; passed: no cone hit), the road test's dynamic tyre load RMS one column per
wheel (fl, fr, rl, rr), the damper's force at rest f_static_n [N] and the run's duration_s [s];
a metric the cell's test does not measure is empty.
Both simulation kinds, for a neural or hybrid model (dampnet.envelope.coverage): time_outside_training_data,
the share [0-1] of the run's time its damper inputs spent outside the model's training envelope,
and extrapolated, the verdict "yes" or "no" (both empty for the truth, lookup and linear dampers).
"""

#: coverage columns of the simulation kinds (dampnet.envelope.coverage; empty for non-neural dampers)
COVERAGE = ("time_outside_training_data", "extrapolated")

TRAINING = ("holdout_nrmse", "holdout_rmse_n", "holdout_max_abs_error_n", "lookup_holdout_nrmse",
            "train_nrmse", "val_nrmse", "test_nrmse", "noise_floor_nrmse", "epochs", "stop_reason",
            "algorithm_used", "train_time_s", "n_inputs", "features_used", "model_id")
SIMULATION = ("acc_rms_m_s2", "acc_wk_rms_m_s2", "acc_peak_m_s2", "disp_rms_m", "disp_peak_to_rms",
              "travel_rms_m", "travel_max_m", "tyre_load_rms_n", "tyre_load_rms_rel", "duration_s", "dt_s",
              "f_static_n", "transmissibility_peak", "transmissibility_peak_hz") + COVERAGE
#: the wheels of per-wheel full-car metrics (FL, FR, RL, RR: the runtime's corner order)
WHEELS = ("fl", "fr", "rl", "rr")


def fullcar() -> tuple[str, ...]:
    """A full-vehicle cell's columns: every test's metrics (dampnet.recipes.maneuvers, read now: a
    test registered later counts), then the damper's force at rest, the run's duration, coverage."""
    from dampnet.recipes.maneuvers import metric_columns

    return metric_columns() + ("f_static_n", "duration_s") + COVERAGE


#: each kind's metric columns, in order
BY_KIND = {"training": lambda: TRAINING, "simulation": lambda: SIMULATION, "fullcar": fullcar}
#: metrics that are not numbers (never an objective)
TEXT = ("stop_reason", "algorithm_used", "features_used", "model_id", "passed", "extrapolated")


def coverage_columns(res: dict) -> dict:
    """The COVERAGE cells of a simulation result (dampnet.sim.quarter_car.runs.simulate, dampnet.sim.full_car.runs.run)."""
    cov = res.get("coverage")
    if cov is None:
        return {}
    return {"time_outside_training_data": float(cov["outside"]["share_time"]),
            "extrapolated": "yes" if cov["extrapolated"] else "no"}  # text: a bool column with gaps is not one in Parquet


def objectives(kind: str) -> list[str]:
    """The metrics of `kind` a spec may name as its objective (numbers; lower is better)."""
    return [m for m in BY_KIND[kind]() if m not in TEXT]
