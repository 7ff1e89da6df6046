"""The derived features the diagnosis adds (voltage_lag/current_lag, velocity_lag,
friction_state) live in dampnet.train.derived, registered with every training feature;
re-exported here for the diagnosis."""

from dampnet.train.derived import LAG_FEATURES, dahl_state, first_order_lag

__all__ = ["LAG_FEATURES", "dahl_state", "first_order_lag"]
