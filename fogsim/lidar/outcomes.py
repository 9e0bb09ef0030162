"""The outcome of each input point of a fogged scan — one vocabulary for every LiDAR fog model
(:mod:`fogsim.lidar.fog` and the published models, :mod:`fogsim.lidar.hahner2021`, :mod:`fogsim.lidar.stf2020`):
``kept`` (reported unchanged), ``attenuated`` (reported, dimmer and/or moved by range noise), ``lost`` (not
reported), ``clutter`` (the fog's echo reported instead, on the same ray); codes 0–3 in this order."""
from __future__ import annotations

__all__ = ["ATTENUATED", "CLUTTER", "EMPTY_RAY_INDEX", "KEPT", "LOST", "OUTCOMES"]

OUTCOMES = ("kept", "attenuated", "lost", "clutter")
KEPT, ATTENUATED, LOST, CLUTTER = range(4)
#: the ``index`` of a fogged scan's rows that no input point made (the empty rays' clutter points, and the
#: points a model adds: stf2020's random scatter)
EMPTY_RAY_INDEX = -1
