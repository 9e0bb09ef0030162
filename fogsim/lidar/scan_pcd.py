"""A fog level's scan as a PCD file for viewers (open3d, pypcd4, CloudCompare, PCL), written beside the
level's scan through THE PCD codec (:mod:`fogsim.lidar.pcd`, ``DATA binary``).

Fields, one record per reported point, in the scan file's order:

============  =======  ==========================================================================
field         type     value
============  =======  ==========================================================================
x, y, z       F 4      metres, the sensor frame (as the scan file)
intensity     F 4      the intensity as the scan file stores it (its scale: the header's comment
                       ``fogsim intensity_scale <scale>``, KITTI 0–1, nuScenes / STF 0–255)
ring          U 2      the beam, where the scan has one (renders, nuScenes, STF; not KITTI)
label         U 2      SemanticKITTI class id (renders: the ``.label`` file's lower 16 bits)
instance      U 2      instance id (renders: the ``.label`` file's upper 16 bits; 0 = none)
outcome       U 1      what fog did to the point: 0 kept, 1 attenuated, 3 clutter, 4 no-return
                       (:data:`fogsim.lidar.fog.OUTCOMES`; lost points are not in the scan, but
                       in a scan that stores every firing, where they are placeholder rows: 2)
============  =======  ==========================================================================

``label`` and ``instance`` are written where labels are known (a render's levels), ``outcome`` for every
fogged level.
"""
from __future__ import annotations

import os

import numpy as np

from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.outcomes import CLUTTER
from fogsim.lidar.pcd import write_pcd
from fogsim.lidar.points import PointCloud

__all__ = ["PCD_SUFFIX", "reported_outcomes", "scan_records", "write_level_pcd"]

PCD_SUFFIX = ".pcd"
SCALE_COMMENT = "fogsim intensity_scale"


def reported_outcomes(fogged: FoggedScan) -> np.ndarray:
    """The outcome of every point of ``fogged.cloud`` (uint8, in its rows' order; the rows after the input's
    points are the empty rays' fog clutter)."""
    out = np.full(len(fogged.cloud), CLUTTER, np.uint8)
    rows = np.flatnonzero(fogged.output_index >= 0)
    out[fogged.output_index[rows]] = fogged.outcome[rows]
    return out


def scan_records(cloud: PointCloud, labels: np.ndarray | None = None,
                 outcome: np.ndarray | None = None) -> np.ndarray:
    """The structured array of the module docstring's fields: ``labels`` the SemanticKITTI uint32 of each
    point (instance << 16 | class; None: no label fields), ``outcome`` one per point (None: no field)."""
    n = len(cloud)
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")]
    fields += [("ring", "<u2")] if cloud.ring is not None else []
    fields += [("label", "<u2"), ("instance", "<u2")] if labels is not None else []
    fields += [("outcome", "u1")] if outcome is not None else []
    rec = np.zeros(n, fields)
    rec["x"], rec["y"], rec["z"] = cloud.xyz[:, 0], cloud.xyz[:, 1], cloud.xyz[:, 2]
    rec["intensity"] = cloud.raw_intensity
    if cloud.ring is not None:
        rec["ring"] = cloud.ring
    if labels is not None:
        labels = np.asarray(labels, np.uint32)
        if labels.shape != (n,):
            raise ValueError(f"{labels.size} labels for {n} points")
        rec["label"], rec["instance"] = labels & np.uint32(0xFFFF), labels >> np.uint32(16)
    if outcome is not None:
        outcome = np.asarray(outcome)
        if outcome.shape != (n,):
            raise ValueError(f"{outcome.size} outcomes for {n} points")
        rec["outcome"] = outcome
    return rec


def write_level_pcd(path: str | os.PathLike, fogged: FoggedScan, labels: np.ndarray | None = None) -> None:
    """Write one fog level's scan as a binary PCD at ``path`` (atomically), with its outcomes and, given
    ``labels`` (uint32 per point, SemanticKITTI's layout), the label and instance fields."""
    write_pcd(path, scan_records(fogged.cloud, labels, reported_outcomes(fogged)),
              comment=f"{SCALE_COMMENT} {fogged.cloud.scale}")
