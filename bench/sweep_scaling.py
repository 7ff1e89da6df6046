"""How `dampnet sweep` scales: cells per second with 1 and 2 workers, the per-cell cost, the scheduler's
overhead per task, and what a cluster of N machines would give.

Measured, in this order:
  1. per-cell cost in this process, one thread (dampnet.sweep.tasks.run_cell, warmed up): a training
     cell (rig quick plan with gas_spring, LM / SCG, decimate 25, 60 epochs) and a simulation cell
     (default model, ISO class C road of 200 m at 15 m/s: 13,334 loop steps, passive / skyhook);
  2. the scheduler's overhead per task: many no-op tasks on an embedded cluster of 1 and of 2
     workers (wall time / tasks: submission, scheduling, the round trip, the result);
  3. the sweep itself (dampnet.sweep.run on an already started cluster, progress off, writing its
     sweep directory as the command does) with 1 and 2 workers: a training sweep (16 cells) and a
     simulation sweep (48 cells); cells per second (from the first submission to the last cell
     saved: cells_s), the speed-up, the sweep's overhead per cell (cells_s x workers / cells - the
     mean cell time on its worker: scheduling, shipping the result, saving the cell and its model
     directory), the cores the workers actually got (their CPU time / cells_s: below the worker
     count when other processes share the machine), and the final table/summary/plots time;
  4. the cluster's start (LocalCluster of 2 processes) and the workers' warm-up (imports);
  and, before and after, the cores free on this machine (one spinning process per core for 1 s:
  their CPU time / 1 s), so that a run on a shared machine says how much of it it had.

Usage:  python bench/sweep_scaling.py [--json FILE] [--noop 400]   (about a minute)

Measured on the 2-core session VM with both cores free (bench/RESULTS.md, "Sweeps on Dask";
bench/sweep_scaling_results.json): training 2.19 -> 3.78 cells/s (1.73x), simulation
78 -> 102 cells/s (1.30x) from 1 to 2 workers; overhead 1.4-3.1 ms per cell, 1.55 ms per no-op task.
The estimate for N machines of c cores: cells/s = N c / (t_cell + t_overhead), capped by the one
scheduler at about 1 / t_sched (t_sched: its own time per task, from 2. with 2 workers).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time


TRAIN = {"training": {"datasets": ["rig:quick"], "rig_effects": [["gas_spring"]], "algorithms": ["lm", "scg"],
                      "add": ["none", "gas_spring"], "seeds": [0, 1, 2, 3], "decimate": 25, "max_epochs": 60}}
SIM = {"simulation": {"models": ["default"], "roads": ["iso:C"], "road_length_m": 200.0,
                      "road_seeds": [0, 1, 2, 3, 4, 5], "speeds": [10.0, 15.0, 20.0, 25.0],
                      "controllers": ["passive_high", "skyhook_onoff"]}}


def noop(i):
    return i


def _spin(seconds: float) -> float:
    t, c = time.perf_counter(), time.process_time()
    while time.perf_counter() - t < seconds:
        pass
    return time.process_time() - c


def free_cores(seconds: float = 1.0) -> float:
    """The cores this machine gives us now: one spinning process per core for `seconds`, the sum of
    their CPU time / seconds (below the core count when other work shares the machine)."""
    import multiprocessing as mp

    n = len(os.sched_getaffinity(0))
    with mp.get_context("spawn").Pool(n) as pool:
        return sum(pool.map(_spin, [seconds] * n)) / seconds


def cell_cost(spec: dict, repeats: int) -> dict:
    """Median wall time [s] of the spec's first cells run here, one after the other (warmed up)."""
    from dampnet.sweep.grid import expand
    from dampnet.sweep.inputs import bind
    from dampnet.sweep.spec import parse_spec
    from dampnet.sweep.tasks import run_cell, warm

    sp = parse_spec(spec)
    cells = expand(sp)
    bind(cells, sp)
    warm(sorted(sp.sections))
    run_cell(cells[0].kind, cells[0].params, cells[0].inputs)          # warm-up
    times = []
    for c in (cells * repeats)[: max(repeats, 4)]:
        t = time.perf_counter()
        r = run_cell(c.kind, c.params, c.inputs)
        assert r["status"] == "ok", r
        times.append(time.perf_counter() - t)
    return {"median_s": statistics.median(times), "min_s": min(times), "n": len(times)}


