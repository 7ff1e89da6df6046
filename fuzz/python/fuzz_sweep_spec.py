"""atheris harness over the sweep-spec reader (`dampnet sweep SPEC.toml`): any bytes as a spec file
give the spec's cells (listed and keyed, as the sweep does before it starts a cluster) or the
project's own refusal, a one-line SpecError (under 2000 characters, no numpy repr), never another
exception or a hang.

Each input is written to a spec file in a scratch directory and read as `dampnet sweep` reads it:
dampnet.sweep.load_spec, then dampnet.sweep.grid.expand (at most MAX_FUZZ_CELLS cells: the size
check itself is fuzzed, a large spec is refused rather than listed) and dampnet.sweep.inputs.bind
(every input hashed). Relative paths resolve in the scratch directory, which holds a dataset, a
model and a road file for the seeds to name.

The seed corpus is SEEDS below (valid specs of every table and distribution, and a few bad ones);
write it into a directory first, since libFuzzer adds what it finds to its first corpus directory:

  python fuzz/python/fuzz_sweep_spec.py --write-seeds /tmp/sweep_corpus
  python fuzz/python/fuzz_sweep_spec.py /tmp/sweep_corpus -runs=2000 -seed=1 -max_len=2048 -timeout=10

(tests/python/test_sweep_fuzz.py runs that CI-sized run; longer runs take -runs=N as
fuzz/python/README.md describes for the readers' harness.)

Recorded run (issue 29, on the shared 2-core machine at load 10-15, nice 10): 200,000 executions
from the seeds (-seed=7, -max_len=2048), 766 s, 261 exec/s, cov 505 / ft 1337 (dampnet edges /
features), 384 new units: no unexpected exception, no timeout. Found while writing the harness,
not by the run: tomllib's RecursionError on deeply nested arrays, and messages repeating a whole
5000-character value or key (both now one short SpecError line).
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

SEEDS = {
    "training_grid": "[training]\ndatasets = ['rig:quick', 'data']\nalgorithms = ['lm', 'scg']\n"
                     "seeds = [0, 1]\nhidden = [30, [20, 10], '8-4']\nadd = ['none', 'gas_spring']\n"
                     "rig_effects = [[], ['gas_spring', 'thermal']]\ndecimate = 'auto'\nmax_epochs = 30\n"
                     "holdout_voltage = 'none'\nfeatures = ['default', ['velocity', 'acceleration', 'voltage']]\n"
                     "objective = 'holdout_nrmse'\n",
    "training_random": "[training]\ndatasets = ['rig:quick']\n[training.random]\nn = 5\nseed = 3\n"
                       "seeds = {integers = [0, 9]}\nalgorithm = {choice = ['lm', 'br']}\n"
                       "holdout_voltage = {uniform = [1.0, 3.0]}\n",
    "simulation": "[sweep]\ndata = 'ship'\nallowed_failures = 2\nname = 'x'\n[simulation]\n"
                  "models = ['default', 'truth', 'linear:1500', 'model.json']\n"
                  "roads = ['impulse', 'bump', 'rough', 'iso:C', 'road.csv']\nroad_seeds = [0, 1]\n"
                  "road_length_m = 30.0\nspeeds = [5.0, 12.5]\ncontrollers = ['passive_low', 'skyhook_onoff']\n"
                  "[simulation.vehicle]\nm_s = [250.0, 300.0]\n[simulation.controller]\nu_tau_s = 0.01\n",
    "simulation_random": "[simulation]\nroads = ['iso:A']\n[simulation.random]\nn = 8\nseed = 1\n"
                         "speed = {loguniform = [2.0, 30.0]}\nroad_seed = {integers = [0, 100]}\n"
                         "[simulation.random.vehicle]\nm_s = {normal = [300.0, 10.0]}\n",
    "fullcar": "[fullcar]\nmodels = ['default', 'truth']\ntests = ['dlc', 'bsst', 'road']\n"
               "damping = ['low', 'skyhook']\nspeeds_kmh = [80.0]\nmodes = ['heave', 'pitch']\n"
               "roads = ['thesis', 'iso:C', 'bump']\ndt = 0.002\nbsst_f0_hz = 1.0\n[fullcar.vehicle]\n"
               "m_s = [2400.0, 2800.0]\ntyre_model = 'linear'\n[fullcar.random]\nn = 2\nseed = 0\n"
               "[fullcar.random.vehicle]\nk_s_f = {uniform = [30000.0, 40000.0]}\n",
    "bad_distribution": "[simulation]\nroads = ['impulse']\n[simulation.random]\nn = 3\nseed = 1\n"
                        "speed = {uniform = [nan, inf]}\n",
    "too_many": "[simulation]\nroads = ['rough']\nroad_seeds = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]\n"
                "speeds = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n[simulation.random]\nn = 100\nseed = 0\n"
                "[simulation.random.vehicle]\nm_s = {uniform = [200.0, 300.0]}\n",
}

#: the most cells an input may list (a larger spec is refused by the size check, as a bigger
#: --max-cells would refuse it; listing 10^5 cells per input would make the run crawl)
MAX_FUZZ_CELLS = 2000


def write_seeds(directory: Path) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    for name, text in SEEDS.items():
        (directory / name).write_text(text)


def scratch() -> Path:
    """A scratch directory with the files the seeds name: a dataset directory, a model, a road."""
    from dampnet.modeldir import default_model_path

    work = Path(tempfile.mkdtemp(prefix="dampnet-fuzz-sweep-"))
    (work / "data").mkdir()
    (work / "data" / "manifest.csv").write_text("test_id,file,frequency_hz,amplitude_m,voltage_v\n")
    shutil.copy(default_model_path(), work / "model.json")
    (work / "road.csv").write_text("distance_m,elevation_m\n0,0\n1,0.01\n2,0\n")
    return work


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--write-seeds":
        write_seeds(Path(sys.argv[2]))
        return
    import atheris

    from dampnet.sweep import SpecError, load_spec
    from dampnet.sweep.grid import expand
    from dampnet.sweep.inputs import bind

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fuzz_readers import _instrument_dampnet   # the same coverage instrumentation

    work = scratch()
    spec_file = work / "sweep.toml"

    def one_input(data: bytes) -> None:
        spec_file.write_bytes(data)
        try:
            spec = load_spec(spec_file)
            cells = expand(spec, max_cells=MAX_FUZZ_CELLS)
            bind(cells, spec)
        except SpecError as e:
            msg = str(e)
            assert "\n" not in msg, f"multi-line error: {msg[:300]!r}"
            assert len(msg) < 2000, f"a {len(msg)}-character error: {msg[:300]!r}"
            assert "np.float64(" not in msg and "np.int64(" not in msg, f"numpy repr in: {msg[:300]!r}"
            return
        assert 0 < len(cells) <= MAX_FUZZ_CELLS
        for c in cells:       # what the sweep then stores: JSON parameters and a key
            assert c.key and len(c.key) == 20
            json.dumps(c.params, allow_nan=False)

    _instrument_dampnet()
    atheris.Setup(sys.argv, one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
