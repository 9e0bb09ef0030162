"""The labels beside a rendered radar sweep or level (``radar/<level>/<frame>.npz``,
:func:`fogsim.render.radar_frame.write_labels`): per reported detection what produced it, where it came from
in the clear sweep, and its measured values — arrays of equal length, checked by
:func:`fogsim.dataset.radar.read_labels`."""
from __future__ import annotations

from typing import ClassVar

from pydantic import ConfigDict

from fogsim.schema.base import Open
from fogsim.schema.documents import Vector

__all__ = ["LABEL_COLUMNS", "RadarLabels"]

#: the per-detection columns, in the file's order (``kind_names`` beside them names the kinds)
LABEL_COLUMNS = ("object_id", "kind", "source_id", "sweep_row", "range_m", "azimuth_rad", "elevation_rad",
                 "radial_velocity_mps", "radial_velocity_comp_mps", "rcs_dbsm", "snr_db", "scan", "x_true", "y_true",
                 "z_true")


class RadarLabels(Open):
    """A rendered radar file's labels: ``object_id`` (mask id, −1 none), ``kind`` (0 object, 1 ghost,
    2 ground clutter, 3 false alarm), ``source_id`` (a ghost's mirrored object, else −1), ``sweep_row`` (the
    detection's row in the clear sweep), range (m), azimuth and elevation (rad), radial velocities (m/s,
    + receding; raw and ego-compensated), RCS (dBsm), SNR (dB), ``scan`` (0 far, 1 near) and the scattering
    centre before the measurement noise (``x_true``, ``y_true``, ``z_true``: sensor frame, m)."""

    document: ClassVar[str] = "radar label file"

    model_config = ConfigDict(arbitrary_types_allowed=True, extra="ignore", frozen=True)

    object_id: Vector
    kind: Vector
    source_id: Vector
    sweep_row: Vector
    range_m: Vector
    azimuth_rad: Vector
    elevation_rad: Vector
    radial_velocity_mps: Vector
    radial_velocity_comp_mps: Vector
    rcs_dbsm: Vector
    snr_db: Vector
    scan: Vector
    x_true: Vector
    y_true: Vector
    z_true: Vector
