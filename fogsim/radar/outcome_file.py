"""The per-detection outcomes beside a fogged sweep: ``<name>.outcomes.npz`` with ``outcome`` (int8, one per
input detection: 0 kept, 1 lost — :data:`fogsim.radar.fog.OUTCOMES`), ``output_index`` (int64, the
detection's row in the fogged sweep file, −1 when lost) and ``snr_fog_db`` (float32, its SNR in the fog).
Written atomically, read without unpickling and checked (equal lengths, known outcomes, −1 exactly for the
lost detections, the others 0 … M−1 in input order), a problem one line naming the file.
"""
from __future__ import annotations

import io
import os

import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.radar.fog import LOST, OUTCOMES, FoggedRadar
from fogsim.schema.base import load_npz
from fogsim.schema.radar import RadarOutcomes

__all__ = ["OUTCOME_SUFFIX", "read_radar_outcomes", "write_radar_outcomes"]

OUTCOME_SUFFIX = ".outcomes.npz"


def write_radar_outcomes(path: str | os.PathLike, fogged: FoggedRadar) -> None:
    """Write ``fogged``'s outcomes, output rows and SNRs in fog to ``path`` (an ``.npz``), atomically."""
    buf = io.BytesIO()
    snr = fogged.snr_fog_db if fogged.snr_fog_db is not None else np.full(len(fogged.outcome), np.nan)
    np.savez(buf, outcome=fogged.outcome.astype(np.int8), output_index=fogged.output_index.astype(np.int64),
             snr_fog_db=np.asarray(snr, np.float32), outcome_names=np.array(OUTCOMES))
    atomic_write_bytes(path, buf.getvalue())


def read_radar_outcomes(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(outcome int8 N, output_index int64 N, snr_fog_db float32 N) of an outcome file, checked."""
    doc = load_npz(path, RadarOutcomes)
    outcome, index, snr = (np.asarray(a) for a in (doc.outcome, doc.output_index, doc.snr_fog_db))
    if not outcome.shape == index.shape == snr.shape:
        raise InputError(path, f"radar outcome file: {outcome.size} outcomes, {index.size} output rows and "
                               f"{snr.size} SNRs")
    if outcome.size and (outcome.min() < 0 or outcome.max() >= len(OUTCOMES) or (outcome != np.round(outcome)).any()):
        raise InputError(path, f"radar outcome file: outcomes must be 0–{len(OUTCOMES) - 1}")
    lost = outcome == LOST
    shown = index[~lost]
    if (index[lost] != -1).any() or not np.array_equal(shown, np.arange(len(shown))):
        raise InputError(path, "radar outcome file: output rows must be −1 for lost detections and 0, 1, … for "
                               "the others in input order")
    return outcome.astype(np.int8), index.astype(np.int64), snr.astype(np.float32)