def scheduler_overhead(client, n: int) -> float:
    """Wall time per no-op task [s] (n tasks submitted at once, gathered)."""
    client.gather(client.map(noop, range(50), pure=False))           # warm-up
    t = time.perf_counter()
    client.gather(client.map(noop, range(n), pure=False))
    return (time.perf_counter() - t) / n


def sweep_rate(client, spec: dict, workers: int) -> dict:
    """The sweep as the command runs it: cells saved to a sweep directory, model directories, table."""
    import tempfile

    from dampnet.sweep import run

    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        df = run(spec, client=client, out=os.path.join(tmp, "out"), progress=False)
        wall = time.perf_counter() - t
    assert (df["status"] == "ok").all(), df[["status", "error"]]
    mean_cell = float(df["time_s"].mean())
    st = df.attrs["sweep"]
    return {"cells": int(len(df)), "wall_s": wall, "cells_s": st["cells_s"], "results_s": st["results_s"],
            "cells_per_s": len(df) / st["cells_s"], "mean_cell_s": mean_cell,
            "mean_cell_cpu_s": float(df["cpu_s"].mean()),
            "cores_used": float(df["cpu_s"].sum()) / st["cells_s"],
            "overhead_per_cell_s": st["cells_s"] * workers / len(df) - mean_cell}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", default=None, help="write the results here")
    ap.add_argument("--noop", type=int, default=400, help="no-op tasks for the scheduler's overhead")
    args = ap.parse_args()
    from dampnet.sweep.runner import session
    from dampnet.sweep.tasks import warm

    out: dict = {"machine": {"cores": len(os.sched_getaffinity(0)), "load_1min_before": os.getloadavg()[0],
                             "free_cores_before": free_cores()}}
    print(f"{out['machine']['cores']} cores, {out['machine']['free_cores_before']:.2f} free before (load "
          f"{out['machine']['load_1min_before']:.2f})")
    out["cell_cost"] = {"training": cell_cost(TRAIN, 6), "simulation": cell_cost(SIM, 12)}
    print(f"per-cell cost here (1 thread): training {out['cell_cost']['training']['median_s'] * 1e3:.0f} ms, "
          f"simulation {out['cell_cost']['simulation']['median_s'] * 1e3:.1f} ms (medians)")
    for w in (1, 2):
        t = time.perf_counter()
        with session(workers=w) as (client, _):
            started = time.perf_counter() - t
            t = time.perf_counter()
            client.run(warm, ["simulation", "training"])
            warmed = time.perf_counter() - t
            r = {"start_s": started, "warm_s": warmed,
                 "noop_per_task_s": scheduler_overhead(client, args.noop),
                 "training": sweep_rate(client, TRAIN, w), "simulation": sweep_rate(client, SIM, w)}
        out[f"workers_{w}"] = r
        print(f"{w} worker(s): cluster start {started:.2f} s, warm-up {warmed:.2f} s; no-op task "
              f"{r['noop_per_task_s'] * 1e3:.2f} ms; training {r['training']['cells_per_s']:.2f} cells/s "
              f"(cell {r['training']['mean_cell_s'] * 1e3:.0f} ms, overhead {r['training']['overhead_per_cell_s'] * 1e3:.1f} "
              f"ms/cell, results {r['training']['results_s']:.2f} s, cores used {r['training']['cores_used']:.2f}); simulation {r['simulation']['cells_per_s']:.1f} cells/s (cell "
              f"{r['simulation']['mean_cell_s'] * 1e3:.1f} ms, overhead {r['simulation']['overhead_per_cell_s'] * 1e3:.1f} ms/cell, "
              f"cores used {r['simulation']['cores_used']:.2f})")
    for kind in ("training", "simulation"):
        s = out["workers_2"][kind]["cells_per_s"] / out["workers_1"][kind]["cells_per_s"]
        out[f"speedup_{kind}"] = s
        print(f"{kind}: 2 workers / 1 worker = {s:.2f}x")
    out["machine"]["load_1min_after"] = os.getloadavg()[0]
    out["machine"]["free_cores_after"] = free_cores()
    print(f"{out['machine']['free_cores_after']:.2f} cores free after (load {out['machine']['load_1min_after']:.2f})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
