"""The per-point outcomes beside a fogged scan: ``<frame>.outcomes.npz`` with ``outcome`` (int8, one per
input point: 0 kept, 1 attenuated, 2 lost, 3 clutter, 4 no-return — :data:`fogsim.lidar.fog.OUTCOMES`) and
``output_index`` (int64, the point's row in the fogged scan file, −1 when lost — except in a scan that
stores every firing, where a lost point keeps a placeholder row: :mod:`fogsim.lidar.fog`). Written
atomically, read without unpickling and checked (equal lengths, known outcomes, −1 for lost points only,
the rows present 0 … M−1 in input order), a problem one line naming the file.
"""
from __future__ import annotations

import io
import os

import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.outcomes import LOST, OUTCOMES
from fogsim.schema.base import load_npz
from fogsim.schema.lidar import LidarOutcomes

__all__ = ["OUTCOME_SUFFIX", "read_outcomes", "write_outcomes"]

OUTCOME_SUFFIX = ".outcomes.npz"


def write_outcomes(path: str | os.PathLike, fogged: FoggedScan) -> None:
    """Write ``fogged``'s outcomes and output rows to ``path`` (an ``.npz``), atomically."""
    buf = io.BytesIO()
    np.savez(buf, outcome=fogged.outcome.astype(np.int8), output_index=fogged.output_index.astype(np.int64),
             outcome_names=np.array(OUTCOMES))
    atomic_write_bytes(path, buf.getvalue())


def read_outcomes(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """(outcome int8 N, output_index int64 N) of an outcome file, checked (the module docstring)."""
    doc = load_npz(path, LidarOutcomes)
    outcome, index = np.asarray(doc.outcome), np.asarray(doc.output_index)
    if outcome.shape != index.shape:
        raise InputError(path, f"LiDAR outcome file: {outcome.size} outcomes but {index.size} output rows")
    if outcome.size and (outcome.min() < 0 or outcome.max() >= len(OUTCOMES) or (outcome != np.round(outcome)).any()):
        raise InputError(path, f"LiDAR outcome file: outcomes must be 0–{len(OUTCOMES) - 1}")
    absent = index == -1
    shown = index[~absent]
    if (outcome[absent] != LOST).any() or not np.array_equal(shown, np.arange(len(shown))):
        raise InputError(path, "LiDAR outcome file: output rows must be −1 for lost points (only) and 0, 1, … "
                               "for the others in input order")
    return outcome.astype(np.int8), index.astype(np.int64)
