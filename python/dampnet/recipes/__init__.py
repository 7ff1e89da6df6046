"""The vocabulary of runs, defined once: each module is one registry that every front end
(the CLI, the sweep's TOML, `plan-tests`, the Python API) parses into and none keeps its own list.

Modules (one vocabulary each; docs/recipes.md says how to add an entry to each):
- `roads`: road profiles (name, parameters with units, builder);
- `control_laws`: semi-active control laws (passive levels, skyhook, ...);
- `maneuvers`: full-vehicle manoeuvres (builder, parameters with units, metrics, plot, headline);
- `training`: a training request (features, algorithm, restarts, average, seed, hold-out);
- `export_targets`: what `dampnet export` can write, and which options apply to each.
"""
