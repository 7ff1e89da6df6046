"""The model directory: MODEL_DIR/{model.json, metrics.json, model.h} and, when the training
samples are known, the training envelope (envelope.npz, envelope.json: dampnet.envelope),
written as one atomic step."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence

from dampnet.paths import default_model_path  # noqa: F401 (its home is dampnet.paths; imported from here too)
from dampnet.export.header import write_header
from dampnet.model import MlpModel
from dampnet.outputs import check_output_dir, staged_dir, write_json

HEADER_NAME = "model.h"
HEADER_PREFIX = "dn_model"


def model_file(path: str | os.PathLike) -> Path:
    """The model.json of `path`: the file itself, or the one in a model directory."""
    p = Path(path)
    return p / "model.json" if p.is_dir() else p


def load_model(path: str | os.PathLike) -> MlpModel:
    """The model in `path`: a model.json file or a model directory holding one."""
    return MlpModel.load(model_file(path))


def default_model() -> MlpModel:
    """The default model shipped with dampnet (export/dn_model_default.json, installed beside the headers)."""
    return MlpModel.load(default_model_path())


def save_model_dir(model: MlpModel, metrics: dict[str, Any] | None, out_dir: str | os.PathLike,
                   force: bool = False, prefix: str = HEADER_PREFIX,
                   inputs: Sequence[str | os.PathLike] = (), envelope=None) -> Path:
    """Write MODEL_DIR/{model.json, metrics.json, model.h} as one atomic step, with
    envelope.npz and envelope.json when `envelope` (a dampnet.envelope.Envelope of this model:
    `envelope_of(model, split)` after training) is given.

    The files go to a staging directory next to out_dir that is then swapped into
    place (`dampnet.outputs`): a reader never sees a half-written model directory,
    and a kill at any point leaves the old or the new one. An existing out_dir is
    refused (OutputError, a FileExistsError) unless `force`, and even then unless it
    is a model directory (model.json) that is not one of `inputs`, `.` or a parent.
    """
    out = check_output_dir(out_dir, "model", inputs, force)
    if envelope is not None:
        from dampnet.envelope import check_belongs

        check_belongs(envelope, model)
    with staged_dir(out) as tmp:
        model.save(tmp / "model.json", overwrite=True)
        write_json(tmp / "metrics.json", metrics or {}, overwrite=True)
        write_header(model, tmp / HEADER_NAME, prefix=prefix, overwrite=True, envelope=envelope)
        if envelope is not None:
            from dampnet.envelope import save_envelope

            save_envelope(envelope, tmp)
    return out
